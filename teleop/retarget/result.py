"""What one retargeting step returns (:class:`RetargetResult`) and why a frame can be held.

Kept apart from :mod:`teleop.retarget.retargeter` so that consumers of results (the bridge,
offline traces) need not know the solver. Quaternions wxyz, positions metres, joints radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HOLD_REASONS", "RetargetResult"]

Array = np.ndarray

#: Why a frame was held (the keys of :attr:`teleop.retarget.retargeter.Retargeter.held_counts`).
HOLD_REASONS = ("no_hand", "untracked", "invalid_joints", "solver_failed")


@dataclass(frozen=True)
class RetargetResult:
    """One retargeted frame.

    q: (nq,) full joint vector, radians, in ``Hand.joint_names`` order (filtered, coupled,
    within limits). base_pos_m / base_quat_wxyz: where to put the hand model's base (its model
    frame, the root) in the world so the robot's wrist follows the operator's wrist.
    palm_pos_m / palm_quat_wxyz: the resulting frame_palm pose in the world. tip_targets_m,
    tip_positions_m: (nfingers, 3) the fingertip targets (the operator's finger pads, scaled,
    pinch-adjusted and snapped onto the object) and the achieved pulp sites of ``q``, both in
    the hand's base frame.
    tip_errors_m: (nfingers,) their distances. snap_moved_m: (nfingers,) how far each target
    was moved onto the object surface (metres; 0 without an object or out of snap range).
    held: this frame repeats the last output, for
    ``reason`` (one of :data:`HOLD_REASONS`). time_s: the frame's timestamp (None if unknown).
    The arrays are read-only: a held frame shares them with the frame it repeats.
    """

    q: Array
    base_pos_m: Array
    base_quat_wxyz: Array
    palm_pos_m: Array
    palm_quat_wxyz: Array
    tip_targets_m: Array
    tip_positions_m: Array
    tip_errors_m: Array
    held: bool = False
    reason: str | None = None
    time_s: float | None = None
    snap_moved_m: Array | None = None
