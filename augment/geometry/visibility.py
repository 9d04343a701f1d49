"""Hidden point removal (Katz, Tal & Basri 2007, "Direct visibility of point sets").

AutoWS keeps only the fingertip points seen from a viewpoint far out on the pulp side, so that no
contact face is ever placed on the nail (paper section 3.1). HPR decides visibility from the
points alone, without a surface: every point is mirrored through a large sphere centred on the
viewpoint ("spherical flipping", p' = p + 2 (R - |p|) p/|p| with p relative to the viewpoint),
and the points whose images lie on the convex hull of the images plus the viewpoint are the
visible ones. A point hidden behind the surface maps to an image that is enclosed by the images
of the nearer points around it.

The sphere radius is ``R = radius_factor * max|p|``. A larger R keeps more points (in the limit
every point on the cloud's "silhouette cone" survives), a smaller R is stricter and also drops
visible points on strongly curved regions. Katz et al. search R over 10^k; for the far viewpoints
of AutoWS (about 110 cloud diagonals away) the results change little between 10^1 and 10^3 and the
default 10^2 was chosen by checking uniformly sampled spheres against the exact answer (see
tests/test_contact_face.py): it keeps all of the truly visible cap and nothing of the back side
beyond a thin band at the silhouette (normals within about 3° past the tangent). Factors of 10^4
and more lose precision (the flipped points sit at 2R while the cloud's depth is tiny compared
with R) and start keeping back-side points.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import ConvexHull, QhullError

from sim.errors import DexaugError

__all__ = ["DEFAULT_RADIUS_FACTOR", "VisibilityError", "hidden_point_removal"]

#: R / max|p| of the spherical flipping (see the module docstring).
DEFAULT_RADIUS_FACTOR = 100.0


class VisibilityError(DexaugError, ValueError):
    """A point cloud or viewpoint for which visibility is undefined (too few points, points at
    the viewpoint, all points in a plane through the viewpoint)."""


def hidden_point_removal(points: ArrayLike, viewpoint: ArrayLike,
                         radius_factor: float = DEFAULT_RADIUS_FACTOR) -> np.ndarray:
    """Indices (sorted, int64) of the points visible from ``viewpoint``.

    Args:
        points: (N,3) point positions, metres, N >= 4.
        viewpoint: (3,) eye position in the same frame, metres.
        radius_factor: flipping-sphere radius as a multiple of the farthest point's distance from
            the viewpoint (> 1).

    Raises:
        VisibilityError: fewer than 4 points, non-finite input, a point at the viewpoint, or a
            cloud whose flipped image has no 3-D hull (all points and the viewpoint coplanar).
    """
    p = np.asarray(points, dtype=float)
    c = np.asarray(viewpoint, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise VisibilityError(f"points must be an (N,3) array, got shape {p.shape}")
    if c.shape != (3,):
        raise VisibilityError(f"viewpoint must be a 3-vector, got shape {c.shape}")
    if len(p) < 4:
        raise VisibilityError(f"hidden point removal needs at least 4 points, got {len(p)}")
    if not (np.isfinite(p).all() and np.isfinite(c).all()):
        raise VisibilityError("points or viewpoint contain NaN or inf")
    if not radius_factor > 1.0:
        raise VisibilityError(f"radius_factor must be > 1, got {radius_factor}")

    rel = p - c
    dist = np.linalg.norm(rel, axis=1)
    far = float(dist.max())
    if dist.min() <= 1e-12 * far:
        raise VisibilityError("a point coincides with the viewpoint; visibility is undefined")
    radius = radius_factor * far
    flipped = rel * ((2.0 * radius - dist) / dist)[:, None]
    try:
        hull = ConvexHull(np.vstack([flipped, np.zeros((1, 3))]))
    except QhullError as exc:
        raise VisibilityError(f"hidden point removal failed: the cloud and the viewpoint are "
                              f"(nearly) coplanar ({str(exc).splitlines()[0]})") from exc
    vis = hull.vertices
    return np.sort(vis[vis < len(p)]).astype(np.int64)
