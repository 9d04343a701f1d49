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

import dataclasses
import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.transforms import axis_angle_to_mat, slerp_mat
from teleop.messages import HandFrame
from teleop.synthetic.config import SynthConfig
from teleop.synthetic.human_hand import FINGERS, HandPose, HumanHand, lerp_pose
from teleop.synthetic.preshape import Obstacles, approach_directions, contact_progress, plan_reach

__all__ = ["GraspMotion", "SynthEpisode", "min_jerk", "phase_times"]

Array = np.ndarray

logger = logging.getLogger(__name__)

#: Samples of the reach and of the closure checked for clearance by the reach planner.
_REACH_SAMPLES, _CLOSE_SAMPLES = 24, 8

#: Fraction of the close phase at which the fingers touch, together; the rest is the squeeze.
TOUCH_AT = 0.7

#: A fingertip touches when within this of the surface (metres, beyond its radius).
_TOUCH_M = 0.002


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
    open_pose / grasp_pose: the hand before closing and at the grasp. contact_at: per finger,
    how far along its joint-space closure it touches the object
    (:func:`teleop.synthetic.preshape.contact_progress`); the closure is warped so that every
    such finger touches at :data:`TOUCH_AT` of the close phase, together (how people close).
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
    #: per finger, where along its straight closure it touches (synchronised, see :meth:`at`)
    contact_at: dict[str, float] = field(default_factory=dict)

    @classmethod
    def plan(cls, cfg: SynthConfig, wrist_pos_m: Array, wrist_rot: Array, palm_rot: Array,
             grasp_pose: HandPose, *, human: HumanHand | None = None,
             obstacles: Obstacles | None = None, pressed: bool = False) -> GraspMotion:
        """The motion toward the grasp wrist pose whose robot palm axes are ``palm_rot``.

        With ``human`` and ``obstacles`` (the table and the object the operator sees) the hand
        comes in from the direction, and in the pre-shape, that keep it off both until it
        closes (:func:`teleop.synthetic.preshape.plan_reach`); without, it backs off along the
        palm normal and up and reaches with the relaxed open hand. ``pressed``: the grasp
        closes its fingertips past the surface (a generic grasp;
        :func:`teleop.synthetic.preshape.reach_clearance_m`)."""
        phases, t_end = phase_times(cfg)

        def along(away: Array, open_pose: HandPose) -> GraspMotion:
            start_pos = wrist_pos_m + cfg.approach_distance_m * away
            # the start turned 0.35 rad about world z and −0.3 rad about the wrist's own x
            turn = axis_angle_to_mat(np.eye(3)[[2, 0]], np.array([0.35, -0.3]))
            return cls(phases=phases, duration_s=t_end, start_pos_m=start_pos,
                       start_rot=turn[0] @ wrist_rot @ turn[1], wrist_pos_m=wrist_pos_m,
                       wrist_rot=wrist_rot, away=away, retreat_m=cfg.approach_distance_m,
                       lift_m=np.array([0.0, 0.0, cfg.lift_height_m]),
                       open_pose=open_pose, grasp_pose=grasp_pose)

        # palm normal (+y of frame_palm) points at the object: back off against it, and up
        dirs = approach_directions(palm_rot[:, 1], wrist_rot[:, 0])
        if human is None or obstacles is None:
            return along(dirs[0], HandPose.relaxed())
        a0, a1 = phases["approach"]
        reach_t = np.linspace(a0, a1, _REACH_SAMPLES)
        close_t = np.linspace(*phases["close"], _CLOSE_SAMPLES)

        def path_for(away: Array) -> tuple[Any, Array, Array]:
            return along(away, grasp_pose).wrist_and_closure, reach_t, close_t

        reach = plan_reach(human, grasp_pose, path_for, obstacles, cfg.table_clearance_m,
                           cfg.object_clearance_m, dirs, pressed)
        p_g, r_g, _ = along(reach.away, reach.preshape).wrist_and_closure(phases["close"][1])
        touch = contact_progress(human, reach.preshape, grasp_pose, p_g, r_g, obstacles,
                                 _TOUCH_M)
        logger.info("reach along %s (of %d directions), finger openings %s, clear of table and "
                    "object: %s", np.round(reach.away, 2).tolist(), len(dirs), reach.openings,
                    reach.clear)
        return dataclasses.replace(along(reach.away, reach.preshape), contact_at=touch)

    def progress(self, name: str, t: float) -> float:
        """How far phase ``name`` is at time ``t`` (0 before, 1 after; min-jerk within)."""
        a, b = self.phases[name]
        return float(min_jerk((t - a) / (b - a))) if b > a else float(t >= b)

    def wrist_and_closure(self, t: float) -> tuple[Array, Array, float]:
        """Wrist position (metres), wrist axes and closure (0: the open pose, 1: the grasp) at
        time ``t`` (seconds from the episode start)."""
        s = self.progress
        p = self.start_pos_m + s("approach", t) * (self.wrist_pos_m - self.start_pos_m)
        r = slerp_mat(self.start_rot, self.wrist_rot, s("approach", t))
        p = p + s("lift", t) * self.lift_m
        p = p + s("retreat", t) * self.retreat_m * self.away
        return p, r, s("close", t) * (1.0 - s("release", t))

    def at(self, t: float) -> tuple[Array, Array, HandPose]:
        """Wrist position (metres), wrist axes and hand pose at time ``t`` (seconds from the
        episode start)."""
        p, r, closure = self.wrist_and_closure(t)
        if not self.contact_at:
            return p, r, lerp_pose(self.open_pose, self.grasp_pose, closure)
        a, b = self.open_pose.vector(), self.grasp_pose.vector()
        per = np.full(len(a), closure)
        for k, finger in enumerate(FINGERS):   # HandPose.vector: 4 angles per finger
            if (c := self.contact_at.get(finger)) is not None:
                per[4 * k:4 * k + 4] = (c * closure / TOUCH_AT if closure <= TOUCH_AT else
                                        c + (1.0 - c) * (closure - TOUCH_AT) / (1.0 - TOUCH_AT))
        return p, r, HandPose.from_vector(a + per * (b - a))


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
