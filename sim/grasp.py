"""The grasp record shared by the validator, the augmenter and the dataset."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.errors import GraspInputError


@dataclass(frozen=True)
class Grasp:
    """A grasp as DESIGN §3 defines it: frame_palm in the object frame (metres, quaternion wxyz)
    and the full hand joint vector (model order, radians). ``pregrasp`` and ``squeeze`` are the
    joint vectors to close from and to, when the grasp carries them (a benchmark's or a
    generator's own); without them a validator makes them by a named convention
    (:mod:`sim.validate.stages`)."""

    palm_pos: np.ndarray
    palm_quat_wxyz: np.ndarray
    joints: np.ndarray
    pregrasp: np.ndarray | None = None
    squeeze: np.ndarray | None = None

    @classmethod
    def from_arrays(cls, palm_pos: np.ndarray | list[float], palm_quat_wxyz: np.ndarray | list[float],
                    joints: np.ndarray | list[float], *, pregrasp: np.ndarray | list[float] | None = None,
                    squeeze: np.ndarray | list[float] | None = None) -> Grasp:
        """Check shapes and values; normalise a quaternion that is off by rounding only."""
        pos = np.asarray(palm_pos, dtype=float)
        quat = np.asarray(palm_quat_wxyz, dtype=float)
        q = np.asarray(joints, dtype=float)
        if pos.shape != (3,) or not np.isfinite(pos).all():
            raise GraspInputError(f"palm_pos: expected 3 finite numbers (metres), got {pos.tolist()}")
        if quat.shape != (4,) or not np.isfinite(quat).all():
            raise GraspInputError(f"palm_quat_wxyz: expected 4 finite numbers, got {quat.tolist()}")
        norm = np.linalg.norm(quat)
        if abs(norm - 1.0) > 1e-3:
            raise GraspInputError(f"palm_quat_wxyz: expected a unit quaternion (w, x, y, z), got "
                                  f"norm {norm:.4f}")
        if q.ndim != 1 or not np.isfinite(q).all():
            raise GraspInputError(f"joints: expected a flat vector of finite angles, got shape {q.shape}")
        stages = []
        for name, value in (("pregrasp", pregrasp), ("squeeze", squeeze)):
            arr = None if value is None else np.asarray(value, dtype=float)
            if arr is not None and (arr.shape != q.shape or not np.isfinite(arr).all()):
                raise GraspInputError(f"{name}: expected {q.size} finite joint values like joints, "
                                      f"got shape {arr.shape}")
            stages.append(arr)
        return cls(pos, quat / norm, q, *stages)
