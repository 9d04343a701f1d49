"""Fingertip clouds and contact faces per finger (AutoWS, paper section 3.1), in the fingertip
body frame.

A finger's contact faces depend only on the fingertip mesh, the finger's ``v_f``/``v_u`` and the
query point (a demo's contact centroid, or none), never on the joint angles, so they are computed
once per finger here and then carried through forward kinematics by :mod:`augment.autows.build`.

Steps (implemented in :mod:`augment.geometry` — ``sampling``, ``pulp``, ``contact_face``):

1. :func:`tip_mesh` — the fingertip mesh of the hand model in the tip *body* frame. MuJoCo
   re-centres and re-orients meshes on compile (``mesh_vert`` is in the mesh's inertial frame);
   the geom that uses the mesh on the tip body carries the mesh pose, so vertices are mapped by
   that geom's ``geom_pos``/``geom_quat``.
2. :func:`fingertip_cloud` — Poisson-disk samples with outward normals (about 2e6 points/m²).
   Cached in memory by mesh content, density and seed: the four Shadow fingers share one mesh.
3. :func:`fingertip_faces` — hidden point removal from the pulp-side viewpoint (the nail side
   goes), the main contact face around the query, then the kept extra faces (upper, left, right;
   each at least 1/4 of the main face's area). Cached in memory by all of its inputs.
"""

from __future__ import annotations

import hashlib
import logging
from collections import OrderedDict
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from augment.geometry.contact_face import DEFAULT_DEPTH_M, DEFAULT_NORMAL_DOT, contact_face, extra_faces
from augment.geometry.face import CentreMode, ContactFace, ContactFaceError, ShapeKind
from augment.geometry.pulp import visible_pulp_cloud
from augment.geometry.sampling import poisson_disk_sample
from augment.geometry.visibility import DEFAULT_RADIUS_FACTOR
from sim.errors import ConfigError
from sim.transforms import quat_to_mat

if TYPE_CHECKING:
    from sim.hand.model import Hand

__all__ = [
    "FingertipFaces",
    "FingertipParams",
    "TipMesh",
    "clear_caches",
    "fingertip_cloud",
    "fingertip_faces",
    "hand_fingertip_faces",
    "tip_mesh",
]

log = logging.getLogger(__name__)

#: Entries kept by each in-memory cache (a few hands' worth of fingers and demos).
_CACHE_SIZE = 64


@dataclass(frozen=True)
class FingertipParams:
    """Parameters of the fingertip cloud and its contact faces (``[autows]`` of
    ``configs/augment.toml``; defaults are the authors' values, DESIGN §4).

    Attributes:
        density_per_m2: Poisson-disk sample density on the fingertip surface, points/m².
        seed: seed of the Poisson-disk sampler (same seed and mesh → same cloud).
        depth_m: contact-face neighbourhood half-depth along the centre normal, metres.
        normal_dot: minimum normal dot product of a neighbour with the centre normal.
        shape: ``"circle"`` (largest inscribed circle, the paper's default) or ``"rect"``.
        centre: ``"point"`` (face centred on the cloud point, the paper) or ``"inscribed"``.
        extra_faces: also build the upper / left / right extra faces.
        extra_min_area_ratio: an extra face is kept when its area is at least this fraction of
            the main face's.
        extra_offset_factor: extra-face query distance from the main face centre, in main-face
            extents (2: where a same-sized face would just touch the main one).
        hpr_radius_factor: spherical-flipping radius of hidden point removal, in farthest-point
            distances.
    """

    density_per_m2: float = 2e6
    seed: int = 0
    depth_m: float = DEFAULT_DEPTH_M
    normal_dot: float = DEFAULT_NORMAL_DOT
    shape: ShapeKind = "circle"
    centre: CentreMode = "point"
    extra_faces: bool = True
    extra_min_area_ratio: float = 0.25
    extra_offset_factor: float = 2.0
    hpr_radius_factor: float = DEFAULT_RADIUS_FACTOR

    def __post_init__(self) -> None:
        if self.shape not in ("circle", "rect"):
            raise ValueError(f"shape must be 'circle' or 'rect', got {self.shape!r}")
        if self.centre not in ("point", "inscribed"):
            raise ValueError(f"centre must be 'point' or 'inscribed', got {self.centre!r}")
        if not (np.isfinite(self.density_per_m2) and self.density_per_m2 > 0):
            raise ValueError(f"density_per_m2 must be > 0, got {self.density_per_m2}")
        if not self.depth_m > 0:
            raise ValueError(f"depth_m must be > 0 metres, got {self.depth_m}")
        if not -1.0 <= self.normal_dot < 1.0:
            raise ValueError(f"normal_dot must be in [-1, 1), got {self.normal_dot}")
        if not self.extra_min_area_ratio >= 0.0:
            raise ValueError(f"extra_min_area_ratio must be >= 0, got {self.extra_min_area_ratio}")
        if not self.extra_offset_factor > 0:
            raise ValueError(f"extra_offset_factor must be > 0, got {self.extra_offset_factor}")
        if not self.hpr_radius_factor > 1:
            raise ValueError(f"hpr_radius_factor must be > 1, got {self.hpr_radius_factor}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class TipMesh:
    """A fingertip mesh in its tip body frame: vertices (V,3) metres, faces (F,3) indices."""

    vertices: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True)
