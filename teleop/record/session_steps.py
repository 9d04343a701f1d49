"""A recorded bridge session as per-step arrays: what the person's demonstration is, step by step.

Why: a session used as training data (``dexaug export SESSION.mcap --format lerobot``,
:mod:`augment.export.lerobot_sessions`) is read as arrays of the bridge's steps, exactly the
numbers the recording holds. The pairing of ``/state`` and ``/contacts`` and the one simulated
clock are :func:`teleop.record.demo_track.read_track`'s (the demo extraction's), so both read a
session alike. What a step holds: :class:`sim.session_steps.SessionSteps`.

Steps before the first hand frame carry no target (the hand waits parked) and are left out;
a session without ``/state`` or without targets, a step with a non-finite joint or target, or
an object change mid-session (one episode names one object) is refused with a one-line
:class:`SessionError`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sim.demo import DemoError
from sim.session_steps import SessionSteps
from teleop.record.demo_track import object_changes, read_track
from teleop.record.session import SessionError, open_session

__all__ = ["read_session_steps"]


def _floats(rows: list[Any], width: int, where: str, what: str) -> np.ndarray:
    """Rows of JSON numbers (null: non-finite) as (steps, width) float64, every value finite."""
    short = [i for i, r in enumerate(rows) if r is None or len(r) != width]
    if short:
        raise SessionError(f"{where}: /state step {short[0]} has no {what} of {width} values")
    arr = np.array([[np.nan if v is None else v for v in r] for r in rows],
                   dtype=np.float64).reshape(len(rows), width)
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if len(bad):
        raise SessionError(f"{where}: /state step {bad[0]} has a non-finite {what}")
    return arr


def _scalar_extras(states: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """The ``extra`` values every step has as one number or truth value (module docstring)."""
    out = {}
    for key in states[0].get("extra", {}):
        values = [s.get("extra", {}).get(key) for s in states]
        if all(isinstance(v, bool) for v in values):
            out[key] = np.array(values, dtype=bool)
        elif all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
            out[key] = np.array(values, dtype=np.float64)
    return out


def read_session_steps(path: Path | str) -> SessionSteps:
    """The steps of the session at ``path`` (module docstring)."""
    path = Path(path)
    session = open_session(path)
    meta = session.metadata
    joints, fingers = tuple(meta.get("joint_names", ())), tuple(meta.get("fingers", ()))
    if not joints or not meta.get("hand") or not meta.get("object"):
        raise SessionError(f"{path}: its metadata names no hand, object or joint_names")
    try:
        track = read_track(session, fingers)
    except DemoError as exc:
        raise SessionError(str(exc)) from None
    targets = [s.get("extra", {}).get("q_target") for s in track.states]
    first = next((i for i, q in enumerate(targets) if q is not None), None)
    if first is None:
        raise SessionError(f"{path}: its /state messages record no joint targets "
                           "(extra.q_target): a bridge session's do; this one is no teleop "
                           "recording of the bridge (scripted demos hold states only)")
    changes = [name for _, name in object_changes(session, track)]
    if any(name != meta["object"] for name in changes):
        raise SessionError(f"{path}: the object changes during the session ({meta['object']} "
                           f"to {', '.join(changes)}); one episode names one object")
    states, n, where = track.states[first:], len(joints), str(path)
    pose = [s["palm_pos_m"] + s["palm_quat_wxyz"] for s in states]
    obj = [s["object_pos_m"] + s["object_quat_wxyz"] for s in states]
    touching = (None if not session.counts.get("/contacts") else
                np.array([[f in t for f in fingers] for t in track.fingers_touching[first:]],
                         dtype=bool).reshape(len(states), len(fingers)))
    marks = [{"t_s": ev.get("t_s"), **(ev.get("payload") or {})}
             for _, ev in session.events() if ev.get("type") == "grasp_mark"]
    return SessionSteps(
        path=path, hand=str(meta["hand"]), object=str(meta["object"]), joint_names=joints,
        finger_names=fingers, clock_ns=np.asarray(track.clock_ns[first:], np.int64),
        qpos=_floats([s["qpos"] for s in states], n, where, "qpos"),
        q_target=_floats(targets[first:], n, where, "extra.q_target"),
        palm_pose=_floats(pose, 7, where, "palm pose"),
        object_pose=_floats(obj, 7, where, "object pose"),
        tracked=np.array([bool(s.get("tracked", True)) for s in states]), touching=touching,
        extras=_scalar_extras(states), metadata=dict(meta), grasp_marks=marks)
