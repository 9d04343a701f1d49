"""A recorded session read as a track of bridge steps, for demo extraction
(:mod:`teleop.record.demos`): per state its log time, the one simulated clock, seq, the state
and its fingertip contacts, and what the session's events say about the scene (where it was
rebuilt, which object was on the table from when, which state an event names).

Why a module of its own: this is the reading of the file — how ``/state`` and ``/contacts``
pair (by the step's seq and simulated time, else time alone, else log time), how the clock
continues across a rebuilt scene — while :mod:`teleop.record.demos` holds the rules of what a
grasp is. Times: nanoseconds (integers) on the track, seconds in events.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.demo import DemoError
from teleop.record.schemas import TOPIC_CONTACTS, TOPIC_STATE
from teleop.record.session import Session

__all__ = ["SCENE_BREAKS", "Track", "marked_state", "object_at", "object_changes", "read_track",
           "scene_breaks", "session_time_s"]


@dataclass
class Track:
    """Per-state arrays of a session: log times (ns), the extraction clock (nanoseconds of
    simulated time, see :func:`_clock_ns`) and its offset from the states' own ``t_s``, seq,
    states, fingertip contacts, and every hand body touching the object (palm and phalanges
    too: a whole-hand wrap, :mod:`teleop.record.power_demo`) with those contacts."""

    t_ns: np.ndarray
    clock_ns: np.ndarray
    offset_ns: np.ndarray | None
    seq: list[int | None]
    states: list[dict[str, Any]]
    contacts: list[list[dict[str, Any]]]
    fingers_touching: list[frozenset[str]]
    #: per state every hand–object contact, and the hand bodies in them (empty lists on a
    #: track built without them: no state is then a wrap)
    hand_contacts: list[list[dict[str, Any]]] = field(default_factory=list)
    bodies_touching: list[frozenset[str]] = field(default_factory=list)


def _pairing(contacts: list[tuple[int, dict[str, Any]]]) -> str:
    """How the ``/contacts`` of a state are found: ``"seq"`` (the step's seq and t_s), ``"sim"``
    (t_s) or ``"log"`` (log time), the best every contacts message allows."""
    if contacts and all("seq" in c for _, c in contacts):
        return "seq"
    if contacts and all(_finite(c.get("t_s")) for _, c in contacts):
        return "sim"
    return "log"


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and np.isfinite(value)


def _step_key(log_ns: int, msg: dict[str, Any], pairing: str) -> Any:
    if pairing == "seq":
        return msg.get("seq"), msg.get("t_s")
    return msg.get("t_s") if pairing == "sim" else log_ns


def _clock_ns(states: list[dict[str, Any]], t_ns: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray | None]:
    """Per state, integer nanoseconds on one monotone simulated clock (integers, like log times:
    durations are exact differences), and its offset from the states' ``t_s`` (None when some
    state has no ``t_s``: then the clock is the log time)."""
    raw = [s.get("t_s") for s in states]
    if not all(_finite(t) for t in raw):
        return t_ns, None
    t = np.array([round(float(v) * 1e9) for v in raw if v is not None], np.int64)   # all finite
    clock = t.copy()
    for j in np.flatnonzero(np.diff(t) < 0) + 1:  # the scene was rebuilt: sim time restarted
        clock[j:] += clock[j - 1] - clock[j] + (t_ns[j] - t_ns[j - 1])
    return clock, clock - t


def session_time_s(track: Track, i: int) -> float:
    """Seconds from the session's first state to state ``i`` on the extraction clock (simulated
    time, continuous across scene rebuilds; log time in files whose states carry no ``t_s``): a
    demo's time, the same in every re-recording of the session."""
    return (int(track.clock_ns[i]) - int(track.clock_ns[0])) * 1e-9


def read_track(session: Session, fingers: tuple[str, ...]) -> Track:
    where = session.path
    for topic in (TOPIC_STATE, TOPIC_CONTACTS):
        if not session.counts.get(topic):
            if session.truncated:
                raise DemoError(f"{where}: no {topic} message survives: the file is "
                                f"{session.cut_note}")
            raise DemoError(f"{where}: no {topic} messages; the session holds raw input only "
                            f"(record it through the bridge: `dexaug rerecord {where} OUT.mcap`)")
    states = session.json_messages(TOPIC_STATE)
    contacts = session.json_messages(TOPIC_CONTACTS)
    pairing = _pairing(contacts)
    by_step = {_step_key(t, c, pairing): c for t, c in contacts}
    known = set(fingers)
    t_ns, seq, st, con, touching, every, bodies = [], [], [], [], [], [], []
    for t, s in states:
        hand = by_step.get(_step_key(t, s, pairing), {}).get("contacts", [])
        c = [x for x in hand if x.get("finger") in known]
        t_ns.append(t)
        seq.append(s.get("seq"))
        st.append(s)
        con.append(c)
        touching.append(frozenset(x["finger"] for x in c))
        every.append(hand)
        bodies.append(frozenset(str(x["hand_body"]) for x in hand if "hand_body" in x))
    log_ns = np.asarray(t_ns, np.int64)
    clock, offset = _clock_ns(st, log_ns) if st else (log_ns, None)
    return Track(log_ns, clock, offset, seq, st, con, touching, every, bodies)


#: events after which the scene is not the one before: a contact run never spans them
SCENE_BREAKS = ("scene_restored", "object_reset", "object_changed")


def scene_breaks(session: Session, track: Track) -> list[int]:
    """State indices at which the bridge re-placed the object or restored the scene
    (:data:`SCENE_BREAKS`): a grasp cannot go on across them."""
    return sorted({marked_state(track, t, ev) for t, ev in session.events()
                   if ev.get("type") in SCENE_BREAKS})


def marked_state(track: Track, log_ns: int, event: dict[str, Any]) -> int:
    """The state a ``grasp_mark`` (logged at ``log_ns``) names: by seq, else by simulated time,
    else by log time (module docstring)."""
    seq = (event.get("payload") or {}).get("seq")
    hits = [i for i, s in enumerate(track.seq) if seq is not None and s == seq]
    if hits:
        return hits[-1]
    last_logged = max(int(np.searchsorted(track.t_ns, log_ns, side="right")) - 1, 0)
    if track.offset_ns is None or not _finite(event.get("t_s")):
        return last_logged
    t = round(float(event["t_s"]) * 1e9) + int(track.offset_ns[last_logged])  # that scene's
    return max(int(np.searchsorted(track.clock_ns, t, side="right")) - 1, 0)


def object_changes(session: Session, track: Track) -> list[tuple[int, str]]:
    """(state index, object) of every event that names the object on the table from then on
    (``object_changed``, ``object_reset``): a bridge whose object was chosen after the
    recording started — a replay puts the session's object there — records the first one in
    its metadata, and a demo must name the object it grasped."""
    out = []
    for t, ev in session.events():
        name = (ev.get("payload") or {}).get("object")
        if ev.get("type") in ("object_changed", "object_reset") and isinstance(name, str):
            out.append((marked_state(track, t, ev), name))
    return sorted(out, key=lambda c: c[0])


def object_at(changes: list[tuple[int, str]], i: int, first: str) -> str:
    """The object on the table at state ``i``: the last change at or before it, else the
    session's metadata object."""
    named = [name for at, name in changes if at <= i]
    return named[-1] if named else first
