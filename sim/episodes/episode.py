"""One rolled-out grasp as a trajectory, and a set of them split by verdict.

Layout (T physics steps of ``timestep_s``): step t applies the *actions* ``ctrl[t]`` (the
hand's actuator targets: joint or tendon positions of its position servos, radians) and the
hand base's mocap target ``base_target_pos[t]`` (metres, world) / ``base_target_quat[t]``
(wxyz) under the protocol's *conditions* ``gravity[t]`` (m/s², world), ``object_force[t]``
(newtons on the object's centre of mass, world) and ``pin_pose[t]`` (the object put back at
that pose after the step; NaN: not pinned), from the state of row t to that of row t + 1 of
the state arrays (:data:`sim.episodes.observe.STATE_KEYS`, T + 1 rows: the first is the
start, at the pregrasp or out on the approach). A rollout with a camera adds ``frames``
(K, h, w, 3), RGB uint8 images of the hand and object (a camera framed on them at the
start) showing state rows ``frame_rows`` (K).
``stage[t]`` names the protocol stage step t belongs to (:data:`STAGES`) and ``time_s[t]``
the simulation time before it. ``initial_state`` is the full MuJoCo state
(mjSTATE_INTEGRATION) of row 0 and ``initial_gravity`` the gravity then: with them, a fresh
model of the same scene replays the episode (:mod:`sim.episodes.replay`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["STAGES", "Episode", "EpisodeSet"]

#: the stages of a lift-drop rollout, in order: the hand comes in to the grasp (only with an
#: approach, :mod:`sim.episodes.approach`), the fingers close from the pregrasp onto the
#: squeeze target, settle there, the hand lifts, holds, and lets go
STAGES = ("approach", "close", "settle", "lift", "hold", "release")

_ARRAYS = ("initial_state", "initial_gravity", "time_s", "stage", "ctrl", "base_target_pos",
           "base_target_quat", "gravity", "object_force", "pin_pose", "frames", "frame_rows")


@dataclass
class Episode:
    """A grasp's rollout (module docstring for the arrays). ``success`` and ``failure`` are
    the validator's verdict on this very run; ``result`` its summary
    (:meth:`sim.validate.result.ValidationResult.summary`); ``grasp_index`` the grasp's row in
    the list it was rolled out from."""

    hand: str
    object: str
    protocol: str
    grasp_index: int
    success: bool
    failure: str | None
    timestep_s: float
    joint_names: tuple[str, ...]
    actuator_names: tuple[str, ...]
    finger_names: tuple[str, ...]
    initial_state: np.ndarray
    initial_gravity: np.ndarray
    time_s: np.ndarray
    stage: np.ndarray
    ctrl: np.ndarray
    base_target_pos: np.ndarray
    base_target_quat: np.ndarray
    gravity: np.ndarray
    object_force: np.ndarray
    pin_pose: np.ndarray
    states: dict[str, np.ndarray]
    result: dict[str, Any] = field(default_factory=dict)
    #: how far out along the palm normal the episode's approach started (metres; 0: none)
    approach_m: float = 0.0
    frames: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0, 3), np.uint8))
    frame_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    def __len__(self) -> int:
        """Number of steps (actions); the state arrays have one row more."""
        return len(self.time_s)

    def save(self, path: Path | str) -> None:
        """Write the episode as one ``.npz`` (arrays as they are, the rest as 0-d entries)."""
        out: dict[str, Any] = {k: getattr(self, k) for k in _ARRAYS}
        out.update({f"state/{k}": v for k, v in self.states.items()})
        meta = {f.name: getattr(self, f.name) for f in fields(self)
                if f.name not in _ARRAYS and f.name != "states"}
        out["meta"] = np.array(json.dumps(meta, default=_plain))
        np.savez_compressed(path, **out)

    @classmethod
    def load(cls, path: Path | str) -> Episode:
        """Read an episode :meth:`save` wrote."""
        with np.load(path, allow_pickle=False) as z:
            kw: dict[str, Any] = {k: z[k] for k in _ARRAYS}
            kw["states"] = {k.removeprefix("state/"): z[k] for k in z.files if k.startswith("state/")}
            kw.update(json.loads(str(z["meta"])))
        for k in ("joint_names", "actuator_names", "finger_names"):
            kw[k] = tuple(kw[k])
        return cls(**kw)


def _plain(value: Any) -> Any:
    """A NumPy scalar or array in the metadata as plain Python (for JSON)."""
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


@dataclass
class EpisodeSet:
    """Rollouts of many grasps: the successful ones, and the failed ones kept apart (each
    with its ``failure`` reason)."""

    succeeded: list[Episode] = field(default_factory=list)
    failed: list[Episode] = field(default_factory=list)

    def add(self, episode: Episode) -> None:
        (self.succeeded if episode.success else self.failed).append(episode)

    def failure_counts(self) -> dict[str, int]:
        """How many rollouts failed for each reason."""
        out: dict[str, int] = {}
        for e in self.failed:
            out[str(e.failure)] = out.get(str(e.failure), 0) + 1
        return out
