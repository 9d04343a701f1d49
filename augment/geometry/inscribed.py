"""Largest circles and axis-aligned rectangles inside a convex polygon (the contact-face shapes of
AutoWS, paper section 3.1).

The polygon is ``{x: a_i·x <= h_i}``, given by its edge normals ``a_i`` (unit, (M,2)) and offsets
``h_i`` (M,), as :class:`scipy.spatial.ConvexHull` reports them (``equations[:, :2]`` and
``-equations[:, 2]``); lengths are in the polygon's units (metres in AutoWS). Rectangles are
axis-aligned in the polygon's coordinates and described by their half-edges ``a`` (first axis)
and ``b`` (second axis).

* centred at the origin: :func:`circle_at_origin` (the nearest edge) and :func:`rect_at_origin`
  (exact, by enumerating the optimum's candidates);
* anywhere: :func:`inscribed_circle` (Chebyshev centre, an LP) and :func:`inscribed_rect` (an LP
  per aspect ratio, golden-section search over the ratio).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from augment.geometry.face import ContactFaceError

__all__ = ["circle_at_origin", "inscribed_circle", "inscribed_rect", "rect_at_origin"]


def circle_at_origin(offsets: np.ndarray) -> float:
    """Largest circle centred at the origin inside {x: a_i·x <= h_i}: the nearest edge."""
    return float(max(offsets.min(), 0.0))


def rect_at_origin(edge_normals: np.ndarray, offsets: np.ndarray) -> tuple[float, float]:
    """Largest axis-aligned rectangle ``[-a, a] x [-b, b]`` inside {x: a_i·x <= h_i} (exact).

    The four corners are inside iff ``|n_i0| a + |n_i1| b <= h_i`` for every edge, a polygon in
    (a, b). The maximum of ``a·b`` on a polygon lies at a vertex or where an edge line is tangent
    to a hyperbola ``a·b = const`` (the midpoint ``(h/2α, h/2β)`` of that line between the axes),
    so all those candidates are enumerated and the best feasible one is taken."""
    alpha, beta = np.abs(edge_normals[:, 0]), np.abs(edge_normals[:, 1])
    h = np.maximum(offsets, 0.0)
    cands = [np.zeros((1, 2))]
    both = (alpha > 1e-12) & (beta > 1e-12)
    cands.append(np.stack([h[both] / (2 * alpha[both]), h[both] / (2 * beta[both])], axis=1))
    i, j = np.triu_indices(len(h), k=1)
    det = alpha[i] * beta[j] - alpha[j] * beta[i]
    ok = np.abs(det) > 1e-12
    i, j, det = i[ok], j[ok], det[ok]
    cands.append(np.stack([(h[i] * beta[j] - h[j] * beta[i]) / det,
                           (alpha[i] * h[j] - alpha[j] * h[i]) / det], axis=1))
    c = np.vstack(cands)
    c = c[(c >= -1e-15).all(axis=1)]
    scale = max(float(h.max()), 1e-300)
    feasible = np.all(c @ np.stack([alpha, beta]) <= h + 1e-9 * scale, axis=1)
    c = np.clip(c[feasible], 0.0, None)
    best = int(np.argmax(c[:, 0] * c[:, 1]))
    return float(c[best, 0]), float(c[best, 1])


def inscribed_circle(edge_normals: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, float]:
    """Chebyshev centre: max r s.t. a_i·x + r <= h_i (a_i unit), solved as an LP."""
    a_ub = np.hstack([edge_normals, np.ones((len(offsets), 1))])
    res = linprog(c=[0.0, 0.0, -1.0], A_ub=a_ub, b_ub=offsets,
                  bounds=[(None, None), (None, None), (0.0, None)], method="highs")
    if res.status != 0:
        raise ContactFaceError(f"inscribed-circle LP failed: {res.message}")
    return np.asarray(res.x[:2]), float(res.x[2])


def inscribed_rect(edge_normals: np.ndarray, offsets: np.ndarray, width: float, height: float,
                    ) -> tuple[np.ndarray, float, float]:
    """Largest axis-aligned rectangle anywhere in {x: a_i·x <= h_i}.

    For a fixed aspect ratio ``ρ = b/a`` the best rectangle is an LP in (centre, a). The log of
    the best area is concave in ``log ρ`` (partial maximisation of a concave objective over a
    convex set), so a golden-section search over ``log ρ`` within a factor 20 either side of the
    hull's own aspect ratio finds the optimum; 40 iterations give ``log ρ`` to about 1e-7, i.e.
    an area within about 1e-6 relative of the optimum."""
    abs_n = np.abs(edge_normals)

    def best_for(log_rho: float) -> tuple[float, np.ndarray, float, float]:
        rho = float(np.exp(log_rho))
        a_ub = np.hstack([edge_normals, (abs_n[:, 0] + rho * abs_n[:, 1])[:, None]])
        res = linprog(c=[0.0, 0.0, -1.0], A_ub=a_ub, b_ub=offsets,
                      bounds=[(None, None), (None, None), (0.0, None)], method="highs")
        if res.status != 0:
            raise ContactFaceError(f"inscribed-rectangle LP failed: {res.message}")
        a = float(res.x[2])
        return 4.0 * rho * a * a, np.asarray(res.x[:2]), a, a * rho

    centre_ratio = np.log(max(height, 1e-300) / max(width, 1e-300))
    lo, hi = centre_ratio - np.log(20.0), centre_ratio + np.log(20.0)
    golden = (np.sqrt(5.0) - 1.0) / 2.0
    x1, x2 = hi - golden * (hi - lo), lo + golden * (hi - lo)
    f1, f2 = best_for(x1)[0], best_for(x2)[0]
    for _ in range(40):
        if f1 < f2:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + golden * (hi - lo)
            f2 = best_for(x2)[0]
        else:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - golden * (hi - lo)
            f1 = best_for(x1)[0]
    _, xy, a, b = best_for(0.5 * (lo + hi))
    return xy, a, b
