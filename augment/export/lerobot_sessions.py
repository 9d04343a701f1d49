"""A recorded teleop session as one LeRobot episode: the person's demonstration, frame by step.

Why: the sessions a person records through the bridge are the demonstrations augmentation
starts from; exported with the rollouts' writer (:mod:`augment.export.lerobot`) they train a
policy in LeRobot as they were performed. The steps are a
:class:`sim.session_steps.SessionSteps`, as :func:`teleop.record.session_steps.read_session_steps`
reads them from the file; this module only says what a frame of them is.

Frame t is step t of the session, at the recording's rate (the bridge's step, 12 ms today:
83.33… frames a second; ``fps`` is written as that number, an int only where the rate is
whole, and the timestamps are the session's simulated clock, so LeRobot's
``delta_timestamps`` in multiples of the step find the frames):

- ``observation.state``: the hand's joints as recorded (``<joint>.pos``, rad), then
  frame_palm's pose and the object's (``palm.x`` … ``palm.qz``, ``object.x`` …; metres, wxyz,
  world), as a rollout's without the joint velocities (not recorded);
- ``action``: the joint targets the retargeter commanded that step (``<joint>.pos``, rad);
- ``observation.fingertip_contact``: 1.0 where a finger touches the object (per finger of the
  session's metadata), where the session has ``/contacts``; no forces (none are recorded);
- ``session.tracked`` and ``session.<extra>``: the step's tracking flag and its other scalar
  extras (grasp assist level, held, ...), as recorded;
- ``next.done`` true on the last frame; ``timestamp``: seconds from the first frame.

All floats are the recording's float64 numbers bit for bit. The ``dexaug/...`` columns: the
session file, hand, object, rig, the simulated time of the first frame, the ``grasp_mark``
events and the whole metadata record (JSON). There is no verdict (a session is a person's
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

__all__ = ["session_episode", "session_fps"]

#: how far a step may stray from the session's step and still count as the same rate (ns)
STEP_TOLERANCE_NS = 1000


def session_fps(steps: SessionSteps) -> int | float:
    """Frames a second of a session whose steps are evenly spaced (module docstring); a
    one-line error where they are not (a dropped or doubled step) or there is only one."""
    dt = np.diff(steps.clock_ns)
    if not len(dt):
        raise DexaugError(f"{steps.path}: one step only: no frame rate to give LeRobot")
    step = int(np.median(dt))
    if step <= 0 or np.abs(dt - step).max() > STEP_TOLERANCE_NS:
        raise DexaugError(f"{steps.path}: its steps are not evenly spaced ({dt.min() * 1e-9:.4f} "
                          f"to {dt.max() * 1e-9:.4f} s): a LeRobot episode has one frame rate")
    fps = 1e9 / step
    return round(fps) if abs(fps - round(fps)) < 1e-9 else fps


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
    out["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
    return out


def session_episode(steps: SessionSteps) -> LeRobotEpisode:
    """The session's steps as the LeRobot writer's episode (module docstring)."""
    n = len(steps)
    fps = session_fps(steps)
    columns: dict[str, np.ndarray] = {
        "observation.state": np.concatenate([steps.qpos, steps.palm_pose, steps.object_pose],
                                            axis=1),
        "action": steps.q_target}
    if steps.touching is not None:
        columns["observation.fingertip_contact"] = steps.touching.astype(np.float64)
    columns["session.tracked"] = steps.tracked
    columns.update({f"session.{k}": v for k, v in steps.extras.items()})
    columns["next.done"] = np.arange(n) == n - 1
    columns["timestamp"] = ((steps.clock_ns - steps.clock_ns[0]) * 1e-9).astype(np.float32)
    meta = {"dexaug/session": steps.path.name, "dexaug/hand": steps.hand,
            "dexaug/object": steps.object, "dexaug/rig": str(steps.metadata.get("rig", "")),
            "dexaug/first_t_s": int(steps.clock_ns[0]) * 1e-9,
            "dexaug/grasp_marks": json.dumps(steps.grasp_marks),
            "dexaug/metadata": json.dumps(steps.metadata, default=str)}
    return LeRobotEpisode(columns, _features(steps), task_text(steps.object, steps.hand), fps,
                          steps.hand, meta)
