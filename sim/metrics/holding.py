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

from sim.metrics.lp import EqualityLP

__all__ = ["HoldLoads", "finger_contacts", "min_actuator_efforts", "min_grip_force_n", "min_grip_forces_n"]


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


def _contact_columns(points_m: np.ndarray, normals_in: np.ndarray, centre_m: np.ndarray,
                     mu: float, mu_torsion_m: float, n_edges: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The contact model of the LPs. Variables: ``n·E`` cone-edge magnitudes (each edge carries
    1 N of normal force), then, with torsional friction, ``n`` positive and ``n`` negative
    spins about the normals. Returns the (6, V) wrench columns on the object, the (n·E, 3)
    edge forces, and the (n, V) rows of ``spin⁺ + spin⁻ − μ_t·λ ≤ 0`` (None without
    torsion)."""
    n = len(points_m)
    t1, t2 = _tangents(normals_in)
    angles = 2 * np.pi * np.arange(n_edges) / n_edges
    edges = (normals_in[:, None, :] + mu * (np.cos(angles)[None, :, None] * t1[:, None, :]
                                           + np.sin(angles)[None, :, None] * t2[:, None, :]))
    torques = np.cross((points_m - np.asarray(centre_m, dtype=float))[:, None, :], edges)
    columns = [np.concatenate([edges, torques], axis=2).reshape(n * n_edges, 6).T]
    torsion = None
    if mu_torsion_m > 0:
        spin = np.concatenate([np.zeros((n, 3)), normals_in], axis=1).T
        columns += [spin, -spin]
        torsion = np.zeros((n, n * n_edges + 2 * n))
        for i in range(n):
            torsion[i, i * n_edges:(i + 1) * n_edges] = -mu_torsion_m
            torsion[i, n * n_edges + i] = 1.0
            torsion[i, n * n_edges + n + i] = 1.0
    return np.concatenate(columns, axis=1), edges.reshape(n * n_edges, 3), torsion


def min_grip_forces_n(points_m: np.ndarray, normals_in: np.ndarray, centre_m: np.ndarray,
                      loads: np.ndarray, mu: float, mu_torsion_m: float = 0.0, n_edges: int = 8
                      ) -> np.ndarray:
    """Per external wrench of ``loads`` (k, 6: force in newtons, torque in N·m about
    ``centre_m``) on the object, the least total normal force (newtons) with which contacts at
    ``points_m`` (n, 3) with inward unit ``normals_in`` (n, 3) hold it: (k,), ``inf`` where no
    forces inside the friction cones (``mu``, torsional ``mu_torsion_m`` metres) can. One
    programme for all loads (:class:`sim.metrics.lp.EqualityLP`)."""
    points_m = np.asarray(points_m, dtype=float).reshape(-1, 3)
    normals_in = np.asarray(normals_in, dtype=float).reshape(-1, 3)
    loads = np.asarray(loads, dtype=float).reshape(-1, 6)
    n = len(points_m)
    if n == 0:
        return np.full(len(loads), np.inf)
    a_eq, _, torsion = _contact_columns(points_m, normals_in, centre_m, mu, mu_torsion_m, n_edges)
    cost = np.zeros(a_eq.shape[1])
    cost[:n * n_edges] = 1.0
    return EqualityLP(cost, a_eq, torsion).minima(-loads)


def min_grip_force_n(points_m: np.ndarray, normals_in: np.ndarray, centre_m: np.ndarray,
                     load: np.ndarray, mu: float, mu_torsion_m: float = 0.0, n_edges: int = 8
                     ) -> float:
    """:func:`min_grip_forces_n` of the one wrench ``load`` (6,)."""
    return float(min_grip_forces_n(points_m, normals_in, centre_m, load, mu, mu_torsion_m,
                                   n_edges)[0])


def min_actuator_efforts(points_m: np.ndarray, normals_in: np.ndarray, centre_m: np.ndarray,
                         loads: np.ndarray, mu: float, effort_per_force: np.ndarray,
                         effort_limit: np.ndarray, mu_torsion_m: float = 0.0, n_edges: int = 8
                         ) -> np.ndarray:
    """Per load of ``loads`` (k, 6), the least worst actuator effort, as a fraction of its
    limit, with which the hand holds it: minimise t subject to the contact forces of
    :func:`min_grip_forces_n` holding the load and every actuator's force
    ``|u_j| ≤ t · effort_limit[j]``, where the actuator forces are linear in the contact forces:
    ``u = effort_per_force @ f`` with ``effort_per_force`` (nu, n, 3) — per contact, the
    actuator forces that press the object with 1 N along each axis (from the contact Jacobian
    and the actuator moment arms; the caller builds it). (k,); > 1: the actuators cannot hold
    the load at these contacts however the forces are shared; ``inf``: the friction cones cannot
    at all."""
    points_m = np.asarray(points_m, dtype=float).reshape(-1, 3)
    normals_in = np.asarray(normals_in, dtype=float).reshape(-1, 3)
    loads = np.asarray(loads, dtype=float).reshape(-1, 6)
    n = len(points_m)
    if n == 0:
        return np.full(len(loads), np.inf)
    a_eq, edges, torsion = _contact_columns(points_m, normals_in, centre_m, mu, mu_torsion_m,
                                            n_edges)
    per = np.asarray(effort_per_force, dtype=float).reshape(-1, n, 3)
    limit = np.asarray(effort_limit, dtype=float).reshape(-1)
    keep = np.isfinite(limit) & (limit > 0)
    per, limit = per[keep], limit[keep]
    # actuator forces per unit of each edge variable: (nu, n·E)
    contact_of_edge = np.repeat(np.arange(n), n_edges)
    u_edges = np.einsum("uek,ek->ue", per[:, contact_of_edge, :], edges)
    v = a_eq.shape[1]
    u_cols = np.zeros((len(limit), v + 1))
    u_cols[:, :n * n_edges] = u_edges
    u_cols[:, v] = -limit
    a_ub = [u_cols, np.hstack([-u_cols[:, :v], -limit[:, None]])]
    if torsion is not None:
        a_ub.append(np.hstack([torsion, np.zeros((n, 1))]))
    cost = np.zeros(v + 1)
    cost[v] = 1.0
    return EqualityLP(cost, np.hstack([a_eq, np.zeros((6, 1))]), np.vstack(a_ub)).minima(-loads)


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
        loads = np.asarray(self.loads, dtype=float).reshape(-1, 6)
        lam = min_grip_forces_n(centres, normals_in, self.com_m, loads, self.mu, self.mu_torsion_m)
        if not np.all(np.isfinite(lam)):
            return float("inf")
        scale_n = np.maximum(np.linalg.norm(loads[:, :3], axis=1), 1e-9)
        return float(np.max(lam / scale_n, initial=0.0))
