"""Fingertip contact faces (AutoWS, paper section 3.1): the flat patch of a fingertip that may
touch an object, approximated from a point cloud of the fingertip surface.

All inputs live in the fingertip body frame (``frame_tip``), in metres; normals are unit and point
out of the fingertip. The pipeline of the paper, with the choices it leaves open:

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
3. :func:`contact_face` — the centre ``c`` is the cloud point nearest to the query (the centroid
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
4. :func:`extra_faces` — three more faces above, left and right of the first one: query points on
   the first face's plane at ``offset_factor`` (default 2) times its extent in that direction from
   its centre, i.e. where a face of the same size would just touch the first one; each is snapped
   to the nearest cloud point and grown like the first face. Faces smaller than 1/4 of the first
   one are dropped (paper), as are faces that snap back onto the first face's centre.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linprog
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError, cKDTree

from augment.geometry.visibility import DEFAULT_RADIUS_FACTOR, hidden_point_removal
from sim.errors import DexaugError

__all__ = [
    "DEFAULT_DEPTH_M",
    "DEFAULT_NORMAL_DOT",
    "ContactFace",
    "ContactFaceError",
    "contact_face",
    "extra_faces",
    "viewpoint",
    "visible_pulp_cloud",
    "visible_pulp_indices",
]

#: Neighbourhood half-depth along the centre normal, metres (authors' implementation: 3 mm).
DEFAULT_DEPTH_M = 0.003
#: Minimum normal dot product with the centre normal (authors' implementation: 0.5).
DEFAULT_NORMAL_DOT = 0.5
#: Viewpoint offsets along v_f and v_u, in bounding-box diagonals (paper section 3.1).
VIEW_FORWARD = 100.0
VIEW_UP = 50.0
#: Connectivity link length of the neighbourhood, in median point spacings.
_LINK_SPACINGS = 2.5
#: Faces with a radius / half-edge below this are treated as empty, metres.
_MIN_SIZE_M = 1e-9

ShapeKind = Literal["circle", "rect"]
CentreMode = Literal["point", "inscribed"]


class ContactFaceError(DexaugError, ValueError):
    """A contact face cannot be built: empty cloud, a neighbourhood with too few points or no
    area, a centre on the edge of its neighbourhood, or a viewpoint that sees nothing."""


@dataclass(frozen=True)
class ContactFace:
    """A planar fingertip contact face in the frame of the cloud it was built from.

    Attributes:
        centre: (3,) face centre, metres.
        normal: (3,) unit normal, out of the fingertip (towards the object it would touch).
        shape: ``"circle"`` or ``"rect"``.
        radius: circle radius, metres (``None`` for a rectangle).
        half_edges: (2,3) rectangle half-edge vectors, metres, along ``basis[0]`` and
            ``basis[1]`` (``None`` for a circle) — the paper stores these for rectangles.
        area: face area, square metres.
        basis: (2,3) orthonormal in-plane axes; ``basis[0] x basis[1] = normal``. ``basis[0]`` is
            ``v_u`` projected onto the plane when it was given.
        centre_index: index of the cloud point the face was grown from (``c``).
    """

    centre: np.ndarray
    normal: np.ndarray
    shape: ShapeKind
    radius: float | None
    half_edges: np.ndarray | None
    area: float
    basis: np.ndarray
    centre_index: int = field(default=-1)

    def __post_init__(self) -> None:
        if self.shape not in ("circle", "rect"):
            raise ValueError(f"shape must be 'circle' or 'rect', got {self.shape!r}")
        if self.shape == "circle" and self.radius is None:
            raise ValueError("a circular contact face needs a radius")
        if self.shape == "rect" and self.half_edges is None:
            raise ValueError("a rectangular contact face needs half_edges")
        for name in ("centre", "normal", "basis", "half_edges"):
            value = getattr(self, name)
            if value is not None:
                arr = np.array(value, dtype=float)
                arr.flags.writeable = False
                object.__setattr__(self, name, arr)

    def extent_along(self, direction: ArrayLike) -> float:
        """Distance (metres) from the centre to the face boundary along an in-plane unit
        direction (its component along the normal is ignored)."""
        w = np.asarray(direction, dtype=float)
        w = w - (w @ self.normal) * self.normal
        norm = float(np.linalg.norm(w))
        if norm < 1e-12:
            raise ValueError("direction is parallel to the face normal")
        w /= norm
        if self.radius is not None:
            return self.radius
        if self.half_edges is None:
            raise ValueError("a contact face needs a radius or half_edges")
        # distance to the rectangle boundary along w: min over the two slabs
        along = np.abs(self.half_edges @ w)
        half = np.linalg.norm(self.half_edges, axis=1)
        with np.errstate(divide="ignore"):
            t = np.where(along > 0, half * half / np.maximum(along, 1e-300), np.inf)
        return float(t.min())

    def contains(self, points: ArrayLike, *, plane_tol_m: float) -> np.ndarray:
        """Boolean mask (N,) of the points within ``plane_tol_m`` of the face plane whose
        projection falls inside the face (FSG collects object contacts this way). Rectangle
        half-edges are taken to lie along ``basis`` (as :func:`contact_face` builds them)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3) - self.centre
        near_plane = np.abs(p @ self.normal) <= plane_tol_m
        xy = p @ self.basis.T
        if self.radius is not None:
            inside = np.einsum("ij,ij->i", xy, xy) <= self.radius**2
        elif self.half_edges is not None:
            half = np.linalg.norm(self.half_edges, axis=1)
            inside = np.all(np.abs(xy) <= half, axis=1)
        else:
            raise ValueError("a contact face needs a radius or half_edges")
        return near_plane & inside


