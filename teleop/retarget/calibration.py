"""Per-operator scale calibration: the operator's reference length from tracked frames
(:func:`operator_length_m`), either from frames at hand or from the next seconds of tracking
(:class:`ScaleCalibration`, what :meth:`teleop.retarget.retargeter.Retargeter.recalibrate` and
the automatic calibration at the start use).

scale = robot length / operator length × ``scale`` (config). The robot length is the
straight-line distance from ``wrist_pos_m`` to the pulp site of ``scale_finger`` at the open
pose (fingers straight). The operator length is the sum of the bone lengths from the wrist
through that finger's OpenXR chain to its tip joint, median over the frames: unlike the
wrist-to-tip distance, a bone chain does not change when the operator curls the finger, so any
stretch of tracking calibrates, not only flat-hand frames. Palm width was rejected: it is short
(≈ 8 cm), so tracking noise weighs more than twice as much, and the hand configs name no
knuckle points to measure it on the robot.

Why from the *next* seconds: an operator who puts on the headset of another, or whose
tracking was poor while the bridge started, asks for a new calibration (a control command)
and the following ``calibration_s`` of tracking is measured; the current scale stays in use
until then, so the robot hand does not freeze or jump while it collects.

Metres, seconds.
"""

from __future__ import annotations

import numpy as np

from teleop.messages import JOINT_INDEX, OPENXR_JOINTS, HandState

__all__ = ["MIN_CALIBRATION_FRAMES", "ScaleCalibration", "chain_length_m", "operator_chain"]

Array = np.ndarray

#: A calibration over time needs at least this many usable frames, however long it ran.
MIN_CALIBRATION_FRAMES = 10


def operator_chain(tip_joint: str) -> tuple[str, ...]:
    """OpenXR joints from the wrist along ``tip_joint``'s finger up to it (e.g. wrist,
    middle_metacarpal, …, middle_tip)."""
    prefix = tip_joint.rsplit("_", 1)[0] + "_"
    chain = [j for j in OPENXR_JOINTS[:JOINT_INDEX[tip_joint] + 1] if j.startswith(prefix)]
    return ("wrist", *chain)


def chain_length_m(hand: HandState | None, chain_idx: Array) -> float | None:
    """Bone-chain length (metres) through joints ``chain_idx`` of a tracked hand; None when
    the hand is missing, untracked or any chain joint invalid."""
    if hand is None or not hand.tracked or not hand.valid[chain_idx].all():
        return None
    pts = hand.positions[chain_idx]
    if not np.isfinite(pts).all():
        return None
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


class ScaleCalibration:
    """Collects chain lengths over ``duration_s`` of tracking (device time; ``dt_s`` per frame
    where frames carry no time) and then yields their median (:meth:`feed`)."""

    def __init__(self, chain_idx: Array, duration_s: float, dt_s: float) -> None:
        self.chain_idx = chain_idx
        self.duration_s = float(duration_s)
        self.dt_s = float(dt_s)
        self.lengths: list[float] = []
        self._t_first: float | None = None
        self._elapsed_s = 0.0

    def feed(self, hand: HandState | None, time_s: float | None) -> float | None:
        """Take one frame; the operator length (metres) once ``duration_s`` of usable frames
        (and at least :data:`MIN_CALIBRATION_FRAMES`) are in, else None."""
        length = chain_length_m(hand, self.chain_idx)
        if length is None:
            return None
        self.lengths.append(length)
        if time_s is None:
            self._elapsed_s += self.dt_s
        else:
            self._t_first = time_s if self._t_first is None else self._t_first
            self._elapsed_s = time_s - self._t_first
        if self._elapsed_s >= self.duration_s and len(self.lengths) >= MIN_CALIBRATION_FRAMES:
            return float(np.median(self.lengths))
        return None
