"""How hard each grasping contact should press: normal forces that squeeze without shoving.

A squeeze that gives every contact the same normal force pushes the object whenever the
contacts are not arranged symmetrically: a thumb opposing four fingertips meets four times its
own force, so a free object is shoved toward the thumb while the fingers close, fingers lose
contact, and what is left at the lift is often the thumb and one finger (the authors'
five-finger sugar-box demonstration closes that way). An internal squeeze is a set of normal
forces λ ≥ 0 whose net wrench on the object is zero: it holds the object without moving it.

:func:`balanced_normal_forces` finds the normal forces of a given total that come closest to
that (bounded least squares): minimise ‖W λ‖² with W's columns the unit wrench of each contact's
normal, ``[nᵢ; (pᵢ − c) × nᵢ / ρ]`` (torques divided by the contacts' spread ρ, so force and
torque rows weigh alike), subject to ``Σ λ = total`` and every λᵢ at least ``min_share`` of the
equal split, so no contact the grasp relies on is left slack. Contacts that cannot be balanced
(all on one side) get the least unbalanced split the bounds allow; friction and the servos'
stiffness carry the rest, as before. Arrays in, arrays out (metres, newtons).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

__all__ = ["balanced_normal_forces", "normal_wrench_matrix"]

# weight of the "forces sum to the total" row against the balance rows (both in newtons)
_TOTAL_WEIGHT = 30.0
# smallest spread (metres) used to scale torques: about a fingertip pad
_MIN_SPREAD_M = 0.005


def normal_wrench_matrix(points_m: np.ndarray, normals: np.ndarray, centre_m: np.ndarray) -> np.ndarray:
    """(6, n) wrench on the object per newton of normal force at each contact: force rows are
    the unit normals ``normals`` (n, 3, pointing into the object), torque rows ``(p − c) × n``
    about ``centre_m`` divided by the contacts' RMS spread (so they are in newtons too)."""
    points_m = np.asarray(points_m, dtype=float).reshape(-1, 3)
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    centroid = points_m.mean(axis=0)
    spread_m = max(float(np.sqrt(((points_m - centroid) ** 2).sum(axis=1).mean())), _MIN_SPREAD_M)
    torques = np.cross(points_m - np.asarray(centre_m, dtype=float), normals) / spread_m
    return np.vstack([normals.T, torques.T])


def balanced_normal_forces(points_m: np.ndarray, normals: np.ndarray, centre_m: np.ndarray,
                           total_n: float, min_share: float = 0.25) -> np.ndarray:
    """(n,) normal forces (newtons) summing to ``total_n`` whose net wrench on the object about
    ``centre_m`` is as small as possible, each at least ``min_share · total_n / n``.

    ``points_m`` (n, 3) are the contact points, ``normals`` (n, 3) unit normals pointing into
    the object. One contact gets the whole total; ``min_share = 1`` is the equal split.
    """
    n = len(points_m)
    if n == 0:
        return np.zeros(0)
    floor_n = min(max(min_share, 0.0), 1.0) * total_n / n
    if n == 1 or floor_n * n >= total_n:
        return np.full(n, total_n / n)
    wrench = normal_wrench_matrix(points_m, normals, centre_m)
    a = np.vstack([wrench, np.full((1, n), _TOTAL_WEIGHT)])
    b = np.concatenate([np.zeros(6), [_TOTAL_WEIGHT * total_n]])
    sol = lsq_linear(a, b, bounds=(floor_n, np.inf), method="bvls")
    forces = np.maximum(sol.x, floor_n)
    return forces * (total_n / forces.sum())
