"""The generic grasp of an object without a reference grasp (:func:`search_grasp`): a search
over operator wrist placements × per-finger closure levels, scored on where the retargeter
would put the robot fingertips.

Why a search: one fixed side grasp fits only objects of one size and shape (on a small fruit
the fingers pass over the top, on a box only the thumb reaches). A person grasping an object
chooses an approach (from the side or from above, the hand turned about it), puts the palm
near the object and closes every finger until the object stops it. The search does the same
with the human hand model: for each candidate wrist placement it closes each finger along
the open → power-grasp path (:meth:`HandPose.relaxed` → :meth:`HandPose.power`) to the first
level whose *mapped* tip (through the retargeter's wrist correspondence and fingertip scale,
:class:`teleop.synthetic.correspondence.Correspondence`) lies ``press_m`` past the surface —
or, as a person does, whose *own* pad (the tip joint less its radius) stops a standoff short
of it (``standoff_m``, per finger: tracked fingertips stop 3–8 mm off a virtual object; the
robot's pads then come onto it only if the retargeter brings them there) — and scores the
placement by how well the thumb and an opposing finger reach that depth, with the other
fingers touching as a bonus. Placements where the robot palm box (``[palm]`` of the
hand config, frame_palm) would enter the object or the table, where the open hand already
goes into the object, or where a robot finger's links (its pad aside) go into it at the
grasp, are rejected.

A person also picks a grasp that will hold the object up. Of the placements that fit, the
operator takes the best-fitting one whose touching fingertips can carry the object's weight
with friction (:func:`sim.metrics.holding.min_grip_force_n`: one soft contact per fingertip,
friction ``friction``, the weight at the object's centre of mass) with a total grip of at most
:data:`_MAX_GRIP_RATIO` times the weight; only where none can is the best-fitting one taken
as it is. Measured on the closed-loop benchmark (``benchmarks/bench_teleop_loop.py``):
fingertips placed on a box's top face or a bottle's shoulder fit as well as any, and the
simulated hand then lifts nothing.

The object rests on a table: its lowest point is the table top. Distances are signed
distances to the object's surface mesh, from its nearest vertex and that vertex's normal
(YCB meshes are dense: ≈ 1–2 mm between vertices), so the whole search is a few KD-tree
queries. World frame (the operator's tracking space), metres; rotations as 3×3 matrices.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from sim.hand.model import Hand
from sim.metrics.holding import min_grip_force_n
from teleop.messages import JOINT_INDEX
from teleop.synthetic.correspondence import Correspondence
from teleop.synthetic.human_hand import FINGERS, LONG_FINGERS, HandPose, HumanHand, finger_of, lerp_pose

__all__ = ["GenericGrasp", "search_grasp"]

logger = logging.getLogger(__name__)

Array = np.ndarray

#: Closure levels searched per finger (0: relaxed open hand, 1: power grasp).
_LEVELS = np.linspace(0.0, 1.0, 26)
#: Side approaches: palm normal azimuths (from +x, the operator looking forward) and
#: elevations (negative: pointing down), radians; roll of the fingers about the palm normal
#: from straight up.
_SIDE_AZIMUTH = np.radians([-60.0, -30.0, 0.0, 30.0, 60.0])
_SIDE_ELEVATION = np.radians([0.0, -30.0, -60.0])
_SIDE_ROLL = np.radians([-60.0, -30.0, 0.0, 30.0, 60.0])
#: Top approaches: fingers horizontal, at these azimuths from +x (never toward the operator).
_TOP_AZIMUTH = np.radians([-90.0, -45.0, 0.0, 45.0, 90.0])
#: Palm box clearance from the object's extent toward the palm, and how far the palm origin
#: sits back along the fingers from the object's centre (metres).
_GAPS_M = np.array([0.0, 0.01, 0.02, 0.035])
_BACKS_M = np.array([0.0, 0.02, 0.04, 0.06, 0.08])
#: Rejections (metres): palm box points at least this far outside the object and above the
#: table; open-hand joints at most this deep in the object; robot finger link axes (but the
#: pad) at most this deep at the grasp; every hand joint at least this far above the table.
_PALM_CLEAR_M = 0.003
_OPEN_DEPTH_M = 0.005
_LINK_DEPTH_M = 0.008
_PAD_M = 0.012
_TABLE_CLEAR_M = 0.008
#: A finger "touches" when its mapped tip reaches within this of the wanted depth; the thumb
#: opposes a finger when their surface normals' dot product is below _OPPOSE_DOT.
_TOUCH_M = 0.005
#: Joint-range samples of the robot hand for its fingertip workspaces.
_REACH_SAMPLES = 20000
_OPPOSE_DOT = -0.2
#: The most grip (total normal force per newton of weight) a holding placement may need.
_MAX_GRIP_RATIO = 10.0
#: The object's weight as a unit load (force, torque about the centre of mass; world, z up).
_WEIGHT = np.array([0.0, 0.0, -1.0, 0.0, 0.0, 0.0])


@dataclass(frozen=True)
class GenericGrasp:
    """The search's choice: frame_palm in the world (palm_pos_m, palm_rot), the hand pose,
    per human finger the signed distance of its mapped tip (with a standoff: of its own pad)
    to the surface (``surface_m``, metres, negative inside), which fingers touch, the score
    (metres-like; lower is better) and the grip ratio (total normal force per newton of weight with which the
    touching fingertips hold the object up; inf where no fitting placement could within
    :data:`_MAX_GRIP_RATIO` and the best-fitting one was taken)."""

    palm_pos_m: Array
    palm_rot: Array
    pose: HandPose
    surface_m: dict[str, float]
    touching: tuple[str, ...]
    cost: float
    grip_ratio: float


class _Sdf:
    """Signed distance to a dense surface mesh from its nearest vertex and vertex normal."""

    def __init__(self, vertices: Array, normals: Array) -> None:
        self._tree = cKDTree(vertices)
        self._v, self._n = vertices, normals

    def __call__(self, pts: Array) -> tuple[Array, Array]:
        """Signed distances (...) and the outward normals (..., 3) there, for points (..., 3)."""
        flat = pts.reshape(-1, 3)
        dist, idx = self._tree.query(flat, workers=-1)
        n = self._n[idx]
        sign = np.where(np.einsum("ij,ij->i", flat - self._v[idx], n) >= 0.0, 1.0, -1.0)
        return (sign * dist).reshape(pts.shape[:-1]), n.reshape(pts.shape)


def _frames() -> Array:
    """Candidate frame_palm axes (N, 3, 3): +y the palm normal toward the object, +z along
    the fingers, x = y × z."""
    rots = []
    for az in _SIDE_AZIMUTH:
        for el in _SIDE_ELEVATION:
            y = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
            up = np.array([0.0, 0.0, 1.0]) - y[2] * y
            up /= np.linalg.norm(up)
            side = np.cross(y, up)
            for roll in _SIDE_ROLL:
                z = np.cos(roll) * up + np.sin(roll) * side
                rots.append(np.column_stack([np.cross(y, z), y, z]))
    y = np.array([0.0, 0.0, -1.0])
    for az in _TOP_AZIMUTH:
        z = np.array([np.cos(az), np.sin(az), 0.0])
        rots.append(np.column_stack([np.cross(y, z), y, z]))
    return np.array(rots)


def _palm_box_points(box_center: Array, half: Array) -> Array:
    """Corners, face centres and centre of the palm box (frame_palm), (27, 3)."""
    g = np.array(np.meshgrid(*[[-1.0, 0.0, 1.0]] * 3, indexing="ij")).reshape(3, -1).T
    return box_center + g * half


def _reachable(robot: Hand, corr: Correspondence, tips_palm: Array
               ) -> tuple[Array, list[Array | None]]:
    """For mapped human fingertips (L, 5, 3) in frame_palm (FINGERS order), the nearest
    point each robot finger's pulp site can reach (same shape), from a fixed sample of the
    hand's joint ranges, and per human finger the robot finger's link points (L, P, 3) in
    that configuration, without the last ``_PAD_M`` before the pulp (None: no robot finger
    follows it; its mapped tip is kept). Why: the retargeter's IK can only bring a robot
    fingertip as close to its target as the finger's workspace allows (a human finger curls
    deeper into the palm than a Shadow finger can), and a robot finger whose links meet the
    object first is stopped there."""
    q = robot.fill_coupled(np.random.default_rng(0).uniform(
        robot.lower, robot.upper, (_REACH_SAMPLES, robot.nq)))
    samples = robot.fingertip_sites(q, frame="palm")                       # (M, nf, 3)
    out = tips_palm.copy()
    links: list[Array | None] = []
    by_human = {finger_of(j): r for r, j in corr.mapping.fingers.items()}
    for k, f in enumerate(FINGERS):
        if f not in by_human:
            links.append(None)
            continue
        cloud = samples[:, robot.finger_names.index(by_human[f])]
        near = cKDTree(cloud).query(tips_palm[:, k])[1]
        out[:, k] = cloud[near]
        skel = robot.skeleton(q[near], by_human[f], spacing_m=0.008)      # (L, P, 3)
        keep = np.linalg.norm(skel[0] - skel[0, -1], axis=1) > _PAD_M
        links.append(skel[:, keep])
    return out, links


def _placements(verts: Array, centre: Array, rots: Array) -> tuple[Array, Array]:
    """Palm positions (N, 3) and axes (N, 3, 3) over frames × gaps × backs."""
    normal, along = rots[:, :, 1], rots[:, :, 2]
    extent = np.max((centre - verts) @ normal.T, axis=0)                 # (R,) toward the palm
    grid = np.meshgrid(np.arange(len(rots)), np.arange(len(_GAPS_M)),
                       np.arange(len(_BACKS_M)), indexing="ij")
    r, g, b = (axis.ravel() for axis in grid)
    pos = (centre - normal[r] * (extent[r] + _GAPS_M[g])[:, None]
           - along[r] * _BACKS_M[b][:, None])
    return pos, rots[r]


@dataclass(frozen=True)
class _Scored:
    """Every placement (N) scored for the five fingers (FINGERS order): the human poses along
    the closure (L levels), each finger's chosen level (N, 5), its mapped tip's signed
    distance to the wanted depth at every level (N, L, 5, metres), the reachable robot pulp
    point at the chosen level (N, 5, 3, world) with the surface's outward normal there
    (N, 5, 3), which fingers touch (N, 5), the placement cost (N,; inf: rejected)."""

    poses: list[HandPose]
    level: Array
    err: Array
    points: Array
    normals: Array
    touch: Array
    cost: Array


def _score(robot: Hand, human: HumanHand, corr: Correspondence, scale: float, sdf: _Sdf,
           table_z: float, pos: Array, rots: Array, press_m: float,
           standoff_m: Array | None) -> _Scored:
    """Every placement, each finger closed along the open → power-grasp path to its level, its
    cost and rejections (module docstring). ``standoff_m`` (per finger, FINGERS order): the
    levels are where the operator's own pads (tip joint less its radius) stop that far short
    of the surface, and the touch points are the surface below them; None: where the mapped
    robot tips lie ``press_m`` past it."""
    poses = [lerp_pose(HandPose.relaxed(), HandPose.power(), float(s)) for s in _LEVELS]
    joints = np.array([human.joints_in_wrist(p)[0] for p in poses])
    mapped = corr.p_pw + scale * joints @ corr.r_pw.T
    # the open hand (level 0) in the world: (N, 26, 3)
    open_hand = pos[:, None] + np.einsum("nij,kj->nki", rots, mapped[0])
    # where the robot pulp sites can go: the reachable point nearest each mapped tip
    tip_idx = [JOINT_INDEX[f"{f}_tip"] for f in FINGERS]
    reach, links = _reachable(robot, corr, mapped[:, tip_idx])             # (L, 5, 3)
    reach_w = pos[:, None, None] + np.einsum("nij,lkj->nlki", rots, reach)  # (N, L, 5, 3)
    clear = np.full(len(pos), True)
    if standoff_m is None:
        tip_sd, tip_normals = sdf(reach_w)
        points = reach_w
        err = tip_sd + np.asarray(press_m, float)                          # (N, L, 5)
    else:   # the operator's own pads, not where the retargeter will put the robot's
        human_palm = corr.p_pw + joints[:, tip_idx] @ corr.r_pw.T                 # (L, 5, 3)
        human_w = pos[:, None, None] + np.einsum("nij,lkj->nlki", rots, human_palm)
        tip_sd, tip_normals = sdf(human_w)
        points = human_w - tip_sd[..., None] * tip_normals   # the surface below each pad
        err = tip_sd - human.radii[tip_idx] - np.asarray(standoff_m, float)
        # nor does a person's open hand reach into the object it sees
        open_w = pos[:, None] + np.einsum("nij,kj->nki", rots, corr.p_pw + joints[0] @ corr.r_pw.T)
        clear = (sdf(open_w)[0] - human.radii).min(axis=1) > 0.0
    n_pl, n_lv = len(pos), len(_LEVELS)
    # each finger closes to the first level whose tip reaches the wanted depth, or fully
    reached = err <= 0.0
    first = np.where(reached.any(axis=1), np.argmax(reached, axis=1), n_lv - 1)   # (N, 5)
    prev = np.maximum(first - 1, 0)
    take_prev = np.abs(np.take_along_axis(err, prev[:, None], 1)[:, 0]) < \
        np.abs(np.take_along_axis(err, first[:, None], 1)[:, 0])
    level = np.where(take_prev, prev, first)
    pick = (np.arange(n_pl)[:, None], level, np.arange(5)[None, :])
    tip_err = np.abs(err[pick])                                            # (N, 5)
    tip_n = tip_normals[pick]                                              # (N, 5, 3)
    # per robot finger at its level: its links' deepest point in the object, lowest point
    link_depth, finger_z = np.zeros((n_pl, 5)), np.full((n_pl, 5), np.inf)
    for k, pts in enumerate(links):
        if pts is not None:
            w = pos[:, None] + np.einsum("nij,npj->npi", rots, pts[level[:, k]])  # (N, P, 3)
            link_depth[:, k] = -sdf(w)[0].min(axis=1)
            finger_z[:, k] = w[..., 2].min(axis=1)

    touch = tip_err < _TOUCH_M
    oppose = np.einsum("nj,nkj->nk", tip_n[:, 0], tip_n[:, 1:]) < _OPPOSE_DOT
    best_opp = np.where(oppose, tip_err[:, 1:], np.inf).min(axis=1)
    cost = tip_err[:, 0] + best_opp + 0.01 * (4 - touch[:, 1:].sum(axis=1))

    box = _palm_box_points(np.asarray(robot.config.palm.box_center, float),
                           np.asarray(robot.config.palm.box_half_extents, float))
    palm_w = pos[:, None] + np.einsum("nij,kj->nki", rots, box)
    ok = ((sdf(palm_w)[0].min(axis=1) > _PALM_CLEAR_M)
          & (palm_w[..., 2].min(axis=1) > table_z + _TABLE_CLEAR_M)
          & (-sdf(open_hand)[0].min(axis=1) < _OPEN_DEPTH_M) & clear
          & (link_depth.max(axis=1) < _LINK_DEPTH_M)
          & (open_hand[..., 2].min(axis=1) > table_z + _TABLE_CLEAR_M)
          & (finger_z.min(axis=1) > table_z + _TABLE_CLEAR_M))
    return _Scored(poses=poses, level=level, err=err, points=points[pick], normals=tip_n,
                   touch=touch, cost=np.where(ok, cost, np.inf))


def _grip_ratio(c: _Scored, i: int, com_m: Array, friction: float) -> float:
    """Least total normal force, per newton of weight, with which placement ``i``'s touching
    fingertips hold the object up (:func:`sim.metrics.holding.min_grip_force_n`, one contact
    per finger, sliding ``friction``); inf when they cannot."""
    k = np.flatnonzero(c.touch[i])
    return min_grip_force_n(c.points[i, k], -c.normals[i, k], com_m, _WEIGHT, friction)


def search_grasp(robot: Hand, human: HumanHand, corr: Correspondence, scale: float, mesh: Any,
                 obj_pos: Array, obj_rot: Array, press_m: float, com_m: Array,
                 friction: float, standoff_m: Array | None = None) -> GenericGrasp:
    """The best generic grasp of ``mesh`` (object frame; the object at ``obj_pos``,
    ``obj_rot`` in the world, resting on a table at its lowest point, its centre of mass at
    ``com_m`` in the world) for robot hand ``robot`` driven by operator hand ``human``
    through ``corr`` with fingertip ``scale`` (module docstring). ``friction``: the sliding
    friction the operator counts on to hold the object up. ``standoff_m`` (per finger,
    FINGERS order, metres): the operator's pads stop that far short of the surface
    (``press_m`` is then unused)."""
    verts = np.asarray(mesh.vertices) @ obj_rot.T + obj_pos
    sdf = _Sdf(verts, np.asarray(mesh.vertex_normals) @ obj_rot.T)
    table_z = float(verts[:, 2].min())
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    pos, rots = _placements(verts, 0.5 * (lo + hi), _frames())
    c = _score(robot, human, corr, scale, sdf, table_z, pos, rots, press_m, standoff_m)
    order = np.argsort(c.cost, kind="stable")
    order = order[np.isfinite(c.cost[order])]
    if not len(order):
        raise ValueError("no generic grasp placement keeps the palm out of the object and the "
                         "table with the thumb opposing a finger")
    # the best-fitting placement whose fingertips can hold the object up, else the best-fitting
    i, ratio = int(order[0]), float("inf")
    for cand in order:
        r = _grip_ratio(c, int(cand), com_m, friction)
        if r <= _MAX_GRIP_RATIO:
            i, ratio = int(cand), r
            break
    level = c.level[i]
    pose = HandPose.from_vector(np.concatenate(
        [c.poses[level[0]].thumb, *(c.poses[level[k + 1]].fingers[f]
                                    for k, f in enumerate(LONG_FINGERS))]))
    wanted = np.broadcast_to(-press_m if standoff_m is None else np.asarray(standoff_m, float),
                             (len(FINGERS),))
    surface = {f: float(c.err[i, level[k], k] + wanted[k]) for k, f in enumerate(FINGERS)}
    touching = tuple(f for k, f in enumerate(FINGERS) if c.touch[i, k])
    logger.info("generic grasp: %d of %d placements valid; cost %.4f (rank %d of the fitting), "
                "grip ratio %.2f, palm normal %s, fingers %s, touching %s", len(order),
                len(c.cost), c.cost[i], int(np.flatnonzero(order == i)[0]), ratio,
                np.round(rots[i][:, 1], 2).tolist(), np.round(rots[i][:, 2], 2).tolist(),
                touching)
    return GenericGrasp(palm_pos_m=pos[i], palm_rot=rots[i], pose=pose, surface_m=surface,
                        touching=touching, cost=float(c.cost[i]), grip_ratio=ratio)
