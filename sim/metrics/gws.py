"""Grasp wrench space (GWS) quality: Q1 (ε) and hull volume, GraspIt conventions (DESIGN §4, §5).

Two callers use the same code so that their numbers are comparable: the FSG sampler scores its
*sampled* contacts, and the MuJoCo validator scores the *simulated* contacts after closing (the
paper's "valid ε"). Both call it many times, so everything up to the convex hull is vectorised
NumPy and the hull itself is one Qhull call.

Model (Ferrari & Canny's L1 GWS, as in the paper's eq. 1 and GraspIt):

- each contact applies a unit normal force along its normal (pointing *into* the object: the
  direction of the force the hand applies), with Coulomb friction ``mu``; the friction cone is
  approximated by ``n_edges`` edge forces ``n + mu·t_j`` (tangent directions ``t_j`` evenly
  spaced), so every edge has a normal component of exactly 1 N;
- each edge force ``f`` at point ``p`` gives the wrench ``(f, (p − centre) × f / ρ)``, where ``ρ``
  (``torque_scale_m``) is the object's maximum radius from ``centre``: dividing by it makes torque
  (N·m) commensurate with force (N), so ε does not depend on the object's size in metres;
- the GWS is the convex hull of all edge wrenches. ε is the radius of the largest ball about the
  origin inside it (the smallest facet-plane distance); it is ``-1`` when the origin is not
  strictly inside (no force closure). The authors' reference code returned a positive value in
  that case; we do not. The volume is the hull's 6D volume whatever the origin's position (as
  GraspIt's ``QualVolume``); callers that average it "over force-closure grasps" as in the paper
  filter on :attr:`GwsMetrics.force_closure`.

Degenerate inputs (no contacts, fewer than 7 wrenches, wrenches spanning less than 6D) are not
errors: they are grasps without force closure, reported as ε = −1 and volume 0. Malformed inputs
(wrong shapes, NaN) are caller bugs and raise ``ValueError`` naming the argument.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from sim.transforms import cross

NO_FORCE_CLOSURE = -1.0
"""ε reported when the origin is not strictly inside the GWS (GraspIt convention)."""

WRENCH_DIM = 6
MIN_CONE_EDGES = 3  # fewer edges cannot span the tangent plane: the "cone" would be flat
# The origin counts as inside only when its distance to every facet exceeds this fraction of the
# largest wrench norm: Qhull's facet offsets carry errors of ~1e-15 relative, so an origin lying
# on a facet (e.g. two antipodal contacts) must not come out as a tiny positive ε.
INSIDE_REL_TOL = 1e-9
# Wrench sets whose smallest singular value (about their mean) is below this fraction of the
# largest are flat in 6D: Qhull would either fail or return a sliver of rounding noise.
RANK_REL_TOL = 1e-9


@dataclass(frozen=True)
class GwsMetrics:
    """Quality of one grasp: ``epsilon`` = Q1, the radius of the largest origin-centred ball in
    the GWS (units of the unit normal force, torque scaled by ``torque_scale_m``), −1 without force
    closure; ``volume`` = 6D volume of the GWS hull, 0 when the wrenches do not span 6D."""

    epsilon: float
    volume: float

    @property
    def force_closure(self) -> bool:
        """Whether the origin is strictly inside the GWS, i.e. any wrench can be resisted."""
        return self.epsilon > 0.0


DEGENERATE = GwsMetrics(epsilon=NO_FORCE_CLOSURE, volume=0.0)


# ------------------------------------------------------------------------------ validation


def _vectors(name: str, value: np.ndarray, n: int | None = None) -> np.ndarray:
    """``value`` as a finite float (N,3) array (a single (3,) vector is not accepted: an
    ambiguous shape usually means a transposed or flattened input)."""
    arr = np.asarray(value, dtype=float)
    expected = "(N, 3)" if n is None else f"({n}, 3)"
    if arr.ndim != 2 or arr.shape[1] != 3 or (n is not None and arr.shape[0] != n):
        raise ValueError(f"{name}: expected shape {expected}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: contains NaN or infinite values")
    return arr


def _unit_normals(normals: np.ndarray, n: int | None = None, name: str = "normals") -> np.ndarray:
    """Normals normalised to unit length; a (near-)zero normal has no direction and is rejected."""
    arr = _vectors(name, normals, n)
    norm = np.linalg.norm(arr, axis=1)
    if arr.shape[0] and norm.min() < 1e-12:
        raise ValueError(f"{name}: row {int(norm.argmin())} has zero length; normals must be non-zero")
    return arr / norm[:, None]


def _check_mu(mu: float) -> float:
    mu = float(mu)
    if not np.isfinite(mu) or mu < 0.0:
        raise ValueError(f"mu: expected a finite friction coefficient >= 0, got {mu}")
    return mu


def _check_edges(n_edges: int) -> int:
    if int(n_edges) != n_edges or n_edges < MIN_CONE_EDGES:
        raise ValueError(f"n_edges: expected an integer >= {MIN_CONE_EDGES}, got {n_edges}")
    return int(n_edges)


def _check_centre(centre: np.ndarray | Sequence[float] | None) -> np.ndarray:
    if centre is None:
        return np.zeros(3)
    arr = np.asarray(centre, dtype=float)
    if arr.shape != (3,):
        raise ValueError(f"centre: expected shape (3,), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("centre: contains NaN or infinite values")
    return arr


def _check_scale(torque_scale_m: float) -> float:
    scale = float(torque_scale_m)
    if not np.isfinite(scale) or scale <= 0.0:
        raise ValueError(f"torque_scale_m: expected a finite length > 0 metres, got {torque_scale_m}")
    return scale


# ------------------------------------------------------------------------------ wrenches


def tangent_basis(normals: np.ndarray, tangents: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangent pair ``(t1, t2)``, each (N,3), with ``t1 × t2 = n`` for unit normals.

    Without ``tangents``, ``t1`` is ``n × e_k`` normalised, with ``e_k`` the axis along which
    ``n`` has its smallest component: ``|n × e_k| >= sqrt(2/3)``, so it is well conditioned for
    every normal (axis-aligned ones included), unlike a fixed helper axis. This choice is not
    rotation-equivariant (no continuous choice on the sphere can be), so a rotated grasp gets its
    polygonal cones at a different phase; pass ``tangents`` (any vectors not parallel to the
    normals, e.g. MuJoCo's contact frame) to pin the phase: they are projected onto each tangent
    plane and used as ``t1``.
    """
    n = np.asarray(normals, dtype=float)
    if tangents is None:
        k = np.argmin(np.abs(n), axis=1)
        helper = np.zeros_like(n)
        helper[np.arange(len(n)), k] = 1.0
        t1 = cross(n, helper)
    else:
        t = _vectors("tangents", tangents, len(n))
        t1 = t - np.sum(t * n, axis=1, keepdims=True) * n
    norm = np.linalg.norm(t1, axis=1)
    if len(n) and norm.min() < 1e-9:
        raise ValueError(f"tangents: row {int(norm.argmin())} is parallel to its normal")
    t1 = t1 / norm[:, None]
    t2 = cross(n, t1)
    return t1, t2


