"""Grasp demonstrations extracted from recorded sessions (DESIGN §6, "demo extraction").

A demo is what the augmenter needs of one human grasp: the object, the hand's joint angles,
frame_palm in the object frame, and per finger the contact centroid in its fingertip body frame
(AutoWS centres the contact faces there) — plus where it came from (session file, log time).

Where the grasp moment is. A bridge recording holds ``/state`` (simulated qpos, palm and object
poses in the world) and ``/contacts`` (hand–object contacts, tagged with the finger whose tip
body touches), one of each per bridge step. A *stable grasp* is a run of states in which at least
``min_fingers`` fingertips touch the object, the hand's most important finger (its first in
priority order: the thumb for the Shadow Hand) among them, lasting at least ``min_duration_s``;
the moment inside a run is the state with the most fingertips in contact (the middle one of
those, for ties). Contact losses shorter than ``max_gap_s`` do not split a run. A shorter run
(``min_confirmed_s`` at least) is a grasp when the hand lifts it — a *lift-confirmed contact*:
people lift 0.12–0.64 s after first touching (median 0.36 s), so the contact before the lift
is often shorter than ``min_duration_s``, and a hand that carries the object up, or in the
demonstration mode rises off the held object right after, has grasped it.
A *whole-hand wrap* — the thumb, ``min_fingers`` other fingers and the palm side (or the
inner phalanges of ``power_inner_fingers`` fingers) on the object, :mod:`teleop.record.power_demo`
— lasting ``power_min_s`` that the hand lifts (the same lift confirmation) is a *power demo*
(:data:`sim.demo.POWER`, how "lift-confirmed wrap", or "grasp_mark" when marked): its moment
is the wrap state with the most hand bodies on the object, its fingers every finger on it with
any link, and the fingertip runs inside it are the same grasp, not demos of their own. FSG
cannot augment a wrap (its palm check refuses a palm on the object); the augmenter seeds its
power generator with it.
An operator's ``grasp_mark`` event names a moment: the state it names
(``seq``) or the last one logged before it — or, within ``mark_snap_s`` of it, the usable state
with the most fingertips in contact (ties: the nearest), because a person marks with a button
or a held gesture, not to the 4 ms physics step, and a fingertip resting on the object touches
and leaves it from step to step (README "Grasping at human speed"); with no usable state that
near, the nearest one within ``mark_window_s`` is taken, and a mark with none is reported, not
silently dropped. A mark within ``mark_window_s`` of a stable run replaces that run's own
moment (one demo per grasp).

One clock: the simulation's. A state and its contacts are paired by the step's ``seq`` and
simulated time ``t_s`` (both carried by each since the bridge writes them; ``seq`` alone
repeats, as a live bridge publishes several states per frame while physics advances), else by
``t_s`` alone (older recordings), else by identical log time (files whose records carry no
``t_s``). Every duration — ``min_duration_s``, ``max_gap_s``, ``mark_window_s`` — is measured
in the states' simulated time, so a session re-recorded faster or slower than real time gives
the same demos; an object change restarts the simulation's clock, and the states after it
continue from the last one before (plus the log time between them). A ``grasp_mark`` names its
state by ``seq`` when it carries one (the last state with it), else by its simulated ``t_s``
(the last state at or before it), else by log time (the last state logged at or before it).
A demo's time (:attr:`sim.demo.Demo.time_s`, and so its id) is on that clock too: simulated
seconds since the session's first state. A re-recording runs faster than real time, so its log
times differ from run to run and from the person's (the same grasp was ``@0.62s``, ``@0.79s``
and ``@1.65s`` on one machine, by its load); its simulated time is the person's, in every run.

Why simulated contacts and not the operator's hand: the augmenter works on the robot hand's
grasp, and the recording's contacts are the robot's, in the robot fingertip frames.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.demo import POWER, PRECISION, Demo, DemoError
from sim.hand.model import Hand
from sim.transforms import pose_inv, pose_mul
from teleop.record.demo_quality import fragment_flag, slip_flag, table_in_object_frame
from teleop.record.demo_track import (
    Track,
    marked_state,
    object_at,
    object_changes,
    read_track,
    scene_breaks,
    session_time_s,
)
from teleop.record.power_demo import link_bodies, wrap_fingers, wrap_mask, wrap_points
from teleop.record.session import Session, SessionError, open_session

__all__ = ["DemoParams", "extract_demos"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DemoParams:
    """Grasp-moment detection. ``min_fingers`` fingertips (the first finger of the hand among
    them) in contact for at least ``min_duration_s`` seconds, losses shorter than
    ``max_gap_s`` bridged; a ``grasp_mark`` belongs to a contact run within ``mark_window_s``
    seconds of it, and may look that far either side for a state with enough contacts; it
    takes the state with the most fingertips within ``mark_snap_s`` of it (a person's
    reaction time). All seconds of simulated time (module docstring)."""

    min_fingers: int = 2
    min_duration_s: float = 0.3
    max_gap_s: float = 0.25
    mark_window_s: float = 0.5
    mark_snap_s: float = 0.2
    #: a shorter run is a grasp too when the hand lifts (:func:`_lift_confirmed`): a person
    #: lifts 0.12–0.64 s after the first contact (median 0.36 s), so a held object gives a
    #: contact run shorter than ``min_duration_s`` before it rises; this long at least (s)
    min_confirmed_s: float = 0.05
    #: the rise that confirms it (metres): the palm's, and in the free-object mode the
    #: object's with it — well above tracking jitter (mm), well below a lift (5–15 cm)
    lift_confirm_m: float = 0.02
    #: in the demonstration mode (object held fixed) the palm must rise this soon after the
    #: run ends (s): the operator lifting off the fixed object is the lift
    lift_window_s: float = 1.0
    #: a whole-hand wrap (:mod:`teleop.record.power_demo`: the thumb, ``min_fingers`` other
    #: fingers and the palm side, or the inner links of ``power_inner_fingers`` fingers, on
    #: the object) lasting this long (s, gaps bridged) that the hand lifts is a power demo
    power_min_s: float = 0.1
    power_inner_fingers: int = 2


def _runs(ok: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the True runs of ``ok``."""
    edges = np.diff(np.concatenate([[0], ok.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _merged_runs(clock_ns: np.ndarray, ok: np.ndarray, max_gap_s: float) -> list[tuple[int, int]]:
    """True runs of ``ok`` with gaps shorter than ``max_gap_s`` bridged: a fingertip that
    flickers off for a few frames while the object is held is the same grasp."""
    merged: list[tuple[int, int]] = []
    for lo, hi in _runs(ok):
        if merged and (int(clock_ns[lo]) - int(clock_ns[merged[-1][1] - 1])) * 1e-9 <= max_gap_s:
            merged[-1] = (merged[-1][0], hi)
        else:
            merged.append((lo, hi))
    return merged


def _best_in(track: Track, lo: int, hi: int, ok: np.ndarray, power: bool = False) -> int:
    """The grasp moment of the run [lo, hi): of its states that meet the rule (``ok``: the
    lead finger and enough others touching), the one with the most fingertips — with
    ``power``, the most hand bodies (the middle one of ties). Only those: a gap-bridged run
    also holds states inside its gaps, and the fullest of all could be one without the thumb
    — a thumbless demo of a thumb grasp."""
    idx = lo + np.flatnonzero(ok[lo:hi])
    n = np.array([len(track.bodies_touching[i] if power else track.fingers_touching[i])
                  for i in idx])
    best = idx[n == n.max()]
    return int(best[len(best) // 2])


def _demo_at(session: Session, track: Track, i: int, hand: str, obj: str, how: str,
             duration_s: float, run_end: int | None, power: bool = False) -> Demo:
    s = track.states[i]
    joints = np.asarray(s["qpos"], float)
    inv_p, inv_q = pose_inv(np.asarray(s["object_pos_m"], float),
                            np.asarray(s["object_quat_wxyz"], float))
    palm_p, palm_q = pose_mul(inv_p, inv_q, np.asarray(s["palm_pos_m"], float),
                              np.asarray(s["palm_quat_wxyz"], float))
    tip: dict[str, np.ndarray] = {}
    pts: dict[str, np.ndarray] = {}
    for finger in sorted(track.fingers_touching[i]):
        mine = [c for c in track.contacts[i] if c["finger"] == finger]
        tip[finger] = np.mean([c["pos_hand_body_m"] for c in mine], axis=0)
        pts[finger] = np.array([c["pos_object_m"] for c in mine], float)
    t_s = session_time_s(track, i)
    meta = session.metadata
    fingers = tuple(sorted(track.fingers_touching[i]))
    links = link_bodies(track, i, _hand(hand))
    if power:   # the person's finger set: every finger on the object, with any link
        fingers = tuple(sorted(wrap_fingers(track, i, _hand(hand))))
        pts = wrap_points(track, i, _hand(hand))
    flags = [fragment_flag(_hand(hand), joints, fingers)]
    if meta.get("object_mode", "free") == "free" and run_end is not None:
        flags.append(slip_flag(track.states[i:run_end]))
    demo = Demo(id=f"{session.path.stem}@{t_s:.2f}s", hand=hand, object=obj, joints=joints,
                palm_pos_m=palm_p, palm_quat_wxyz=palm_q, tip_contacts=tip,
                contact_points_obj=pts, source=session.path, time_s=t_s, how=how,
                duration_s=duration_s, fingers=fingers,
                table=table_in_object_frame(meta.get("table"), s["object_pos_m"],
                                            s["object_quat_wxyz"]),
                flags=tuple(f for f in flags if f), grasp_type=POWER if power else PRECISION,
                link_contacts=links)
    for flag in demo.flags:
        log.warning("%s: demo %s: %s", session.path, demo.id, flag)
    return demo


@functools.lru_cache(maxsize=8)
def _hand(name: str) -> Hand:
    return Hand.load(name)


def extract_demos(path: Path | str, params: DemoParams | None = None) -> list[Demo]:
    """All grasp demonstrations of the session at ``path`` (module docstring), in time order.

    Raises:
        DemoError: the session names no hand or object, was recorded without the bridge, or
            holds no grasp (the message gives the longest contact run found and why it fell
            short), or cannot be read (damaged, not MCAP: the reader's message).
    """
    p = params or DemoParams()
    try:
        session = open_session(path)
    except SessionError as exc:
        raise DemoError(str(exc)) from None
    meta = session.metadata
    hand, obj = meta.get("hand"), meta.get("object")
    if not hand:
        raise DemoError(f"{path}: session metadata names no hand (key 'hand')")
    if not obj:
        raise DemoError(f"{path}: session has no object (metadata key 'object'); a demo needs "
                        f"the grasped object")
    fingers = tuple(meta.get("fingers") or ())
    if not fingers:
        raise DemoError(f"{path}: session metadata lists no fingers (key 'fingers')")
    if session.truncated:
        log.warning("%s is truncated at byte %d (recorder did not close it); using what is "
                    "readable", path, session.stop_offset)
    track = read_track(session, fingers)
    if not len(track.t_ns):
        raise DemoError(f"{path}: no states")
    lead = fingers[0]
    n_touch = np.array([len(f) for f in track.fingers_touching])
    ok = np.array([lead in f for f in track.fingers_touching]) & (n_touch >= p.min_fingers)
    clock = track.clock_ns
    free = meta.get("object_mode", "free") != "demo"
    breaks = scene_breaks(session, track)
    runs = []
    for lo, hi in _split_at(_merged_runs(clock, ok, p.max_gap_s), breaks):
        dur = (int(clock[hi - 1]) - int(clock[lo])) * 1e-9
        if dur >= p.min_duration_s:
            runs.append((lo, hi, dur, "stable contact"))
        elif dur >= p.min_confirmed_s and _lift_confirmed(track, lo, hi, p, free):
            runs.append((lo, hi, dur, "lift-confirmed contact"))
    wrap = wrap_mask(track, _hand(hand), p.min_fingers, p.power_inner_fingers)
    wraps = [(lo, hi, (int(clock[hi - 1]) - int(clock[lo])) * 1e-9)
             for lo, hi in _split_at(_merged_runs(clock, wrap, p.max_gap_s), breaks)]
    wraps = [w for w in wraps if w[2] >= p.power_min_s and _lift_confirmed(track, *w[:2], p, free)]
    # a lifted wrap is the grasp: the fingertip runs inside it are the same grasp
    runs = [r for r in runs if not any(r[0] < hi and lo < r[1] for lo, hi, _ in wraps)]
    marks = _mark_states(session, track, p, lead, ok)
    window_ns = p.mark_window_s * 1e9
    moments: dict[int, tuple[str, float, int | None, bool]] = {}
    for lo, hi, dur in wraps:
        near = [m for m in marks
                if clock[lo] - window_ns <= clock[m] <= clock[hi - 1] + window_ns]
        marks = [m for m in marks if m not in near]
        at = _wrap_moment(track, lo, hi, wrap, near[0] if near else None, p.mark_snap_s)
        moments[at] = ("grasp_mark" if near else "lift-confirmed wrap", dur, hi, True)
    for lo, hi, dur, how in runs:
        near = [m for m in marks
                if clock[lo] - window_ns <= clock[m] <= clock[hi - 1] + window_ns]
        marks = [m for m in marks if m not in near]
        moments[near[0] if near else _best_in(track, lo, hi, ok)] = (
            "grasp_mark" if near else how, dur, hi, False)
    for m in marks:
        moments[m] = ("grasp_mark", 0.0, None, False)
    if not moments:
        raise DemoError(f"{path}: no usable grasp: {_why_not(track, n_touch, ok, lead, p)}"
                        + (f"; a whole-hand wrap touched but was not held {p.power_min_s} s "
                           f"and lifted" if wrap.any() else ""))
    changes = object_changes(session, track)
    return [_demo_at(session, track, i, hand, object_at(changes, i, obj), how, dur, end, power)
            for i, (how, dur, end, power) in sorted(moments.items())]


def _wrap_moment(track: Track, lo: int, hi: int, wrap: np.ndarray, mark: int | None,
                 snap_s: float) -> int:
    """The moment of the wrap run [lo, hi): the wrap state with the most hand bodies on the
    object within ``snap_s`` of an operator's mark (the nearest of ties), else the run's
    fullest (:func:`_best_in`)."""
    if mark is not None:
        idx = np.flatnonzero(wrap & (np.abs(track.clock_ns - track.clock_ns[mark]) <= snap_s * 1e9))
        if len(idx):
            n = np.array([len(track.bodies_touching[k]) for k in idx])
            best = idx[n == n.max()]
            return int(best[np.argmin(np.abs(best - mark))])
    return _best_in(track, lo, hi, wrap, power=True)


def _heights_m(track: Track, key: str, lo: int, hi: int) -> np.ndarray:
    """World z (metres) of ``key`` (``"palm_pos_m"``, ``"object_pos_m"``) in states [lo, hi)."""
    return np.array([float(s[key][2]) for s in track.states[lo:hi]])


def _lift_confirmed(track: Track, lo: int, hi: int, p: DemoParams, free: bool) -> bool:
    """Whether the hand lifted the grasp of the contact run [lo, hi) (:class:`DemoParams`).

    Free object: within the run (the fingers still on it) the object rose ``lift_confirm_m``
    above where it was at the run's start, and so did the palm — the hand carried it up, which
    a push or a tumble does not do. Demonstration mode (the object is held fixed, so it cannot
    rise): the palm rose ``lift_confirm_m`` within ``lift_window_s`` after the run's last
    state — the operator lifting what they grasped."""
    if free:
        obj = _heights_m(track, "object_pos_m", lo, hi)
        palm = _heights_m(track, "palm_pos_m", lo, hi)
        rose = (obj - obj[0] >= p.lift_confirm_m) & (palm - palm[0] >= p.lift_confirm_m)
        return bool(rose.any())
    end = int(np.searchsorted(track.clock_ns, track.clock_ns[hi - 1] + p.lift_window_s * 1e9,
                              side="right"))
    palm = _heights_m(track, "palm_pos_m", lo, end)
    return bool(palm[hi - lo - 1:].max() - palm[0] >= p.lift_confirm_m)


def _split_at(runs: list[tuple[int, int]], breaks: list[int]) -> list[tuple[int, int]]:
    """``runs`` ([start, stop) state ranges) cut at every break index inside one: the part
    before ends at the break, the part after starts after it."""
    out = []
    for lo, hi in runs:
        for b in breaks:
            if lo < b < hi:
                out.append((lo, b))
                lo = b + 1
        if lo < hi:
            out.append((lo, hi))
    return out


def _mark_states(session: Session, track: Track, p: DemoParams, lead: str,
                 ok: np.ndarray) -> list[int]:
    """State indices of the ``grasp_mark`` events that have a usable state nearby."""
    out = []
    for t, ev in session.events():
        if ev.get("type") != "grasp_mark":
            continue
        i = marked_state(track, t, ev)
        dt_ns = np.abs(track.clock_ns - track.clock_ns[i])
        snap = np.flatnonzero(ok & (dt_ns <= p.mark_snap_s * 1e9))
        win = np.flatnonzero(ok & (dt_ns <= p.mark_window_s * 1e9))
        if len(snap):
            n = np.array([len(track.fingers_touching[k]) for k in snap])
            best = snap[n == n.max()]
            out.append(int(best[np.argmin(np.abs(best - i))]))
        elif len(win):
            out.append(int(win[np.argmin(np.abs(win - i))]))
        else:
            log.warning("%s: grasp_mark at %.2f s has no state with >= %d fingertips (%s among "
                        "them) touching the object within %.1f s; ignored", session.path,
                        session_time_s(track, i), p.min_fingers, lead,
                        p.mark_window_s)
    return out


def _why_not(track: Track, n_touch: np.ndarray, ok: np.ndarray, lead: str,
             p: DemoParams) -> str:
    if not n_touch.any():
        return "no fingertip ever touched the object"
    if not ok.any():
        most = max(track.fingers_touching, key=len)
        return (f"never {p.min_fingers} fingertips with the {lead} among them in contact (most "
                f"at once: {sorted(most)})")
    longest = max((int(track.clock_ns[hi - 1]) - int(track.clock_ns[lo])) * 1e-9
                  for lo, hi in _runs(ok))
    return (f"the longest contact with >= {p.min_fingers} fingertips lasted {longest:.2f} s, "
            f"less than {p.min_duration_s} s, the hand did not lift a shorter one "
            f"({p.lift_confirm_m * 100:g} cm), and no grasp_mark event was usable")