class FingertipFaces:
    """The contact faces of one fingertip, in its tip body frame (metres).

    Attributes:
        cloud_points, cloud_normals: (N,3) the whole Poisson-disk cloud and outward normals.
        pulp_points, pulp_normals: (M,3) the part visible from the pulp-side viewpoint
            (``cloud_f`` of the paper): the candidates for face centres.
        faces: the main face first, then the kept extra faces (upper, left, right order).
        query: (3,) the query point the main face was grown around, or ``None`` (cloud centroid).
    """

    cloud_points: np.ndarray
    cloud_normals: np.ndarray
    pulp_points: np.ndarray
    pulp_normals: np.ndarray
    faces: tuple[ContactFace, ...]
    query: np.ndarray | None = field(default=None)

    @property
    def centres(self) -> np.ndarray:
        """(F,3) face centres, metres."""
        return np.stack([f.centre for f in self.faces])

    @property
    def normals(self) -> np.ndarray:
        """(F,3) unit face normals (out of the fingertip)."""
        return np.stack([f.normal for f in self.faces])


# ---------------------------------------------------------------------------------------------
# caches


class _LRU:
    """A tiny in-memory LRU cache; values are treated as immutable by their users."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.items: OrderedDict[bytes, Any] = OrderedDict()

    def get(self, key: bytes) -> Any:
        value = self.items.get(key)
        if value is not None:
            self.items.move_to_end(key)
        return value

    def put(self, key: bytes, value: Any) -> None:
        self.items[key] = value
        self.items.move_to_end(key)
        while len(self.items) > self.size:
            self.items.popitem(last=False)


_CLOUDS = _LRU(_CACHE_SIZE)
_FACES = _LRU(_CACHE_SIZE)


def clear_caches() -> None:
    """Forget the in-memory fingertip clouds and faces (benchmarks time cold builds with it)."""
    _CLOUDS.items.clear()
    _FACES.items.clear()


def _digest(*parts: Any) -> bytes:
    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, np.ndarray):
            h.update(str(part.dtype).encode())
            h.update(str(part.shape).encode())
            h.update(np.ascontiguousarray(part).tobytes())
        else:
            h.update(repr(part).encode())
        h.update(b"\x00")
    return h.digest()


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


# ---------------------------------------------------------------------------------------------
# meshes and clouds


def tip_mesh(hand: Hand, finger: str) -> TipMesh:
    """The fingertip mesh of ``finger`` in its tip body frame (metres).

    The mesh's pose in the body comes from the geom that uses it on the tip body (MuJoCo stores
    ``mesh_vert`` re-centred on the mesh's own frame); a collision geom is preferred when the
    visual and collision geoms differ.

    Raises:
        ConfigError: no geom of the tip body uses the configured ``tip_mesh``.
    """
    m = hand.model
    cfg = hand.config.finger(finger)
    mesh_id = m.mesh(cfg.tip_mesh).id
    body_id = m.body(cfg.tip_body).id
    geoms = [g for g in range(m.ngeom)
             if m.geom_bodyid[g] == body_id and m.geom_dataid[g] == mesh_id
             and int(m.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_MESH)]
    if not geoms:
        raise ConfigError(f"{hand.config.file}: fingers '{finger}'.tip_mesh: no geom of body "
                          f"{cfg.tip_body!r} uses mesh {cfg.tip_mesh!r}")
    colliding = [g for g in geoms if m.geom_contype[g] or m.geom_conaffinity[g]]
    g = (colliding or geoms)[0]
    va, nv = m.mesh_vertadr[mesh_id], m.mesh_vertnum[mesh_id]
    fa, nf = m.mesh_faceadr[mesh_id], m.mesh_facenum[mesh_id]
    verts = m.mesh_vert[va:va + nv].astype(float)
    faces = m.mesh_face[fa:fa + nf].astype(np.int64)
    verts_body = m.geom_pos[g] + verts @ quat_to_mat(m.geom_quat[g]).T
    return TipMesh(vertices=_frozen(verts_body), faces=faces)


def fingertip_cloud(vertices: ArrayLike, faces: ArrayLike, *, density_per_m2: float,
                    seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Poisson-disk ``(points (N,3), outward normals (N,3))`` on a fingertip mesh, cached in
    memory by mesh content, density and seed (arrays are read-only)."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    key = _digest("cloud", v, f, float(density_per_m2), int(seed))
    hit = _CLOUDS.get(key)
    if hit is not None:
        return hit
    points, normals = poisson_disk_sample(v, f, density_per_m2=density_per_m2, seed=seed)
    value = (_frozen(points), _frozen(normals))
    _CLOUDS.put(key, value)
    return value


def _main_face(pulp_p: np.ndarray, pulp_n: np.ndarray, query: np.ndarray | None,
               p: FingertipParams, u_dir: np.ndarray) -> ContactFace:
    """The main contact face at ``query``; a demo contact at the rim of the pulp (a wrap grasp
    often touches with the side of the tip) has too few neighbours for a face, so the query is
    then walked toward the pulp centroid until a face forms, with a warning."""
    def grow(q: np.ndarray | None) -> ContactFace:
        return contact_face(pulp_p, pulp_n, q, depth_m=p.depth_m, normal_dot=p.normal_dot,
                            shape=p.shape, v_u=u_dir, centre=p.centre)

    try:
        return grow(query)
    except ContactFaceError:
        if query is None:
            raise
        centroid = pulp_p.mean(axis=0)
        for t in (0.25, 0.5, 0.75, 1.0):
            try:
                face = grow((1.0 - t) * query + t * centroid)
            except ContactFaceError:
                continue
            log.warning("demo contact %s is at the rim of the fingertip pulp; contact face "
                        "grown %.0f%% of the way to the pulp centroid", query.round(4).tolist(),
                        100 * t)
            return face
        raise


def fingertip_faces(vertices: ArrayLike, faces: ArrayLike, v_f: ArrayLike, v_u: ArrayLike, *,
                    query: ArrayLike | None = None,
                    params: FingertipParams | None = None) -> FingertipFaces:
    """Contact faces of a fingertip mesh given in its tip frame (see the module docstring).

    Args:
        vertices, faces: the fingertip mesh, metres, tip body frame.
        v_f: direction toward the pulp (contact side), tip frame; v_u: along the finger.
        query: (3,) query point in the tip frame (a demo's contact centroid on this fingertip);
            ``None`` grows the main face at the centroid of the visible cloud.
        params: cloud and face parameters (defaults: :class:`FingertipParams`).

    Raises:
        ContactFaceError: nothing of the mesh is visible from the pulp side, or the main face
            cannot be built (too sparse, degenerate).
        ValueError: v_f parallel to v_u, zero or non-finite directions, bad mesh or query.
    """
    p = params or FingertipParams()
    f_dir = np.asarray(v_f, dtype=float)
    u_dir = np.asarray(v_u, dtype=float)
    for name, d in (("v_f", f_dir), ("v_u", u_dir)):
        if d.shape != (3,) or not np.isfinite(d).all() or np.linalg.norm(d) < 1e-12:
            raise ValueError(f"{name} must be a finite non-zero 3-vector, got {d!r}")
    f_dir, u_dir = f_dir / np.linalg.norm(f_dir), u_dir / np.linalg.norm(u_dir)
    if np.linalg.norm(np.cross(f_dir, u_dir)) < 1e-6:
        raise ValueError(f"v_f {f_dir.round(6).tolist()} and v_u {u_dir.round(6).tolist()} are "
                         "parallel: v_f must point to the pulp and v_u along the finger")
    q = None
    if query is not None:
        q = np.asarray(query, dtype=float)
        if q.shape != (3,) or not np.isfinite(q).all():
            raise ValueError(f"query must be a finite 3-vector in the tip frame, got {q!r}")
    points, normals = fingertip_cloud(vertices, faces, density_per_m2=p.density_per_m2,
                                      seed=p.seed)
    key = _digest("faces", points, f_dir, u_dir, q, sorted(p.to_dict().items()))
    hit = _FACES.get(key)
    if hit is not None:
        return hit
    pulp_p, pulp_n = visible_pulp_cloud(points, normals, f_dir, u_dir,
                                        radius_factor=p.hpr_radius_factor)
    main = _main_face(pulp_p, pulp_n, q, p, u_dir)
    extras: list[ContactFace] = []
    if p.extra_faces:
        extras = extra_faces(pulp_p, pulp_n, main, f_dir, u_dir, depth_m=p.depth_m,
                             normal_dot=p.normal_dot, shape=p.shape, centre=p.centre,
                             offset_factor=p.extra_offset_factor,
                             min_area_ratio=p.extra_min_area_ratio)
    result = FingertipFaces(cloud_points=points, cloud_normals=normals,
                            pulp_points=_frozen(pulp_p), pulp_normals=_frozen(pulp_n),
                            faces=(main, *extras), query=None if q is None else _frozen(q))
    log.debug("fingertip faces: %d cloud points, %d visible, %d faces (main area %.1f mm²)",
              len(points), len(pulp_p), len(result.faces), main.area * 1e6)
    _FACES.put(key, result)
    return result


def hand_fingertip_faces(hand: Hand, finger: str, query: ArrayLike | None = None,
                         params: FingertipParams | None = None) -> FingertipFaces:
    """:func:`fingertip_faces` for a finger of a hand (its tip mesh, ``v_f`` and ``v_u``).

    Raises:
        ContactFaceError, ValueError: as :func:`fingertip_faces`, with the hand and finger named.
    """
    cfg = hand.config.finger(finger)
    mesh = tip_mesh(hand, finger)
    try:
        return fingertip_faces(mesh.vertices, mesh.faces, cfg.v_f, cfg.v_u, query=query,
                               params=params)
    except ContactFaceError as exc:
        raise ContactFaceError(f"hand {hand.name!r}, finger {finger!r} (mesh {cfg.tip_mesh!r}): "
                               f"{exc}") from exc
    except ValueError as exc:
        raise ValueError(f"hand {hand.name!r}, finger {finger!r}: {exc}") from exc