def friction_cone_edges(normals: np.ndarray, mu: float, n_edges: int = 8,
                        tangents: np.ndarray | None = None) -> np.ndarray:
    """Edge forces of the polygonal friction cones, (N, n_edges, 3), newtons per newton of normal
    force: ``n + mu·(cos θ_j t1 + sin θ_j t2)`` with ``θ_j = 2πj / n_edges``.

    ``normals`` (N,3) point into the object (the force the hand applies) and are normalised here;
    ``tangents`` optionally fixes the direction of edge 0 (see :func:`tangent_basis`).
    """
    n = _unit_normals(normals)
    mu = _check_mu(mu)
    m = _check_edges(n_edges)
    t1, t2 = tangent_basis(n, tangents)
    theta = 2.0 * np.pi * np.arange(m) / m
    tangential = (np.cos(theta)[None, :, None] * t1[:, None, :]
                  + np.sin(theta)[None, :, None] * t2[:, None, :])
    return n[:, None, :] + mu * tangential


def contact_wrenches(points: np.ndarray, normals: np.ndarray, mu: float, n_edges: int = 8,
                     centre: np.ndarray | Sequence[float] | None = None, *, torque_scale_m: float,
                     tangents: np.ndarray | None = None) -> np.ndarray:
    """Edge wrenches of all contacts, (N·n_edges, 6), contact-major: ``(f, (p − centre) × f / ρ)``.

    ``points`` (N,3) metres and ``centre`` (3,) metres share a frame (the object's); forces are in
    units of the unit normal force; torques are divided by ``torque_scale_m`` = ρ, the object's
    maximum radius from ``centre`` in metres, so both halves are dimensionless and commensurate.
    ``torque_scale_m`` has no default on purpose: a wrong one silently reweights torque vs force.
    """
    p = _vectors("points", points)
    edges = friction_cone_edges(_unit_normals(normals, len(p)), mu, n_edges, tangents)
    c = _check_centre(centre)
    scale = _check_scale(torque_scale_m)
    torques = cross((p - c)[:, None, :], edges) / scale
    return np.concatenate([edges, torques], axis=2).reshape(-1, WRENCH_DIM)


# ------------------------------------------------------------------------------ metrics


# Qhull option sets tried in order (scipy always adds "i Qt"):
# - "Q0" (no facet merging): about 3x faster on these 6D sets (~1000 facets for four contacts) and
#   equal to the default options to ~1e-11 relative on thousands of random and box-aligned grasps;
#   without merging, Qhull reports nearly coplanar facets as precision errors instead of merging
#   them, so such inputs fall through to
# - None (scipy's default, merging), and then
# - "QJ": simulated contacts come in near-duplicate clusters, which can trip Qhull's merging
#   ("dupridge" topology errors); joggling the input (~1e-11 relative) resolves them.
_QHULL_OPTIONS: tuple[str | None, ...] = ("Q0", None, "QJ")


