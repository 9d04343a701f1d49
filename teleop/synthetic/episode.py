"""A synthetic grasp episode: its phases and timing (:func:`phase_times`, :func:`min_jerk`), the
noise-free motion of the operator's hand through them (:class:`GraspMotion`), and the result
handed to callers (:class:`SynthEpisode`).

Phases: still, approach, close (the grasp mark at its end), grasp (fingers closed, object not
yet moved), lift, hold, release, retreat, end. The wrist starts ``approach_distance_m`` back
along the palm normal and up, slightly turned, and moves to the grasp pose with minimum-jerk
timing (how people move between two poses); the fingers close and open in joint space.

Units: metres, seconds (from the episode start unless said otherwise), radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.transforms import axis_angle_to_mat, slerp_mat
from teleop.messages import HandFrame
from teleop.synthetic.config import SynthConfig
from teleop.synthetic.human_hand import HandPose, lerp_pose

__all__ = ["GraspMotion", "SynthEpisode", "min_jerk", "phase_times"]

Array = np.ndarray


def min_jerk(s: Array | float) -> Array:
    """Minimum-jerk time scaling 10s³ − 15s⁴ + 6s⁵ (zero velocity and acceleration at the
    ends): how people move between two poses."""
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s)


def phase_times(cfg: SynthConfig) -> tuple[dict[str, tuple[float, float]], float]:
    """Phase name → (start, end) seconds from the episode start, and the total duration."""
    order = (("still", cfg.still_s), ("approach", cfg.approach_s), ("close", cfg.close_s),
             ("grasp", cfg.settle_s), ("lift", cfg.lift_s), ("hold", cfg.hold_s),
             ("release", cfg.release_s), ("retreat", cfg.retreat_s), ("end", 0.3))
    out, t = {}, 0.0
    for name, dur in order:
        out[name] = (t, t + dur)
        t += dur
    return out, t


@dataclass(frozen=True)
class GraspMotion:
    """The noise-free episode: the operator's wrist pose and hand pose at any time.

    phases / duration_s: from :func:`phase_times`. start_pos_m / start_rot: the wrist at the
    start; wrist_pos_m / wrist_rot: at the grasp (tracking space, metres; axes). away: unit
    direction the wrist retreats along; retreat_m: how far; lift_m: (3,) the lift offset.
    open_pose / grasp_pose: the hand before closing and at the grasp.
    """

    phases: dict[str, tuple[float, float]]
    duration_s: float
    start_pos_m: Array
    start_rot: Array
    wrist_pos_m: Array
    wrist_rot: Array
    away: Array
    retreat_m: float
    lift_m: Array
    open_pose: HandPose
    grasp_pose: HandPose

    @classmethod
    def plan(cls, cfg: SynthConfig, wrist_pos_m: Array, wrist_rot: Array, palm_rot: Array,
             grasp_pose: HandPose) -> GraspMotion:
        """The motion toward the grasp wrist pose whose robot palm axes are ``palm_rot``."""
        phases, t_end = phase_times(cfg)
        # palm normal (+y of frame_palm) points at the object: back off against it, and up
        away = -palm_rot[:, 1] + np.array([0.0, 0.0, 0.5])
        away /= np.linalg.norm(away)
        start_pos = wrist_pos_m + cfg.approach_distance_m * away
        # the start turned 0.35 rad about world z and −0.3 rad about the wrist's own x
        turn = axis_angle_to_mat(np.eye(3)[[2, 0]], np.array([0.35, -0.3]))
        start_rot = turn[0] @ wrist_rot @ turn[1]
        return cls(phases=phases, duration_s=t_end, start_pos_m=start_pos, start_rot=start_rot,
                   wrist_pos_m=wrist_pos_m, wrist_rot=wrist_rot, away=away,
                   retreat_m=cfg.approach_distance_m,
                   lift_m=np.array([0.0, 0.0, cfg.lift_height_m]),
                   open_pose=HandPose.relaxed(), grasp_pose=grasp_pose)

    def progress(self, name: str, t: float) -> float:
        """How far phase ``name`` is at time ``t`` (0 before, 1 after; min-jerk within)."""
        a, b = self.phases[name]
        return float(min_jerk((t - a) / (b - a))) if b > a else float(t >= b)

    def at(self, t: float) -> tuple[Array, Array, HandPose]:
        """Wrist position (metres), wrist axes and hand pose at time ``t`` (seconds from the
        episode start)."""
        s = self.progress
        p = self.start_pos_m + s("approach", t) * (self.wrist_pos_m - self.start_pos_m)
        r = slerp_mat(self.start_rot, self.wrist_rot, s("approach", t))
        p = p + s("lift", t) * self.lift_m
        p = p + s("retreat", t) * self.retreat_m * self.away
        closure = s("close", t) * (1.0 - s("release", t))
        return p, r, lerp_pose(self.open_pose, self.grasp_pose, closure)


@dataclass
class SynthEpisode:
    """A synthetic grasp episode.

    frames: the tracking frames (MuJoCo world, valid per :func:`teleop.messages.validate`).
    grasp_time_s: device time of the grasp moment (fingers closed, before the lift).
    phases: phase name → (start, end) device time, seconds. object_name, object_pos_m,
    object_quat_wxyz: the object and its world pose before the lift. reference_grasp: the name
    of the reference grasp imitated (None: generic side grasp). grasp_wrist_pos_m /
    grasp_wrist_quat_wxyz: the operator wrist pose at the grasp (noise-free).
    target_palm_pos_m / target_palm_quat_wxyz: where the retargeted robot palm should be at
    the grasp (world). fit_residual_m: per human finger, how far its tip stays from the
    position that maps onto the wanted robot fingertip (metres, operator scale); for a generic
    grasp instead ``mean_surface_m``, the mean distance of the mapped fingertips to the surface.
    Phases: still, approach, close (the grasp mark at its end), grasp (fingers closed, object
    not yet moved), lift, hold, release, retreat, end.
    tracked: per frame, whether the hand is tracked. side: the operator hand.
    """

    frames: list[HandFrame]
    grasp_time_s: float
    phases: dict[str, tuple[float, float]]
    object_name: str
    object_pos_m: Array
    object_quat_wxyz: Array
    reference_grasp: str | None
    grasp_wrist_pos_m: Array
    grasp_wrist_quat_wxyz: Array
    target_palm_pos_m: Array
    target_palm_quat_wxyz: Array
    fit_residual_m: dict[str, float]
    tracked: Array
    side: str
    seed: int
    metadata: dict[str, Any] = field(default_factory=dict)
