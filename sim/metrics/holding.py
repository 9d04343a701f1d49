"""How much grip a grasp needs to hold a load: the smallest total normal force, in newtons.

The GWS ε of :mod:`sim.metrics.gws` asks how large a wrench of *any* direction a unit grip
resists. A lift asks something narrower and physical: can these contacts, with the friction the
simulation uses, carry *this* load (the object's weight, a push), and how hard must the hand
press to do it? That is a linear programme (the classic minimum-grip problem):

    minimise Σᵢ λᵢ  over the contact forces
    subject to Σᵢ Gᵢ fᵢ = −w,   fᵢ in its friction cone,  |τᵢ| ≤ μ_t λᵢ

with one soft-finger contact per finger (the centroid and mean normal of the finger's contact
points: a fingertip pad is one contact patch, as MuJoCo's condim-4 contact is), each friction
cone a pyramid of ``n_edges`` edges ``n + μ t_j`` (so each edge carries exactly 1 N of normal
force), the torsional friction ``μ_t`` in metres (MuJoCo's second friction coefficient), and the
torque rows about the object's centre of mass. The optimum λ* is the least total normal force
that can hold the load; ``inf`` when no forces in the cones can (a load the contacts cannot
oppose, e.g. a weight pulling the object out between two fingertips). λ*/W — the *grip ratio* —
is dimensionless: 1/μ for an ideal opposed pinch of a weight W, more when the grip is twisted.

It says what the contacts *allow*; the realised forces depend on the hand's servos, so
:mod:`sim.validate.targets` sizes the squeeze from it and the validator decides. Arrays in
(metres, unit vectors, newtons), floats out (newtons).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

__all__ = ["HoldLoads", "finger_contacts", "min_grip_force_n"]


def finger_contacts(points_m: np.ndarray, normals_out: np.ndarray, finger: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """One contact per finger: (F, 3) centroids of each finger's contact points and (F, 3) unit
    mean *inward* normals, from ``points_m`` (M, 3), their outward ``normals_out`` (M, 3) and
    the finger index of each (M,), in the order of the sorted finger indices."""
    points_m = np.asarray(points_m, dtype=float).reshape(-1, 3)
    normals_out = np.asarray(normals_out, dtype=float).reshape(-1, 3)
    finger = np.asarray(finger).reshape(-1)
    ids = np.unique(finger)
    centres = np.array([points_m[finger == f].mean(axis=0) for f in ids]).reshape(-1, 3)
    mean_n = np.array([-normals_out[finger == f].sum(axis=0) for f in ids]).reshape(-1, 3)
    norms = np.linalg.norm(mean_n, axis=1, keepdims=True)
    return centres, mean_n / np.where(norms > 0, norms, 1.0)


def _tangents(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangent directions per unit normal (rows), orthogonal to it and to each other."""
    helper = np.where(np.abs(normals[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(normals, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(normals, t1)


def min_grip_force_n(points_m: np.ndarray, normals_in: np.ndarray, centre_m: np.ndarray,
                     load: np.ndarray, mu: float, mu_torsion_m: float = 0.0, n_edges: int = 8
                     ) -> float:
    """Least total normal force (newtons) with which contacts at ``points_m`` (n, 3) with
    inward unit ``normals_in`` (n, 3) hold the external wrench ``load`` (6,: force in newtons,
    torque in N·m about ``centre_m``) on the object; ``inf`` when no forces inside the friction
    cones (``mu``, torsional ``mu_torsion_m`` metres) can."""
    points_m = np.asarray(points_m, dtype=float).reshape(-1, 3)
    normals_in = np.asarray(normals_in, dtype=float).reshape(-1, 3)
    n = len(points_m)
    if n == 0:
        return float("inf")
    t1, t2 = _tangents(normals_in)
    angles = 2 * np.pi * np.arange(n_edges) / n_edges
    # (n, E, 3): the pyramid edges, each with 1 N of normal force
    edges = (normals_in[:, None, :] + mu * (np.cos(angles)[None, :, None] * t1[:, None, :]
                                           + np.sin(angles)[None, :, None] * t2[:, None, :]))
    arms = points_m - np.asarray(centre_m, dtype=float)
    torques = np.cross(arms[:, None, :], edges)
    columns = [np.concatenate([edges, torques], axis=2).reshape(n * n_edges, 6).T]
    cost = [np.ones(n * n_edges)]
    if mu_torsion_m > 0:
        # torsion about each normal, ±; bounded by μ_t × that contact's normal force below
        spin = np.concatenate([np.zeros((n, 3)), normals_in], axis=1).T
        columns += [spin, -spin]
        cost += [np.zeros(2 * n)]
    a_eq = np.concatenate(columns, axis=1)
    b_eq = -np.asarray(load, dtype=float).reshape(6)
    a_ub = None
    b_ub = None
    if mu_torsion_m > 0:
        # |s⁺ᵢ| + |s⁻ᵢ| ≤ μ_t Σ_k α_ik  for each contact i
        a_ub = np.zeros((n, a_eq.shape[1]))
        for i in range(n):
            a_ub[i, i * n_edges:(i + 1) * n_edges] = -mu_torsion_m
            a_ub[i, n * n_edges + i] = 1.0
            a_ub[i, n * n_edges + n + i] = 1.0
        b_ub = np.zeros(n)
    res = linprog(np.concatenate(cost), A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=b_eq,
                  bounds=(0, None), method="highs")
    return float(res.fun) if res.status == 0 else float("inf")


@dataclass(frozen=True)
class HoldLoads:
    """The loads a grasp must hold and the friction it holds them with, as plain data.

    Attributes:
        loads: (k, 6) external wrenches on the object in the object frame, one per test the
            protocol runs (the weight in the lift; each push): force in newtons, torque in N·m
            about ``com_m``.
        com_m: (3,) the object's centre of mass, object frame, metres.
        mu: sliding friction of the contacts; mu_torsion_m: torsional friction (metres).
        protocol: the validation protocol these loads come from (for reports).
    """

    loads: np.ndarray
    com_m: np.ndarray
    mu: float
    mu_torsion_m: float
    protocol: str = ""

    def grip_ratio(self, points_m: np.ndarray, normals_out: np.ndarray, finger: np.ndarray) -> float:
        """The grasp's grip ratio: over every load, the least total normal force that holds it
        divided by the load's force (dimensionless; ``inf`` when some load cannot be held), for
        contacts at ``points_m`` (M, 3) with outward ``normals_out`` and finger indices
        ``finger`` (M,) — one soft contact per finger (:func:`finger_contacts`)."""
        centres, normals_in = finger_contacts(points_m, normals_out, finger)
        worst = 0.0
        for load in np.asarray(self.loads, dtype=float).reshape(-1, 6):
            scale_n = max(float(np.linalg.norm(load[:3])), 1e-9)
            lam = min_grip_force_n(centres, normals_in, self.com_m, load, self.mu, self.mu_torsion_m)
            if not np.isfinite(lam):
                return float("inf")
            worst = max(worst, lam / scale_n)
        return worst