# ---------------------------------------------------------------------------------------------
# input checks


def _points(points: ArrayLike) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ContactFaceError(f"points must be an (N,3) array, got shape {p.shape}")
    if len(p) == 0:
        raise ContactFaceError("the point cloud is empty")
    if not np.isfinite(p).all():
        raise ContactFaceError("points contain NaN or inf")
    return p


def _cloud(points: ArrayLike, normals: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Checked (N,3) points and unit normals."""
    p = _points(points)
    n = np.asarray(normals, dtype=float)
    if n.shape != p.shape:
        raise ContactFaceError(f"normals must match points, shape {p.shape}; got {n.shape}")
    norm = np.linalg.norm(n, axis=1)
    if not (np.isfinite(norm).all() and norm.min() > 1e-9):
        raise ContactFaceError("normals contain zero-length, NaN or inf vectors")
    return p, n / norm[:, None]


def _unit(v: ArrayLike, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise ValueError(f"{name} must be a finite 3-vector, got {a!r}")
    norm = float(np.linalg.norm(a))
    if norm < 1e-12:
        raise ValueError(f"{name} must not be the zero vector")
    return a / norm


def _directions(v_f: ArrayLike, v_u: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    f = _unit(v_f, "v_f (forward, towards the pulp)")
    u = _unit(v_u, "v_u (up, along the finger)")
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
    p = _points(points)
    f, u = _directions(v_f, v_u)
    diag = float(np.linalg.norm(np.ptp(p, axis=0)))
    if diag <= 0:
        raise ContactFaceError("the point cloud has zero extent (all points coincide)")
    return p.mean(axis=0) + VIEW_FORWARD * diag * f + VIEW_UP * diag * u


def visible_pulp_indices(points: ArrayLike, normals: ArrayLike, v_f: ArrayLike, v_u: ArrayLike,
                         *, radius_factor: float = DEFAULT_RADIUS_FACTOR,
                         cull_backfaces: bool = True) -> np.ndarray:
    """Indices (sorted) of the fingertip points visible from :func:`viewpoint` (the pulp side):
    hidden point removal, then (by default) back-face culling of rim points."""
    p, n = _cloud(points, normals)
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
    p, n = _cloud(points, normals)
    return p[idx].copy(), n[idx].copy()


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


def _circle_at_origin(offsets: np.ndarray) -> float:
    """Largest circle centred at the origin inside {x: a_i·x <= h_i}: the nearest edge."""
    return float(max(offsets.min(), 0.0))


def _rect_at_origin(edge_normals: np.ndarray, offsets: np.ndarray) -> tuple[float, float]:
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


def _circle_inscribed(edge_normals: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, float]:
    """Chebyshev centre: max r s.t. a_i·x + r <= h_i (a_i unit), solved as an LP."""
    a_ub = np.hstack([edge_normals, np.ones((len(offsets), 1))])
    res = linprog(c=[0.0, 0.0, -1.0], A_ub=a_ub, b_ub=offsets,
                  bounds=[(None, None), (None, None), (0.0, None)], method="highs")
    if res.status != 0:
        raise ContactFaceError(f"inscribed-circle LP failed: {res.message}")
    return np.asarray(res.x[:2]), float(res.x[2])


def _rect_inscribed(edge_normals: np.ndarray, offsets: np.ndarray, width: float, height: float,
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


def contact_face(points: ArrayLike, normals: ArrayLike, query: ArrayLike | None = None, *,
                 depth_m: float = DEFAULT_DEPTH_M, normal_dot: float = DEFAULT_NORMAL_DOT,
                 shape: ShapeKind = "circle", v_u: ArrayLike | None = None,
                 centre: CentreMode = "point", connected: bool = True) -> ContactFace:
    """Approximate the contact face of a fingertip around ``query`` (see the module docstring).

    Args:
        points, normals: (N,3) fingertip cloud, usually :func:`visible_pulp_cloud`, metres.
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
    p, n = _cloud(points, normals)
    up = None if v_u is None else _unit(v_u, "v_u (up, along the finger)")
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
            radius = _circle_at_origin(offsets)
        else:
            xy_c, radius = _circle_inscribed(edge_normals, offsets)
        size, area = radius, float(np.pi * radius * radius)
        half_edges = None
    else:
        if centre == "point":
            a, b = _rect_at_origin(edge_normals, offsets)
        else:
            w, h = np.ptp(xy[hull.vertices], axis=0)
            xy_c, a, b = _rect_inscribed(edge_normals, offsets, float(w), float(h))
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
    f, u = _directions(v_f, v_u)
    if not offset_factor > 0:
        raise ValueError(f"offset_factor must be > 0, got {offset_factor}")
    p, n = _cloud(points, normals)
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
