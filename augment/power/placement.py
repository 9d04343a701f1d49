"""Where the palm goes: frames over object surface points, moved to a small gap from it.

Palm frames follow the hand convention (DESIGN §3: +y out of the palm face toward the
object), so a frame over a surface point with outward normal n has +y = −n, and its roll about
n (where the fingers point) is free: a sampled angle. The distance along n is found in the
simulation (the validator's scene), not from a palm box: the open hand is moved until its
nearest geom is ``standoff_m`` from the object, by bisection on MuJoCo's signed distance,
which works for any hand and any object shape; a placement whose palm then stays far from the
object (the point lies on an edge the palm overhangs) is dropped. Units: metres, radians,
quaternions wxyz.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.transforms import mat_to_quat, perpendicular_basis
from sim.world.contacts import contacts_between
from sim.world.scene import OBJECT_HOME, Scene

__all__ = ["SEARCH_M", "hand_gaps_m", "palm_quats", "place_palm"]

#: farthest signed distance (metres) the gap search looks at; beyond it a body is "far"
SEARCH_M = 0.05
#: palm offsets along the normal (metres, from the surface point) the bisection searches
_OFFSET_RANGE_M = (-0.02, 0.12)
_BISECTIONS = 12
#: how far (metres) the hand's gap found may fall short of the asked standoff (the search
#: range ends before the hand is clear: a point in a deep concavity) before it is dropped
_GAP_TOLERANCE_M = 0.001


def palm_quats(normals: np.ndarray, rolls_rad: np.ndarray) -> np.ndarray:
    """(N,4) frame_palm orientations with +y = −normal (into the object) and +z turned by
    ``rolls_rad`` (N,) about the normal from a fixed perpendicular; ``normals`` (N,3) unit,
    outward."""
    n = np.asarray(normals, dtype=float)
    e1, e2 = perpendicular_basis(n)
    roll = np.asarray(rolls_rad, dtype=float)[:, None]
    y = -n
    z = np.cos(roll) * e1 + np.sin(roll) * e2
    x = np.cross(y, z)
    return mat_to_quat(np.stack([x, y, z], axis=2))


def hand_gaps_m(scene: Scene, palm_pos: np.ndarray, palm_quat: np.ndarray,
                q: np.ndarray) -> tuple[float, float]:
    """(palm gap, hand gap), metres, with frame_palm at (``palm_pos``, ``palm_quat``) in the
    object frame and joints ``q``: the least signed distance to the object of the palm body's
    geoms, and of any hand geom (negative: penetrating); :data:`SEARCH_M` when farther."""
    m, d = scene.model, scene.data
    scene.reset_with_grasp(OBJECT_HOME + palm_pos, palm_quat, q)
    saved = m.geom_margin.copy()
    m.geom_margin[scene.obj_geom_mask] = SEARCH_M
    try:
        mujoco.mj_collision(m, d)
    finally:
        m.geom_margin[:] = saved
    near = contacts_between(m, d, scene.hand_geom_mask, scene.obj_geom_mask)
    palm = near.dist[near.body_a == scene.palm_body]
    return (min(float(palm.min()), SEARCH_M) if len(palm) else SEARCH_M,
            min(float(near.dist.min()), SEARCH_M) if len(near) else SEARCH_M)


def place_palm(scene: Scene, point: np.ndarray, normal: np.ndarray, palm_quat: np.ndarray,
               q: np.ndarray, standoff_m: float, max_palm_gap_m: float) -> np.ndarray | None:
    """frame_palm position (object frame) on the line ``point + t·normal`` where the open
    hand (joints ``q``) comes no closer to the object than ``standoff_m``, touching it there
    with its palm or whatever part sticks out of the palm (a thumb); None when the palm is
    then farther than ``max_palm_gap_m`` from the object (it misses the object there)."""
    lo, hi = _OFFSET_RANGE_M
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if hand_gaps_m(scene, point + mid * normal, palm_quat, q)[1] >= standoff_m:
            hi = mid
        else:
            lo = mid
    pos = point + hi * normal
    palm_gap, hand_gap = hand_gaps_m(scene, pos, palm_quat, q)
    if palm_gap > max_palm_gap_m or hand_gap < standoff_m - _GAP_TOLERANCE_M:
        return None
    return pos
