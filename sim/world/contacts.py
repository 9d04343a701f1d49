"""Hand–object contacts read out of a MuJoCo state, as arrays.

Used by the validator (contact count, penetration, simulated grasp wrench space), the teleop
recorder (fingertip contacts) and rendering. Normals are oriented from the hand into the object,
i.e. the direction of the force the hand applies, whatever order MuJoCo stored the pair in.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass(frozen=True)
class Contacts:
    """Contacts between two geom sets: world positions (N,3) metres, unit normals (N,3) from the
    first set into the second, signed distances (N,) metres (negative = penetration), the
    first-set body of each contact (N,), and normal forces (N,) newtons when requested."""

    pos: np.ndarray
    normal: np.ndarray
    dist: np.ndarray
    body_a: np.ndarray
    force_n: np.ndarray

    def __len__(self) -> int:
        return len(self.dist)

    @property
    def points_a(self) -> np.ndarray:
        """Contact points on the first set's surface (MuJoCo's ``pos`` is the midpoint)."""
        return self.pos - self.normal * self.dist[:, None] / 2.0

    @property
    def max_penetration_m(self) -> float:
        return float(max(0.0, -self.dist.min())) if len(self) else 0.0


def contacts_between(model: mujoco.MjModel, data: mujoco.MjData, mask_a: np.ndarray,
                     mask_b: np.ndarray, *, with_force: bool = False) -> Contacts:
    """All contacts of ``data`` whose geoms are one in ``mask_a`` and one in ``mask_b``
    (boolean masks over geoms)."""
    n = data.ncon
    if n == 0:
        empty = np.zeros((0, 3))
        return Contacts(empty, empty, np.zeros(0), np.zeros(0, int), np.zeros(0))
    con = data.contact
    geom = con.geom[:n]
    a_first = mask_a[geom[:, 0]] & mask_b[geom[:, 1]]
    b_first = mask_b[geom[:, 0]] & mask_a[geom[:, 1]]
    sel = np.flatnonzero(a_first | b_first)
    # MuJoCo's frame[0:3] points from geom[0] to geom[1]; flip where the pair is (b, a)
    sign = np.where(a_first[sel], 1.0, -1.0)
    normal = con.frame[sel, :3] * sign[:, None]
    geom_a = np.where(a_first[sel], geom[sel, 0], geom[sel, 1])
    force = np.zeros(len(sel))
    if with_force:
        buf = np.zeros(6)
        for k, i in enumerate(sel):
            mujoco.mj_contactForce(model, data, int(i), buf)
            force[k] = buf[0]
    return Contacts(pos=con.pos[sel].copy(), normal=normal, dist=con.dist[sel].copy(),
                    body_a=model.geom_bodyid[geom_a], force_n=force)


def merge_nearby(points: np.ndarray, normals: np.ndarray, labels: np.ndarray | None = None,
                 cell_m: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """Merge contacts of the same label (e.g. hand body) that fall in the same ``cell_m`` grid
    cell into one: mean point, mean unit normal.

    MuJoCo reports several contacts per touching patch (a fingertip pad gives 2-4); for
    wrench-space metrics they add almost nothing but make the 6D hull slow (thousands of facets)
    and numerically fragile, so each patch is reduced to one point contact.
    """
    if len(points) == 0:
        return points, normals
    keys = np.floor(points / cell_m).astype(np.int64)
    if labels is not None:
        keys = np.column_stack([keys, labels])
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = inverse.ravel()
    count = np.bincount(inverse).astype(float)
    merged_p = np.stack([np.bincount(inverse, points[:, k]) for k in range(3)], 1) / count[:, None]
    merged_n = np.stack([np.bincount(inverse, normals[:, k]) for k in range(3)], 1)
    # (bincount with weights gives floats; numpy's stubs type it as int, so no in-place /=)
    merged_n = merged_n / np.linalg.norm(merged_n, axis=1, keepdims=True)
    return merged_p, merged_n
