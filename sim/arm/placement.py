"""Objects placed on the table as they really lie, and hand-only grasps carried to them.

The paper's hand–arm experiment (§5.3) drops each object at random poses on a table, lets it
settle, transforms the hand-only grasps (frame_palm in the object frame) to the object's pose and
filters out those whose hand would be inside the table before any IK is tried. Placements here
draw one of the object's physically found resting poses (:mod:`sim.world.resting`, weighted by
how often random drops reached it), a yaw and a position in the table's reachable area; the
arm scene then settles the object from there and the grasps follow the *settled* pose.

The table pre-filter is cheap and conservative in one direction only: it tests points along
every finger link (:meth:`~sim.hand.model.Hand.skeleton`) and the palm box's corners against
the table top raised by ``clearance_m`` (about a phalanx radius), so it rejects grasps that
certainly collide; the exact check is MuJoCo's contacts at the arm's IK solution. Units: metres,
degrees; quaternions wxyz.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import product

import numpy as np

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.transforms import pose_mul, quat_to_mat
from sim.world.objects import ObjectAsset
from sim.world.resting import RestPoses, rest_placement

__all__ = ["Placement", "palm_targets", "sample_placements", "table_clear"]

#: share given to a resting pose no random drop reached (found from an axis-aligned start only),
#: so it is drawn now and then rather than never
_MIN_SHARE = 0.02


@dataclass(frozen=True)
class Placement:
    """Placement ``index`` of an object: resting pose ``rest_index`` turned by ``yaw_deg``,
    its origin at ``pos`` (world, m) with orientation ``quat_wxyz``, just above the table."""

    index: int
    rest_index: int
    yaw_deg: float
    pos: np.ndarray
    quat_wxyz: np.ndarray


def sample_placements(obj: ObjectAsset, poses: RestPoses, n: int, *, seed: int,
                      area_x_m: tuple[float, float], area_y_m: tuple[float, float],
                      top_z_m: float, rest_index: int | None = None) -> list[Placement]:
    """``n`` seeded placements of ``obj``: a resting pose drawn by its share (always
    ``rest_index`` when given), a yaw uniform in [0°, 360°) and a position uniform in the area
    (world x and y ranges, metres) on the table top at height ``top_z_m``."""
    if n < 1:
        raise ValueError(f"placements: expected n >= 1, got {n}")
    if not len(poses):
        raise ValueError(f"{obj.name}: no resting pose to place it in")
    rng = np.random.default_rng(seed)
    share = np.maximum([p.share for p in poses.poses], _MIN_SHARE)
    if rest_index is not None:
        share = np.eye(len(share))[poses.check_index(rest_index, "rest_index")]
    out = []
    for i in range(n):
        k = int(rng.choice(len(share), p=share / share.sum()))
        yaw = float(rng.uniform(0.0, 360.0))
        xy = np.array([rng.uniform(*area_x_m), rng.uniform(*area_y_m)])
        pos, quat = rest_placement(obj, poses[k], xy, yaw, top_z_m=top_z_m)
        out.append(Placement(i, k, yaw, pos, quat))
    return out


def palm_targets(grasps: Sequence[Grasp], obj_pos: np.ndarray, obj_quat_wxyz: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray]:
    """frame_palm of each grasp in the world for the object at (``obj_pos``, ``obj_quat_wxyz``):
    T_world←palm = T_world←object · T_object←palm. Returns (N, 3) m and (N, 4) wxyz."""
    n = len(grasps)
    p = np.array([g.palm_pos for g in grasps], float).reshape(n, 3)
    q = np.array([g.palm_quat_wxyz for g in grasps], float).reshape(n, 4)
    op = np.broadcast_to(np.asarray(obj_pos, float), (n, 3))
    oq = np.broadcast_to(np.asarray(obj_quat_wxyz, float), (n, 4))
    return pose_mul(op, oq, p, q)


def table_clear(hand: Hand, grasps: Sequence[Grasp], obj_pos: np.ndarray,
                obj_quat_wxyz: np.ndarray, *, top_z_m: float, clearance_m: float = 0.008,
                ) -> np.ndarray:
    """(N,) bool: the grasp's finger links and palm box stay ``clearance_m`` above the table
    top (module docstring: a pre-filter; False means the hand would be in the table)."""
    if not len(grasps):
        return np.zeros(0, bool)
    q = np.array([g.joints for g in grasps], float)
    pts = [hand.skeleton(q, f) for f in hand.finger_names]   # (N, k, 3) each, frame_palm
    palm = hand.config.palm
    corners = np.array([palm.box_center + np.multiply(s, palm.box_half_extents)
                        for s in product((-1.0, 1.0), repeat=3)])
    pts.append(np.broadcast_to(corners, (len(grasps), 8, 3)))
    local = np.concatenate(pts, axis=1)
    wp, wq = palm_targets(grasps, obj_pos, obj_quat_wxyz)
    world_z = wp[:, None, 2] + np.einsum("nj,nkj->nk", quat_to_mat(wq)[:, 2, :], local)
    return world_z.min(axis=1) > top_z_m + clearance_m
