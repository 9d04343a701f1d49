"""An arm's way to a grasp: IK at the pregrasp, along a straight approach, at the grasp and at
the lift, and the collision checks of the path between them.

The hand reaches a grasp the way a person's does: it comes to a pregrasp ``approach_m`` behind
the palm (along frame_palm −y, the palm normal pointing away from the object), with the fingers
at the grasp's pregrasp joints, then slides straight in along +y; after the fingers close it
lifts straight up. When that way is blocked or out of reach (a palm facing sideways near the
table retreats along the table top, and its pregrasp may lie beyond the arm's reach), the
pregrasp is tried between the palm normal and straight up, then straight up (``retreats``): a
person coming down onto an object lying on a table does the same. Each waypoint is a
whole-body IK solve (:func:`~sim.arm.ik.solve_palm_ik`) seeded by the one before, so
consecutive configurations stay on one IK branch; the path from the arm's home to the
pregrasp is a straight line in joint space.

The hand's joints on the way are the grasp's but for two things a person's hand does near a
table (:func:`hand_for_approach`): the wrist (the hand mount's ``ik_free_joints``) bends as the
IK finds it best at the grasp and is then held, so a palm facing down onto an object lying flat
need not bring the forearm down to the table top; and the pregrasp's fingers open only as far
as the table allows at the grasp (the pregrasp blended toward the grasp), since a fully opened
thumb under a palm a few centimetres above the table would be in it. Measured on the flat
screwdriver (UR5e, grasps made as it lies): the open thumb and index distal links were what
came below the table top on the approach. A plan fails with a reason:
``unreachable`` (a waypoint's IK misses its pose by more than the tolerances) or ``collision``
(a configuration along the way, sampled every ``check_step_rad`` of joint motion, brings the
arm or the hand within ``min_clearance_m`` of the table). Units: metres, radians, seconds.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from itertools import pairwise

import mujoco
import numpy as np

from sim.arm.ik import IKResult, IKSettings, solve_palm_ik
from sim.arm.scene import ArmScene
from sim.transforms import quat_to_mat

__all__ = ["PREGRASP_OPENINGS", "ApproachSettings", "ArmPlan", "hand_for_approach", "plan_grasp"]


@dataclass(frozen=True)
class ApproachSettings:
    """How a grasp is approached and left: ``approach_m`` pregrasp distance behind the palm,
    ``approach_waypoints`` IK solves along it, ``lift_m`` straight up after closing, collision
    samples every ``check_step_rad`` of the largest joint's motion, and the clearance to the
    table every sampled configuration keeps (negative allows that much penetration)."""

    approach_m: float = 0.10
    #: directions to the pregrasp tried in order, as weights of (palm −y, world +z) normalised:
    #: behind the palm, halfway to straight up, straight up; one closer than 10° to a direction
    #: already tried is skipped
    retreats: tuple[tuple[float, float], ...] = ((1.0, 0.0), (1.0, 1.0), (0.0, 1.0))
    approach_waypoints: int = 5
    lift_m: float = 0.10
    check_step_rad: float = 0.05
    min_clearance_m: float = 0.0


@dataclass(frozen=True)
class ArmPlan:
    """The arm joints (config order) at home, pregrasp, along the approach (last = the grasp)
    and at the lift top, or ``failure`` (``unreachable`` / ``collision``) with ``detail``;
    ``retreat`` the unit direction (world) from the grasp to the pregrasp; ``ik`` holds every
    solve (its errors and times); ``time_s`` the planning wall time (all directions tried)."""

    failure: str | None
    detail: str
    home: np.ndarray
    pregrasp: np.ndarray | None = None
    approach: np.ndarray | None = None
    lift: np.ndarray | None = None
    ik: tuple[IKResult, ...] = ()
    time_s: float = 0.0
    retreat: np.ndarray | None = None
    #: the hand joints (``Hand.joint_names`` order, rad) on the way in and at the grasp
    #: (:func:`hand_for_approach`); the simulation closes from the first
    pregrasp_q: np.ndarray | None = None
    grasp_q: np.ndarray | None = None


def _object_clearance_m(scene: ArmScene, qpos: np.ndarray, cap_m: float = 0.05) -> float:
    """Smallest distance (m) between the arm + hand collision geoms and the object's at a full
    qpos (``inf`` beyond ``cap_m`` or without an object)."""
    if scene.obj_qadr < 0:
        return float("inf")
    m, d = scene.model, scene.data
    d.qpos[:] = qpos
    mujoco.mj_kinematics(m, d)
    fromto = np.zeros(6)
    dists = [mujoco.mj_geomDistance(m, d, int(g), int(o), cap_m, fromto)
             for g in np.concatenate([scene.arm_geoms, scene.hand_geoms]) for o in scene.obj_geoms]
    return min((x for x in dists if x < cap_m), default=float("inf"))


def _clear(scene: ArmScene, arm_path: np.ndarray, hand_q: np.ndarray, obj_qpos: np.ndarray,
           s: ApproachSettings, *, with_object: bool) -> tuple[float, float]:
    """Smallest table and object clearances (m) over ``arm_path`` (K, n_arm) densified to
    ``check_step_rad`` (the object's only ``with_object``)."""
    table = obj = float("inf")
    for a, b in pairwise(arm_path):
        n = max(int(np.ceil(np.max(np.abs(b - a)) / s.check_step_rad)), 1)
        for t in np.linspace(0.0, 1.0, n + 1)[1:]:
            q = scene.qpos(a + t * (b - a), hand_q)
            if scene.obj_qadr >= 0:
                q[scene.obj_qadr:scene.obj_qadr + 7] = obj_qpos
            table = min(table, scene.table_clearance_m(q))
            if with_object:
                obj = min(obj, _object_clearance_m(scene, q))
    return table, obj


def _margin(ik: IKSettings | None) -> float:
    s = ik or IKSettings()
    return max(s.collision_min_distance_m, s.hand_min_distance_m)


def _retreats(normal: np.ndarray, s: ApproachSettings) -> list[np.ndarray]:
    """The unit directions to try for the pregrasp (``s.retreats``), near-duplicates dropped."""
    out: list[np.ndarray] = []
    for w_palm, w_up in s.retreats:
        d = -w_palm * normal + w_up * np.array([0.0, 0.0, 1.0])
        norm = float(np.linalg.norm(d))
        if norm < 1e-9:
            continue
        d = d / norm
        if all(float(d @ e) < np.cos(np.radians(10.0)) for e in out):
            out.append(d)
    return out


def plan_grasp(scene: ArmScene, palm_pos_m: np.ndarray, palm_quat_wxyz: np.ndarray,
               pregrasp_q: np.ndarray, grasp_q: np.ndarray, obj_qpos: np.ndarray, *,
               settings: ApproachSettings | None = None, ik: IKSettings | None = None) -> ArmPlan:
    """Plan the approach to frame_palm at (``palm_pos_m``, ``palm_quat_wxyz``) in the world,
    the fingers at ``pregrasp_q`` on the way and ``grasp_q`` at the grasp (module docstring);
    ``obj_qpos`` (7,) is the settled object's free-joint pose, which the way to the pregrasp
    must not pass through, nor the approach before its last waypoint (which ends in contact).
    The first direction that plans wins; when none does, the failure is the palm normal's."""
    s = settings or ApproachSettings()
    t0 = time.perf_counter()
    pos = np.asarray(palm_pos_m, float)
    pregrasp_q, grasp_q = hand_for_approach(scene, pos, palm_quat_wxyz, pregrasp_q, grasp_q, ik)
    normal = quat_to_mat(np.asarray(palm_quat_wxyz, float))[:, 1]   # frame_palm +y, toward the object
    first: ArmPlan | None = None
    for retreat in _retreats(normal, s):
        plan = _plan_along(scene, pos, palm_quat_wxyz, retreat, pregrasp_q, grasp_q, obj_qpos, s, ik)
        if plan.failure is None:
            first = plan
            break
        first = first or plan
    assert first is not None
    return dataclasses.replace(first, time_s=time.perf_counter() - t0, pregrasp_q=pregrasp_q,
                               grasp_q=grasp_q)


#: how far the pregrasp's fingers open at the grasp, tried in order (1: the grasp's pregrasp,
#: 0: the grasp's own joints): the first whose hand clears the table is used
PREGRASP_OPENINGS = (1.0, 0.75, 0.5, 0.25, 0.0)


def hand_for_approach(scene: ArmScene, palm_pos_m: np.ndarray, palm_quat_wxyz: np.ndarray,
                      pregrasp_q: np.ndarray, grasp_q: np.ndarray, ik: IKSettings | None = None,
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The hand joints (pregrasp, grasp) the arm brings to frame_palm at (``palm_pos_m``,
    ``palm_quat_wxyz``): one IK solve at the grasp with the wrist free sets the mount's
    ``ik_free_joints`` in both (kept as given when that solve misses the pose), and the
    pregrasp's fingers are the most open of :data:`PREGRASP_OPENINGS` whose hand keeps the IK's
    hand margin to the table there (when none does, the one farthest from it: the plan then
    says whether that is enough).
    Module docstring: why."""
    pre, grasp = np.array(pregrasp_q, float), np.array(grasp_q, float)
    free = scene.hand_ik_free
    r = solve_palm_ik(scene, palm_pos_m, palm_quat_wxyz, grasp, settings=ik,
                      free_wrist=len(free) > 0)
    if not r.reachable:
        return pre, grasp
    wrist = r.q[scene.hand_qadr[free]]
    pre[free], grasp[free] = wrist, wrist
    margin = (ik or IKSettings()).hand_min_distance_m
    best, best_clear = pre, -np.inf
    for opening in PREGRASP_OPENINGS:
        hand_q = grasp + opening * (pre - grasp)
        clear = scene.table_clearance_m(scene.qpos(r.arm_q_rad, hand_q))
        if clear >= margin:
            return hand_q, grasp
        if clear > best_clear:
            best, best_clear = hand_q, clear
    return best, grasp


def _plan_along(scene: ArmScene, pos: np.ndarray, palm_quat_wxyz: np.ndarray,
                retreat: np.ndarray, pregrasp_q: np.ndarray, grasp_q: np.ndarray,
                obj_qpos: np.ndarray, s: ApproachSettings, ik: IKSettings | None) -> ArmPlan:
    """:func:`plan_grasp` with the pregrasp ``s.approach_m`` along ``retreat`` from the grasp."""
    home = scene.arm.home_rad.copy()
    fractions = np.linspace(0.0, 1.0, s.approach_waypoints + 1)
    solves: list[IKResult] = []

    def fail(reason: str, detail: str) -> ArmPlan:
        return ArmPlan(reason, detail, home, ik=tuple(solves), retreat=retreat)

    q = scene.qpos(home, pregrasp_q)
    path = []
    for f in fractions:
        target = pos + (1.0 - f) * s.approach_m * retreat
        r = solve_palm_ik(scene, target, palm_quat_wxyz, pregrasp_q if f < 1.0 else grasp_q,
                          q_start=q, settings=ik)
        solves.append(r)
        if not r.reachable:
            where = "the pregrasp" if f == 0.0 else f"{(1 - f) * s.approach_m * 1e3:.0f} mm before the grasp"
            held = r.table_clearance_m <= _margin(ik) + 1e-3   # stopped by the table, not by reach
            why = ", the arm held off the table" if held else ""
            return fail("collision" if held else "unreachable",
                        f"IK misses {where} by {r.pos_err_m * 1e3:.1f} mm / "
                        f"{np.degrees(r.rot_err_rad):.1f}°{why}")
        q = r.q
        path.append(r.arm_q_rad)
    approach = np.array(path)
    table, obj = _clear(scene, np.vstack([home, approach[0]]), pregrasp_q, obj_qpos, s,
                        with_object=True)
    if table < s.min_clearance_m:
        return fail("collision", f"the way to the pregrasp comes {table * 1e3:.1f} mm from the table")
    if obj < s.min_clearance_m:
        return fail("collision", "the way from home to the pregrasp goes through the object")
    table, _ = _clear(scene, approach, pregrasp_q, obj_qpos, s, with_object=False)
    if table < s.min_clearance_m:
        return fail("collision", f"the approach comes {table * 1e3:.1f} mm from the table")
    _, obj = _clear(scene, approach[:-1], pregrasp_q, obj_qpos, s, with_object=True)
    if obj < s.min_clearance_m:   # the last stretch ends in contact; before it the hand is clear
        return fail("collision", "the approach sweeps the open fingers through the object")
    grasp_clear = scene.table_clearance_m(scene.qpos(approach[-1], grasp_q))
    if grasp_clear < s.min_clearance_m:
        return fail("collision", f"the hand at the grasp is {grasp_clear * 1e3:.1f} mm from the table")
    r = solve_palm_ik(scene, pos + np.array([0.0, 0.0, s.lift_m]), palm_quat_wxyz, grasp_q,
                      q_start=q, settings=ik)
    solves.append(r)
    if not r.reachable:
        return fail("unreachable", f"IK misses the lift by {r.pos_err_m * 1e3:.1f} mm")
    return ArmPlan(None, "", home, approach[0], approach, r.arm_q_rad, tuple(solves),
                   retreat=retreat)
