"""A recorded bridge session as per-step arrays: the data type shared by its reader and its users.

Why here: :func:`teleop.record.session_steps.read_session_steps` makes it from an MCAP file and
:mod:`augment.export.lerobot_sessions` writes it as a LeRobot episode; ``augment`` sits below
``teleop``, so the type lives in the common layer, as :class:`sim.demo.Demo` does for the demos
extracted from the same sessions. Per step (one ``/state`` message):

- ``qpos``: the robot hand's joints as simulated (radians, the metadata's ``joint_names``);
- ``q_target``: the joint targets the retargeter gave the bridge for that step
  (``/state`` ``extra.q_target``, radians, same order): the command. The bridge adds the grasp
  assist's squeeze deflection to it (its level is the step's ``assist`` extra), and moves the
  hand base to the retargeted wrist pose, which is not recorded (the palm's achieved pose is);
- ``palm_pose``, ``object_pose``: frame_palm and the object in the world (metres, wxyz);
- ``tracked``: the operator's hand was tracked; ``extras``: the step's other scalar
  ``extra`` values (``held``, ``grasp_stable``, ``grasp_held_s``, ``assist``, ``grip_n`` in
  today's bridge), each kept where every step has it;
- ``touching``: per finger of the metadata's ``fingers``, whether it touches the object
  (``/contacts``; None when the session has none). The bridge records no contact forces
  (``force_n`` is null), so none are given.

Times: ``clock_ns``, integer nanoseconds of the session's simulated clock (``t_s``, continuous
across a rebuilt scene).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["SessionSteps"]


@dataclass
class SessionSteps:
    """One session's steps (module docstring); rows = steps, in recording order."""

    path: Path
    hand: str
    object: str
    joint_names: tuple[str, ...]
    finger_names: tuple[str, ...]
    clock_ns: np.ndarray
    qpos: np.ndarray
    q_target: np.ndarray
    palm_pose: np.ndarray
    object_pose: np.ndarray
    tracked: np.ndarray
    touching: np.ndarray | None
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    #: the session's metadata record, and its ``grasp_mark`` events (their payloads, ``t_s``)
    metadata: dict[str, Any] = field(default_factory=dict)
    grasp_marks: list[dict[str, Any]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.clock_ns)
