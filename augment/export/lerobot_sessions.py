"""A recorded teleop session as one LeRobot episode: the person's demonstration at a whole frame rate.

Why: the sessions a person records through the bridge are the demonstrations augmentation
starts from; exported with the rollouts' writer (:mod:`augment.export.lerobot`) they train a
policy in LeRobot as they were performed. The steps are a
:class:`sim.session_steps.SessionSteps`, as :func:`teleop.record.session_steps.read_session_steps`
reads them from the file; this module only says what a frame of them is.

Frames are ticks of a whole rate ``fps`` (LeRobot's ``fps`` is an int: its info.json, its
check that ``timestamp`` ≈ ``frame_index / fps`` within 1e-4 s, its video encoding; the
bridge steps every 12 ms, 83.33… steps a second, no whole rate). Frame k is tick k / fps
seconds after the session's first step, and holds the latest recorded step at or before that
tick (sample and hold: every value is one the recording holds, bit for bit, none
interpolated; ``session.step`` says which); ``timestamp`` is exactly ``k / fps`` (float32, as
LeRobot stores it). The ticks run while a step is at or before them: the steps after the last
tick (less than one frame period of them) are in no frame. An ``fps`` above the session's
own step rate is refused (two ticks would hold one step, a frame repeated), as are steps
unevenly spaced (a dropped step: the session has no one step rate to compare with).
:data:`SESSION_FPS` is the default. Per frame:

- ``observation.state``: the hand's joints as recorded (``<joint>.pos``, rad), then
  frame_palm's pose and the object's (``palm.x`` … ``palm.qz``, ``object.x`` …; metres, wxyz,
  world), as a rollout's without the joint velocities (not recorded);
- ``action``: the joint targets in force at the tick: those the retargeter commanded for the
  held step (``<joint>.pos``, rad);
- ``observation.fingertip_contact``: 1.0 where a finger touches the object (per finger of the
  session's metadata), where the session has ``/contacts``; no forces (none are recorded);
- ``session.tracked`` and ``session.<extra>``: the step's tracking flag and its other scalar
  extras (grasp assist level, held, ...), as recorded;
- ``session.step``: the held step's index among the session's steps (int64);
- ``next.done`` true on the last frame; ``timestamp``: ``frame_index / fps`` seconds.

All floats are the recording's float64 numbers bit for bit. The ``dexaug/...`` columns: the
session file, hand, object, rig, the simulated time of the first frame, the ``grasp_mark``
events, the whole metadata record (JSON) and the session's own step rate
(``dexaug/step_hz``). There is no verdict (a session is a person's
attempt, not a validated rollout), hence no ``next.success``.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from augment.export.lerobot_episode import LeRobotEpisode
from augment.export.lerobot_frames import POSE_NAMES, task_text
from sim.errors import DexaugError
from sim.session_steps import SessionSteps

__all__ = ["SESSION_FPS", "session_episode", "step_rate_hz", "tick_steps"]

#: how far a step may stray from the session's step and still count as the same rate (ns)
STEP_TOLERANCE_NS = 1000
#: default frames a second of a session's episode: 50, the rate of LeRobot's ALOHA datasets
#: (and ACT's), the highest of LeRobot's usual rates (10, 15, 30, 50) below the bridge's
#: 83.33 steps a second. It keeps 3 of every 5 steps (30 fps: 9 of 25) and holds a step at
#: most 12 ms (one bridge step) old, against up to 33 ms at 30 fps, for a hand that closes
#: on an object in a few tenths of a second
SESSION_FPS = 50
NS_PER_S = 1_000_000_000


def _step_ns(steps: SessionSteps) -> np.ndarray:
    """The gaps between the session's steps (ns), or a one-line error where they are not
    evenly spaced (a dropped or doubled step) or there is only one step."""
    dt = np.diff(steps.clock_ns)
    if not len(dt):
        raise DexaugError(f"{steps.path}: one step only: no frame rate to give LeRobot")
    step = int(np.median(dt))
    if step <= 0 or np.abs(dt - step).max() > STEP_TOLERANCE_NS:
        raise DexaugError(f"{steps.path}: its steps are not evenly spaced ({dt.min() * 1e-9:.4f} "
                          f"to {dt.max() * 1e-9:.4f} s): no one step rate to resample from")
    return dt


def step_rate_hz(steps: SessionSteps) -> float:
    """The session's own steps a second (its longest step's inverse, so every tick of an fps up
    to it holds a step of its own); a one-line error where the steps are uneven (module
    docstring)."""
    return NS_PER_S / float(_step_ns(steps).max())


def tick_steps(steps: SessionSteps, fps: int) -> np.ndarray:
    """Per frame k (tick k / ``fps`` s after the first step) the index of the latest step at
    or before it (module docstring); a one-line error for an ``fps`` that is no whole number
    above 0 or above the session's step rate. Integer nanoseconds throughout (step k / fps
    compared as ``t_ns * fps <= k * 1e9``), so no tick lands on the wrong side of a step by
    rounding."""
    if isinstance(fps, bool) or not isinstance(fps, int | np.integer) or fps <= 0:
        raise DexaugError(f"fps {fps!r}: a LeRobot frame rate is a whole number above 0")
    longest_ns = int(_step_ns(steps).max())
    if fps * longest_ns > NS_PER_S:
        raise DexaugError(f"{steps.path}: fps {fps} is above the session's step rate "
                          f"({NS_PER_S / longest_ns:.3f} steps/s): frames would repeat; "
                          f"give at most {NS_PER_S // longest_ns}")
    scaled_ns = (steps.clock_ns - steps.clock_ns[0]) * int(fps)   # step times × fps
    ticks = np.arange(int(scaled_ns[-1]) // NS_PER_S + 1, dtype=np.int64) * NS_PER_S
    return np.searchsorted(scaled_ns, ticks, side="right") - 1


def _features(steps: SessionSteps) -> dict[str, dict[str, Any]]:
    def vec(names: list[str]) -> dict[str, Any]:
        return {"dtype": "float64", "shape": [len(names)], "names": names}

    joints = [f"{j}.pos" for j in steps.joint_names]
    out = {"observation.state": vec(joints + [f"palm.{p}" for p in POSE_NAMES]
                                    + [f"object.{p}" for p in POSE_NAMES]),
           "action": vec(joints)}
    if steps.touching is not None:
        out["observation.fingertip_contact"] = vec(list(steps.finger_names))
    scalars = {"session.tracked": steps.tracked,
               **{f"session.{k}": v for k, v in steps.extras.items()}}
    out.update({k: {"dtype": "bool" if v.dtype == bool else "float64", "shape": [1],
                    "names": None} for k, v in scalars.items()})
    out["session.step"] = {"dtype": "int64", "shape": [1], "names": None}
    out["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
    return out


def session_episode(steps: SessionSteps, fps: int = SESSION_FPS) -> LeRobotEpisode:
    """The session's steps as the LeRobot writer's episode at ``fps`` frames a second (module
    docstring)."""
    at = tick_steps(steps, fps)
    n = len(at)
    columns: dict[str, np.ndarray] = {
        "observation.state": np.concatenate([steps.qpos, steps.palm_pose, steps.object_pose],
                                            axis=1)[at],
        "action": steps.q_target[at]}
    if steps.touching is not None:
        columns["observation.fingertip_contact"] = steps.touching[at].astype(np.float64)
    columns["session.tracked"] = steps.tracked[at]
    columns.update({f"session.{k}": v[at] for k, v in steps.extras.items()})
    columns["session.step"] = at.astype(np.int64)
    columns["next.done"] = np.arange(n) == n - 1
    columns["timestamp"] = (np.arange(n) / fps).astype(np.float32)
    meta = {"dexaug/session": steps.path.name, "dexaug/hand": steps.hand,
            "dexaug/object": steps.object, "dexaug/rig": str(steps.metadata.get("rig", "")),
            "dexaug/first_t_s": int(steps.clock_ns[0]) * 1e-9,
            "dexaug/step_hz": step_rate_hz(steps),
            "dexaug/grasp_marks": json.dumps(steps.grasp_marks),
            "dexaug/metadata": json.dumps(steps.metadata, default=str)}
    return LeRobotEpisode(columns, _features(steps), task_text(steps.object, steps.hand),
                          int(fps), steps.hand, meta)
