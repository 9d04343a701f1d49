"""Whole-body IK with mink: the arm's joints put the hand's ``frame_palm`` on a target pose
while the hand's joints stay at a grasp's joint vector.

Why this shape: a grasp from the dataset fixes the fingers (joint vector) and the palm pose;
only the arm is free (and, when asked, the hand's wrist: the mount's ``ik_free_joints``, which
lie between the flange and frame_palm). The other hand joints and the object's free joint are
frozen exactly (mink's ``DofFreezingTask`` passed as an equality constraint), a light posture
task toward the arm's home resolves redundancy (the 7-DoF iiwa) and keeps the solution near a
sensible elbow, joint limits and table collision avoidance (arm and hand geoms against the
table) are QP inequalities. A target out of reach is not an error: the result says
``reachable=False`` and carries the residual errors, so a batch can count unreachable grasps
instead of crashing.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import mink
import numpy as np

from sim.arm.scene import PALM_SITE, ArmScene
from sim.transforms import quat_angle

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class IKSettings:
    """Tolerances (metres, radians), iteration budget and task weights of :func:`solve_palm_ik`.

    ``dt_s`` is the integration step mink's velocity limits are scaled by (the frame task,
    gain 1, asks for the whole error each step whatever its value). ``stall_m`` stops early
    when a step moves frame_palm by less than this (the solver has converged to what limits
    and collisions allow). ``max_step_rad`` caps the largest joint change of one step: a full
    Gauss-Newton step from far away jumps across the linearised collision and limit bounds
    and lands on another IK branch (measured: the UR5e's elbow dived into the table)."""

    pos_tol_m: float = 1e-3
    rot_tol_rad: float = float(np.deg2rad(1.0))
    max_iterations: int = 300
    dt_s: float = 0.05
    orientation_cost: float = 1.0
    posture_cost: float = 1e-3
    lm_damping: float = 1e-3
    damping: float = 1e-4
    collision_min_distance_m: float = 0.01
    #: the hand's own geoms may come closer: a grasp of an object lying on the table puts the
    #: fingertips a few millimetres above it (measured: 8–11 mm for side grasps of a can), which
    #: the arm's 10 mm margin would forbid outright
    hand_min_distance_m: float = 0.002
    #: pairs farther apart than this are not seen by the collision limit, so it must exceed
    #: what one step can move a geom (``max_step_rad`` × ~1 m of lever arm); measured over 100
    #: random targets per arm, 0.05 m with 0.2 rad steps let geoms end 33 mm inside the table
    collision_detection_distance_m: float = 0.15
    stall_m: float = 1e-7
    max_step_rad: float = 0.05
    #: iterate until the errors are this fraction of the tolerances (or stall), so a reachable
    #: result lies well inside them rather than on their edge
    converge_fraction: float = 0.1
    #: within this distance (metres) of the target the posture task is dropped: on a 6-DoF arm
    #: it has no null space to live in and would hold the palm off the target (measured on the
    #: UR5e: up to 0.8 mm residual with it, against 1e-2 mm without)
    posture_off_m: float = 0.01
    solver: str = "daqp"


@dataclass(frozen=True)
class IKResult:
    """The solution: ``q`` is the full qpos (arm solved, hand at the grasp's joints),
    ``arm_q_rad`` the arm joints in config order; errors are frame_palm's residual position
    (metres) and rotation (radians) at ``q``; ``reachable`` = both within tolerance."""

    q: np.ndarray
    arm_q_rad: np.ndarray
    pos_err_m: float
    rot_err_rad: float
    iterations: int
    reachable: bool
    time_s: float
    #: smallest distance (metres) between the arm + hand collision geoms and the table at ``q``
    #: (negative: penetration; ``inf`` without a table or when all are beyond 1 m)
    table_clearance_m: float = float("inf")


def _frozen_dofs(scene: ArmScene, free_wrist: bool) -> list[int]:
    """The dofs IK must not move: every hand joint (but the mount's ``ik_free_joints`` when
    ``free_wrist``) and the object's free joint (6 dofs)."""
    free = set(scene.hand_ik_free.tolist()) if free_wrist else set()
    dofs = [int(d) for i, d in enumerate(scene.hand_dadr) if i not in free]
    if scene.obj_dadr >= 0:
        dofs += list(range(scene.obj_dadr, scene.obj_dadr + 6))
    return dofs


def _errors(config: mink.Configuration, pos: np.ndarray, quat: np.ndarray) -> tuple[float, float]:
    """frame_palm's position (m) and rotation (rad) error against the target."""
    pose = config.get_transform_frame_to_world(PALM_SITE, "site")
    wxyz_xyz = pose.wxyz_xyz
    return (float(np.linalg.norm(wxyz_xyz[4:] - pos)),
            float(quat_angle(np.asarray(wxyz_xyz[:4]), quat)))


def solve_palm_ik(scene: ArmScene, palm_pos_m: np.ndarray, palm_quat_wxyz: np.ndarray,
                  hand_q: np.ndarray | None = None, *, q_start: np.ndarray | None = None,
                  settings: IKSettings | None = None, free_wrist: bool = False) -> IKResult:
    """Arm joints that put frame_palm on (``palm_pos_m``, ``palm_quat_wxyz``) in the world
    with the hand's joints at ``hand_q`` (``Hand.joint_names`` order, the open pose when
    None); with ``free_wrist`` the hand mount's ``ik_free_joints`` are solved too, from
    ``hand_q``'s values within their limits (``q`` holds what was found). Starts from
    ``q_start`` (a full qpos; the arm's home when None). Never raises for
    an unreachable target: see :class:`IKResult`; a ``hand_q`` of the wrong length is a
    GraspInputError. A start whose geoms are already inside the table stays stuck there (the
    collision limit only forbids going deeper), so start from a clear configuration."""
    s = settings or IKSettings()
    t0 = time.perf_counter()
    pos = np.asarray(palm_pos_m, float)
    quat = np.asarray(palm_quat_wxyz, float) / np.linalg.norm(palm_quat_wxyz)
    hand_q = scene.hand.clip(scene.hand.open_pose if hand_q is None
                             else scene.hand.check_q(hand_q, "grasp joint vector"))
    q0 = scene.qpos(hand_q=hand_q) if q_start is None else np.array(q_start, float)
    q0[scene.hand_qadr] = hand_q
    model = scene.model
    config = mink.Configuration(model, q0)

    frame = mink.FrameTask(PALM_SITE, "site", position_cost=1.0,
                           orientation_cost=s.orientation_cost, lm_damping=s.lm_damping)
    frame.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(quat), pos))
    posture = mink.PostureTask(model, cost=s.posture_cost)
    posture.set_target(scene.qpos(hand_q=hand_q))
    limits: list[mink.Limit] = [mink.ConfigurationLimit(model)]
    if scene.table_geom >= 0:
        for geoms, margin in ((scene.arm_geoms, s.collision_min_distance_m),
                              (scene.hand_geoms, s.hand_min_distance_m)):
            limits.append(mink.CollisionAvoidanceLimit(
                model, [([int(g) for g in geoms], [scene.table_geom])],
                minimum_distance_from_collisions=margin,
                collision_detection_distance=s.collision_detection_distance_m))
    constraints = [mink.DofFreezingTask(model, dof_indices=_frozen_dofs(scene, free_wrist))]

    pos_err, rot_err = _errors(config, pos, quat)
    iterations = 0
    goal_pos, goal_rot = s.converge_fraction * s.pos_tol_m, s.converge_fraction * s.rot_tol_rad
    while iterations < s.max_iterations and not (pos_err <= goal_pos and rot_err <= goal_rot):
        try:
            tasks = [frame] if pos_err < s.posture_off_m else [frame, posture]
            vel = mink.solve_ik(config, tasks, s.dt_s, s.solver, damping=s.damping,
                                limits=limits, constraints=constraints)
        except mink.NoSolutionFound as exc:   # infeasible QP (e.g. start in collision): stop here
            logger.debug("IK QP infeasible after %d iterations: %s", iterations, exc)
            break
        step = float(np.max(np.abs(vel))) * s.dt_s
        if step > s.max_step_rad:
            vel = vel * (s.max_step_rad / step)
        config.integrate_inplace(vel, s.dt_s)
        iterations += 1
        new_pos_err, new_rot_err = _errors(config, pos, quat)
        stalled = (abs(new_pos_err - pos_err) < s.stall_m
                   and abs(new_rot_err - rot_err) < s.stall_m)
        pos_err, rot_err = new_pos_err, new_rot_err
        if stalled:
            break
    q = config.q.copy()
    clearance = scene.table_clearance_m(q)
    frozen = np.ones(len(hand_q), bool)
    if free_wrist:
        frozen[scene.hand_ik_free] = False
    # exact: the frozen dofs do not drift, but say so in the output
    q[scene.hand_qadr[frozen]] = hand_q[frozen]
    return IKResult(q=q, arm_q_rad=q[scene.arm_qadr].copy(), pos_err_m=pos_err, rot_err_rad=rot_err,
                    iterations=iterations,
                    reachable=bool(pos_err <= s.pos_tol_m and rot_err <= s.rot_tol_rad),
                    time_s=time.perf_counter() - t0, table_clearance_m=clearance)
