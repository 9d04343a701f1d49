"""Fingertip contact faces (AutoWS, paper section 3.1): the flat patch of a fingertip that may
touch an object, approximated from a point cloud of the fingertip surface.

All inputs live in the fingertip body frame (``frame_tip``), in metres; normals are unit and point
out of the fingertip. The cloud is usually the pulp side of the fingertip
(:func:`augment.geometry.pulp.visible_pulp_cloud`); the face is a :class:`ContactFace`
(:mod:`augment.geometry.face`), its shape from :mod:`augment.geometry.inscribed`.

1. :func:`contact_face` — the centre ``c`` is the cloud point nearest to the query (the centroid
   of a demo's contacts on this fingertip, else the centroid of the visible cloud). Its
   neighbourhood is every point with ``|<p - c, n_c>| < depth_m`` and ``<n_p, n_c> > normal_dot``
   (paper eq. 1, printed there with ">" for the distance, which contradicts its text "points that
   are close to c along nor_c"; "<" is used), restricted to the part connected to ``c`` (links of
   2.5 median point spacings) so that a separate patch of similar orientation cannot stretch the
   hull over empty space (the paper does not say; on a fingertip this rarely changes anything).
   The neighbourhood is projected onto the tangent plane at ``c`` and its 2-D convex hull is
   taken. The face is the largest circle (default) or axis-aligned rectangle inside that hull.
   **Face centre:** the paper calls ``c`` "the center point of the desired contact face" and
   builds the workspace cloud from "the position and normal of the center point of each contact
   face", so by default (``centre="point"``) the face is centred on ``c``: the largest circle /
   rectangle centred at ``c`` inside the hull. The centre then lies on the fingertip surface and
   its normal is the surface normal there. ``centre="inscribed"`` instead finds the largest circle
   (Chebyshev centre, an LP) or rectangle anywhere in the hull, and moves the face centre there,
   on the tangent plane at ``c`` (so up to the surface's sagitta off the surface).
   The rectangle is axis-aligned in the in-plane basis whose first axis is ``v_u`` projected onto
   the plane (along the finger), the second ``n × first`` (across the finger).
2. :func:`extra_faces` — three more faces above, left and right of the first one: query points on
   the first face's plane at ``offset_factor`` (default 2) times its extent in that direction from
   its centre, i.e. where a face of the same size would just touch the first one; each is snapped
   to the nearest cloud point and grown like the first face. Faces smaller than 1/4 of the first
   one are dropped (paper), as are faces that snap back onto the first face's centre.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError, cKDTree

from augment.geometry.face import CentreMode, ContactFace, ContactFaceError, ShapeKind
from augment.geometry.inscribed import circle_at_origin, inscribed_circle, inscribed_rect, rect_at_origin
from augment.geometry.pulp import checked_cloud, finger_directions, unit_vector

__all__ = ["DEFAULT_DEPTH_M", "DEFAULT_NORMAL_DOT", "contact_face", "extra_faces"]

#: Neighbourhood half-depth along the centre normal, metres (authors' implementation: 3 mm).
DEFAULT_DEPTH_M = 0.003
#: Minimum normal dot product with the centre normal (authors' implementation: 0.5).
DEFAULT_NORMAL_DOT = 0.5
#: Connectivity link length of the neighbourhood, in median point spacings.
_LINK_SPACINGS = 2.5
#: Faces with a radius / half-edge below this are treated as empty, metres.
_MIN_SIZE_M = 1e-9


# ---------------------------------------------------------------------------------------------
# contact faces


def _plane_basis(normal: np.ndarray, v_u: np.ndarray | None) -> np.ndarray:
    """(2,3) orthonormal in-plane axes; the first along ``v_u`` projected onto the plane, or
    along the world axis least aligned with the normal when ``v_u`` is missing or parallel."""
    e0 = None
    if v_u is not None:
        proj = v_u - (v_u @ normal) * normal
        if np.linalg.norm(proj) > 1e-6:
            e0 = proj / np.linalg.norm(proj)
    if e0 is None:
        axis = np.eye(3)[int(np.argmin(np.abs(normal)))]
        proj = axis - (axis @ normal) * normal
        e0 = proj / np.linalg.norm(proj)
    e1 = np.cross(normal, e0)
    return np.stack([e0, e1 / np.linalg.norm(e1)])


def _connected_to(points: np.ndarray, seed: int) -> np.ndarray:
    """Boolean mask of the points linked to ``points[seed]`` by hops shorter than
    ``_LINK_SPACINGS`` median nearest-neighbour spacings."""
    if len(points) <= 2:
        return np.ones(len(points), dtype=bool)
    tree = cKDTree(points)
    nn, _ = tree.query(points, k=2)
    link = _LINK_SPACINGS * float(np.median(nn[:, 1]))
    if link <= 0:
        return np.ones(len(points), dtype=bool)
    pairs = tree.query_pairs(link, output_type="ndarray")
    graph = coo_array((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                      shape=(len(points), len(points)))
    _, labels = connected_components(graph, directed=False)
    return labels == labels[seed]


def contact_face(points: ArrayLike, normals: ArrayLike, query: ArrayLike | None = None, *,
                 depth_m: float = DEFAULT_DEPTH_M, normal_dot: float = DEFAULT_NORMAL_DOT,
                 shape: ShapeKind = "circle", v_u: ArrayLike | None = None,
                 centre: CentreMode = "point", connected: bool = True) -> ContactFace:
    """Approximate the contact face of a fingertip around ``query`` (see the module docstring).

    Args:
        points, normals: (N,3) fingertip cloud, usually :func:`~augment.geometry.pulp.visible_pulp_cloud`,
            metres.
        query: (3,) the initial query point ``q_init`` (centroid of a demo's contact points on
            this fingertip), metres; ``None`` uses the cloud centroid (paper, no demo).
        depth_m: neighbourhood half-depth along the centre normal, metres.
        normal_dot: minimum dot product between a neighbour's normal and the centre normal.
        shape: ``"circle"`` (default) or ``"rect"`` (axis-aligned in :attr:`ContactFace.basis`).
        v_u: finger "up" direction; orients the rectangle (first axis along the finger).
        centre: ``"point"`` (face centred on the cloud point, default) or ``"inscribed"``.
        connected: keep only the neighbourhood part connected to the centre.

    Raises:
        ContactFaceError: empty cloud, fewer than 3 neighbours, a degenerate (collinear or
            zero-area) neighbourhood, or a face of zero size (centre on the neighbourhood edge).
        ValueError: bad ``shape``/``centre``/``v_u``/``query`` or thresholds.
    """
    if shape not in ("circle", "rect"):
        raise ValueError(f"shape must be 'circle' or 'rect', got {shape!r}")
    if centre not in ("point", "inscribed"):
        raise ValueError(f"centre must be 'point' or 'inscribed', got {centre!r}")
    if not depth_m > 0:
        raise ValueError(f"depth_m must be > 0 metres, got {depth_m}")
    if not -1.0 <= normal_dot < 1.0:
        raise ValueError(f"normal_dot must be in [-1, 1), got {normal_dot}")
    p, n = checked_cloud(points, normals)
    up = None if v_u is None else unit_vector(v_u, "v_u (up, along the finger)")
    if query is None:
        q = p.mean(axis=0)
    else:
        q = np.asarray(query, dtype=float)
        if q.shape != (3,) or not np.isfinite(q).all():
            raise ValueError(f"query must be a finite 3-vector, got {q!r}")

    ci = int(np.argmin(np.einsum("ij,ij->i", p - q, p - q)))
    c, nc = p[ci], n[ci]
    rel = p - c
    mask = (np.abs(rel @ nc) < depth_m) & (n @ nc > normal_dot)
    mask[ci] = True
    sel = np.flatnonzero(mask)
    if connected and len(sel) > 2:
        sel = sel[_connected_to(p[sel], int(np.searchsorted(sel, ci)))]
    if len(sel) < 3:
        raise ContactFaceError(f"the neighbourhood of cloud point {ci} has {len(sel)} point(s), "
                               f"need >= 3: the cloud is too sparse there or depth_m={depth_m} / "
                               f"normal_dot={normal_dot} too strict")
    basis = _plane_basis(nc, up)
    xy = rel[sel] @ basis.T
    try:
        hull = ConvexHull(xy)
    except QhullError as exc:
        raise ContactFaceError(f"the neighbourhood of cloud point {ci} is degenerate (its "
                               f"{len(sel)} points project onto a line or a point)") from exc
    span = float(np.ptp(xy, axis=0).max())
    if hull.volume <= 1e-9 * span * span:
        raise ContactFaceError(f"the neighbourhood of cloud point {ci} has no area "
                               f"(hull area {hull.volume:.3g} m²)")
    edge_normals, offsets = hull.equations[:, :2], -hull.equations[:, 2]

    xy_c = np.zeros(2)
    if shape == "circle":
        if centre == "point":
            radius = circle_at_origin(offsets)
        else:
            xy_c, radius = inscribed_circle(edge_normals, offsets)
        size, area = radius, float(np.pi * radius * radius)
        half_edges = None
    else:
        if centre == "point":
            a, b = rect_at_origin(edge_normals, offsets)
        else:
            w, h = np.ptp(xy[hull.vertices], axis=0)
            xy_c, a, b = inscribed_rect(edge_normals, offsets, float(w), float(h))
        size, area = min(a, b), 4.0 * a * b
        half_edges = np.stack([a * basis[0], b * basis[1]])
        radius = None
    if size <= _MIN_SIZE_M:
        raise ContactFaceError(f"the contact face at cloud point {ci} has zero size: the point "
                               f"lies on the edge of its neighbourhood (e.g. on the rim of the "
                               f"visible cloud)")
    return ContactFace(centre=c + xy_c @ basis, normal=nc, shape=shape,
                       radius=None if radius is None else float(radius), half_edges=half_edges,
                       area=float(area), basis=basis, centre_index=ci)


def extra_faces(points: ArrayLike, normals: ArrayLike, main: ContactFace, v_f: ArrayLike,
                v_u: ArrayLike, *, depth_m: float = DEFAULT_DEPTH_M,
                normal_dot: float = DEFAULT_NORMAL_DOT, shape: ShapeKind | None = None,
                centre: CentreMode = "point", connected: bool = True,
                offset_factor: float = 2.0, min_area_ratio: float = 0.25) -> list[ContactFace]:
    """The up to three extra faces above, left and right of ``main`` (paper section 3.1).

    Query points lie on ``main``'s plane at ``offset_factor`` times its extent from its centre,
    along ``v_u`` projected onto the plane ("upper") and along ``±(v_u × v_f)`` made orthogonal
    to it ("left" = +, "right" = −). Each is grown with :func:`contact_face` on the same cloud
    (which must be the one ``main`` came from); a face is kept when it could be built, does not
    snap back onto ``main``'s centre point or an earlier extra face, and has at least
    ``min_area_ratio`` of ``main``'s area. Returned in the order upper, left, right (kept only).
    """
    f, u = finger_directions(v_f, v_u)
    if not offset_factor > 0:
        raise ValueError(f"offset_factor must be > 0, got {offset_factor}")
    p, n = checked_cloud(points, normals)
    nrm = main.normal
    up = u - (u @ nrm) * nrm
    up = main.basis[0] if np.linalg.norm(up) < 1e-6 else up / np.linalg.norm(up)
    side = np.cross(u, f)
    side = side - (side @ nrm) * nrm - (side @ up) * up
    side = np.cross(nrm, up) if np.linalg.norm(side) < 1e-6 else side / np.linalg.norm(side)
    kind = main.shape if shape is None else shape

    faces: list[ContactFace] = []
    used = {main.centre_index}
    for direction in (up, side, -side):
        query = main.centre + offset_factor * main.extent_along(direction) * direction
        try:
            face = contact_face(p, n, query, depth_m=depth_m, normal_dot=normal_dot, shape=kind,
                                v_u=u, centre=centre, connected=connected)
        except ContactFaceError:
            continue
        if face.centre_index in used or face.area < min_area_ratio * main.area:
            continue
        used.add(face.centre_index)
        faces.append(face)
    return faces
