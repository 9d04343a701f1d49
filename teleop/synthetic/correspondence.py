"""The retargeter's operator-wrist ↔ robot-palm correspondence for one robot hand, used
inversely (:class:`Correspondence`): where the operator's wrist must be for the robot palm to
land on a pose, and where an operator fingertip must be for the robot pulp site to land on a
point (the forward map is :mod:`teleop.retarget.retargeter`'s).

Positions metres; rotations as 3×3 matrices (columns: the axes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.hand.model import Hand
from sim.transforms import quat_to_mat
from teleop.retarget.config import WRIST_TO_PALM_CONVENTION, load_retarget_config

__all__ = ["Correspondence"]

Array = np.ndarray


class Correspondence:
    """The inverse retarget map of robot hand ``hand`` (module docstring). ``r_pw`` / ``p_pw``:
    the operator wrist's axes and origin in frame_palm; ``mapping``: the hand's
    :class:`teleop.retarget.config.HandMapping`. config_path: another teleop.toml for
    ``[retarget]`` (the hand's mapping comes from its folder either way)."""

    def __init__(self, hand: Hand, config_path: Path | str | None) -> None:
        cfg = load_retarget_config(config_path)
        self.config = cfg
        self.mapping = cfg.hand(hand.name)
        # palm ← operator wrist: rotation (columns: wrist axes in frame_palm) and origin
        self.r_pw = WRIST_TO_PALM_CONVENTION @ quat_to_mat(self.mapping.wrist_quat_wxyz)
        self.p_pw = np.asarray(self.mapping.wrist_pos_m, dtype=float)
        tips_open = hand.fingertip_sites(hand.open_pose, frame="palm")[0]
        self.robot_length_m = float(np.linalg.norm(
            tips_open[hand.finger_names.index(self.mapping.scale_finger)] - self.p_pw))

    def scale(self, operator_length_m: float) -> float:
        """The retargeter's fingertip scale for an operator of this bone-chain length."""
        return self.robot_length_m / operator_length_m * self.config.scale

    def world_of_tracking(self, p_m: Array) -> Array:
        """A tracking-space point (metres) where the retargeter puts it in the world."""
        return np.asarray(p_m) * self.config.wrist_position_scale + self.config.world_offset_m

    def tracking_of_world(self, p_m: Array) -> Array:
        """A world point (metres) in tracking space: the inverse of :meth:`world_of_tracking`."""
        return (np.asarray(p_m) - self.config.world_offset_m) / self.config.wrist_position_scale

    def wrist_for_palm(self, palm_pos_m: Array, palm_rot: Array) -> tuple[Array, Array]:
        """Operator wrist (tracking-space position, metres; axes) that puts frame_palm at
        (palm_pos_m, palm_rot) in the world."""
        r_w = palm_rot @ self.r_pw
        return self.tracking_of_world(palm_pos_m + palm_rot @ self.p_pw), r_w

    def palm_for_wrist(self, wrist_pos_m: Array, wrist_rot: Array) -> tuple[Array, Array]:
        """frame_palm in the world (position metres, axes) for an operator wrist pose
        (tracking space): the inverse of :meth:`wrist_for_palm`."""
        palm_rot = wrist_rot @ self.r_pw.T
        palm_pos = self.world_of_tracking(wrist_pos_m) - palm_rot @ self.p_pw
        return palm_pos, palm_rot

    def operator_tip_for(self, tip_palm_m: Array, scale: float) -> Array:
        """Operator fingertip (wrist frame, metres) that maps onto robot point ``tip_palm_m``
        (frame_palm) before the pinch adjustment."""
        return self.r_pw.T @ (np.asarray(tip_palm_m) - self.p_pw) / scale