def _hull(w: np.ndarray) -> ConvexHull | None:
    """Qhull hull of ``w`` (M,6), or None when no option set gives one (see ``_QHULL_OPTIONS``)."""
    for options in _QHULL_OPTIONS:
        try:
            return ConvexHull(w, qhull_options=options)
        except (QhullError, ValueError):
            continue
    return None


def wrench_hull_metrics(wrenches: np.ndarray) -> GwsMetrics:
    """ε and volume of the convex hull of given 6D wrenches (M,6); see the module docstring.

    Exposed separately so callers with their own wrench sets (e.g. soft-finger models) get the
    same conventions and degenerate-case handling.
    """
    w = np.asarray(wrenches, dtype=float)
    if w.ndim != 2 or w.shape[1] != WRENCH_DIM:
        raise ValueError(f"wrenches: expected shape (M, {WRENCH_DIM}), got {w.shape}")
    if not np.isfinite(w).all():
        raise ValueError("wrenches: contains NaN or infinite values")
    if w.shape[0] <= WRENCH_DIM:  # a 6D simplex needs 7 vertices
        return DEGENERATE
    scale = float(np.sqrt(np.einsum("ij,ij->i", w, w).max()))
    if scale == 0.0:
        return DEGENERATE
    sv = np.linalg.svd(w - w.mean(axis=0), compute_uv=False)
    if sv[-1] <= RANK_REL_TOL * sv[0]:
        return DEGENERATE
    hull = _hull(w)
    if hull is None:
        return DEGENERATE
    # equations rows are [unit normal, offset] with n·x + offset <= 0 inside, so the origin's
    # distance to facet k is -offset_k (positive for every facet iff the origin is inside)
    dist = -hull.equations[:, -1]
    d_min = float(dist.min())
    epsilon = d_min if d_min > INSIDE_REL_TOL * scale else NO_FORCE_CLOSURE
    return GwsMetrics(epsilon=epsilon, volume=float(hull.volume))


def gws_metrics(points: np.ndarray, normals: np.ndarray, mu: float = 0.5, n_edges: int = 8,
                centre: np.ndarray | Sequence[float] | None = None, *, torque_scale_m: float,
                tangents: np.ndarray | None = None) -> GwsMetrics:
    """Q1 (ε) and GWS volume of point contacts with friction.

    ``points`` (N,3) metres and ``normals`` (N,3, pointing into the object) in the object frame,
    ``centre`` (3,) metres (default: the frame origin; use the centre of mass), ``mu`` the
    friction coefficient, ``n_edges`` cone edges, ``torque_scale_m`` the object's maximum radius
    from ``centre`` (metres). Zero contacts give ε = −1, volume 0; bad shapes or NaN raise
    ``ValueError``.
    """
    p = _vectors("points", points)
    _vectors("normals", normals, len(p))
    if len(p) == 0:
        # still validate the scalar arguments, so a bad call fails the same with or without contacts
        _check_mu(mu)
        _check_edges(n_edges)
        _check_centre(centre)
        _check_scale(torque_scale_m)
        return DEGENERATE
    w = contact_wrenches(p, normals, mu, n_edges, centre, torque_scale_m=torque_scale_m,
                         tangents=tangents)
    return wrench_hull_metrics(w)


def gws_metrics_batch(grasps: Sequence[tuple[np.ndarray, np.ndarray]], mu: float = 0.5, n_edges: int = 8,
                      centre: np.ndarray | Sequence[float] | None = None, *,
                      torque_scale_m: float) -> tuple[np.ndarray, np.ndarray]:
    """ε and volume, each (G,), for several grasps ``[(points, normals), ...]`` on one object.

    A plain loop: each grasp needs its own Qhull call, which dominates the cost.
    """
    eps = np.empty(len(grasps))
    vol = np.empty(len(grasps))
    for i, (p, n) in enumerate(grasps):
        m = gws_metrics(p, n, mu, n_edges, centre, torque_scale_m=torque_scale_m)
        eps[i], vol[i] = m.epsilon, m.volume
    return eps, vol


# ------------------------------------------------------------------------------ benchmark


def benchmark(n_calls: int = 1000, n_contacts: int = 4, seed: int = 0) -> float:
    """Milliseconds per :func:`gws_metrics` call on random contacts on a unit sphere (normals
    inward), printed by ``python -m sim.metrics.gws``: a sanity number for the FSG sampler's budget."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n_calls, n_contacts, 3))
    pts /= np.linalg.norm(pts, axis=2, keepdims=True)
    n_closure = 0
    start = time.perf_counter()
    for g in range(n_calls):
        n_closure += gws_metrics(pts[g], -pts[g], torque_scale_m=1.0).force_closure
    elapsed = time.perf_counter() - start
    ms = 1e3 * elapsed / n_calls
    print(f"gws_metrics: {ms:.3f} ms per call ({n_calls} random {n_contacts}-contact grasps, "
          f"{n_closure} in force closure)")
    return ms


if __name__ == "__main__":
    benchmark()
