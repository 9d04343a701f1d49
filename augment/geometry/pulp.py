"""The pulp side of a fingertip cloud (AutoWS, paper section 3.1), and the checks of the clouds and
directions that the contact-face geometry takes in.

All inputs live in the fingertip body frame (``frame_tip``), in metres; normals are unit and point
out of the fingertip.

1. :func:`viewpoint` — ``cent + 100·d·v_f + 50·d·v_u``: far out on the pulp side and somewhat
   towards the tip. ``cent`` is the mean of the cloud (for a uniform surface sample this is the
   area centroid of the mesh surface) and ``d`` the diagonal of the cloud's axis-aligned bounding
   box, as the paper says ("the diagonal length of the mesh bounding box").
2. :func:`visible_pulp_cloud` — hidden point removal from that viewpoint
   (:func:`augment.geometry.visibility.hidden_point_removal`), which drops the nail side. HPR keeps a few
   points on sharp rims and silhouettes whose normals face away from the viewpoint (on the Shadow
   fingertip: the rim of the flat proximal cut, one point at the top of the nail); those are
   removed by back-face culling (normal · direction to the viewpoint > 0), which only discards
   points that cannot be seen on a closed surface.

The checks (:func:`checked_points`, :func:`checked_cloud`, :func:`unit_vector`,
:func:`finger_directions`) are shared with :mod:`augment.geometry.contact_face`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from augment.geometry.face import ContactFaceError
from augment.geometry.visibility import DEFAULT_RADIUS_FACTOR, hidden_point_removal

__all__ = [
    "VIEW_FORWARD",
    "VIEW_UP",
    "checked_cloud",
    "checked_points",
    "finger_directions",
    "unit_vector",
    "viewpoint",
    "visible_pulp_cloud",
    "visible_pulp_indices",
]

#: Viewpoint offsets along v_f and v_u, in bounding-box diagonals (paper section 3.1).
VIEW_FORWARD = 100.0
VIEW_UP = 50.0


# ---------------------------------------------------------------------------------------------
# input checks


def checked_points(points: ArrayLike) -> np.ndarray:
    """Checked (N,3) finite, non-empty points (raises :class:`ContactFaceError`)."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ContactFaceError(f"points must be an (N,3) array, got shape {p.shape}")
    if len(p) == 0:
        raise ContactFaceError("the point cloud is empty")
    if not np.isfinite(p).all():
        raise ContactFaceError("points contain NaN or inf")
    return p


def checked_cloud(points: ArrayLike, normals: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Checked (N,3) points and unit normals (normalised here; raises :class:`ContactFaceError`)."""
    p = checked_points(points)
    n = np.asarray(normals, dtype=float)
    if n.shape != p.shape:
        raise ContactFaceError(f"normals must match points, shape {p.shape}; got {n.shape}")
    norm = np.linalg.norm(n, axis=1)
    if not (np.isfinite(norm).all() and norm.min() > 1e-9):
        raise ContactFaceError("normals contain zero-length, NaN or inf vectors")
    return p, n / norm[:, None]


def unit_vector(v: ArrayLike, name: str) -> np.ndarray:
    """``v`` (a finite, non-zero 3-vector) normalised; ``name`` goes into the ValueError."""
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise ValueError(f"{name} must be a finite 3-vector, got {a!r}")
    norm = float(np.linalg.norm(a))
    if norm < 1e-12:
        raise ValueError(f"{name} must not be the zero vector")
    return a / norm


def finger_directions(v_f: ArrayLike, v_u: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Unit ``(v_f, v_u)``: forward (towards the pulp) and up (along the finger); ValueError when
    either is bad or they are parallel."""
    f = unit_vector(v_f, "v_f (forward, towards the pulp)")
    u = unit_vector(v_u, "v_u (up, along the finger)")
    if np.linalg.norm(np.cross(f, u)) < 1e-6:
        raise ValueError(f"v_f {f.round(6).tolist()} and v_u {u.round(6).tolist()} are parallel; "
                         f"they must span the pulp-side viewing direction")
    return f, u


# ---------------------------------------------------------------------------------------------
# viewpoint and visibility


def viewpoint(points: ArrayLike, v_f: ArrayLike, v_u: ArrayLike) -> np.ndarray:
    """HPR viewpoint ``cent + 100·d·v_f + 50·d·v_u`` (metres) of a fingertip cloud: ``cent`` the
    cloud mean, ``d`` its bounding-box diagonal, ``v_f``/``v_u`` normalised (not
    orthogonalised)."""
    p = checked_points(points)
    f, u = finger_directions(v_f, v_u)
    diag = float(np.linalg.norm(np.ptp(p, axis=0)))
    if diag <= 0:
        raise ContactFaceError("the point cloud has zero extent (all points coincide)")
    return p.mean(axis=0) + VIEW_FORWARD * diag * f + VIEW_UP * diag * u


def visible_pulp_indices(points: ArrayLike, normals: ArrayLike, v_f: ArrayLike, v_u: ArrayLike,
                         *, radius_factor: float = DEFAULT_RADIUS_FACTOR,
                         cull_backfaces: bool = True) -> np.ndarray:
    """Indices (sorted) of the fingertip points visible from :func:`viewpoint` (the pulp side):
    hidden point removal, then (by default) back-face culling of rim points."""
    p, n = checked_cloud(points, normals)
    eye = viewpoint(p, v_f, v_u)
    idx = hidden_point_removal(p, eye, radius_factor)
    if cull_backfaces:
        facing = np.einsum("ij,ij->i", n[idx], eye - p[idx]) > 0
        idx = idx[facing]
    if len(idx) == 0:
        raise ContactFaceError("no fingertip point is visible from the pulp-side viewpoint; "
                               "check v_f (towards the pulp) and the normals (outward)")
    return idx


def visible_pulp_cloud(points: ArrayLike, normals: ArrayLike, v_f: ArrayLike, v_u: ArrayLike,
                       *, radius_factor: float = DEFAULT_RADIUS_FACTOR,
                       cull_backfaces: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(points, normals)`` of the pulp side of a fingertip cloud (``cloud_f`` of the paper):
    the candidates for contact-face centres."""
    idx = visible_pulp_indices(points, normals, v_f, v_u, radius_factor=radius_factor,
                               cull_backfaces=cull_backfaces)
    p, n = checked_cloud(points, normals)
    return p[idx].copy(), n[idx].copy()

