"""Object clouds for FSG (paper section 4.1; DESIGN §4).

FSG never touches the object mesh: it works on ``cloud_full``, ``n_points`` (1024) Poisson-disk
samples of the visual surface with outward face normals (object frame, metres), and on
``cloud_part``, the subset where a fingertip may be placed. The part comes from an affordance
annotation when one exists (``configs/affordance/<object>.npy`` or ``.txt``: indices into
``cloud_full`` as sampled with the same ``n_points`` and ``seed``), else from a curvature filter.

Curvature measure (documented because the paper only cites "curvature" and the authors' code
uses a threshold of 0.7): for every point, the *normal variation* is

    c_i = 1 − min_j ⟨n_i, n_j⟩   over the ``CURVATURE_NEIGHBOURS`` (10) nearest neighbours j
                                 with ⟨n_i, n_j⟩ ≥ −0.5,

i.e. 0 on a plane, ≈ 1 − cos(spacing / radius) on a smooth curve, and ≥ 1 next to a 90° edge.
Points with ``c_i > curvature_threshold`` are excluded, so 0.7 (neighbours whose normals differ
by more than ~72.5°) removes the points next to sharp edges and corners and keeps smooth faces,
cylinders and rounded edges at the 1024-point resolution. Neighbours facing the other way
(⟨n_i, n_j⟩ < −0.5) are ignored: at 1024 points the nearest neighbours of a point on a thin wall
(a bowl, a can's rolled rim, the inner and outer skins of a scanned mesh) include points of the
opposite skin, which would otherwise mark every point of the wall as an edge.

Clouds are cached in ``sim.paths.cache_dir()/object_clouds`` as ``.npz`` written atomically,
keyed by a SHA-256 of the mesh arrays, the parameters and the affordance file's bytes.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from augment.geometry.sampling import poisson_disk_sample
from sim.errors import DexaugError
from sim.io import atomic_path
from sim.paths import CONFIG_DIR, cache_dir
from sim.world.objects import ObjectAsset

__all__ = ["AFFORDANCE_DIR", "ObjectCloud", "ObjectCloudError", "affordance_path",
           "normal_variation", "object_cloud"]

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
AFFORDANCE_DIR = CONFIG_DIR / "affordance"
#: Neighbours of the normal-variation measure (the point itself excluded).
CURVATURE_NEIGHBOURS = 10
#: Neighbours whose normals are below this dot product lie on the opposite skin of a thin wall.
OPPOSITE_SKIN_DOT = -0.5


class ObjectCloudError(DexaugError, ValueError):
    """An object cloud cannot be built: no graspable part left, or a bad affordance file."""


@dataclass(frozen=True, eq=False)
class ObjectCloud:
    """Object cloud of one object (object frame, metres).

    Attributes:
        name: object name.
        points: (N,3) ``cloud_full`` positions.
        normals: (N,3) outward unit normals.
        part_mask: (N,) bool, True for ``cloud_part`` (the graspable part).
        curvature: (N,) normal variation (see the module docstring).
        source: ``"affordance"`` or ``"curvature"`` (how the part was chosen).
        com_m: (3,) centre of mass; max_radius_m: largest surface distance from it (GWS torque
            scale); z_min_m: lowest surface point (the table plane in table mode).
        key: cache key.
    """

    name: str
    points: np.ndarray
    normals: np.ndarray
    part_mask: np.ndarray
    curvature: np.ndarray
    source: str
    com_m: np.ndarray
    max_radius_m: float
    z_min_m: float
    key: str

    @property
    def part_indices(self) -> np.ndarray:
        return np.flatnonzero(self.part_mask)

    @property
    def part_points(self) -> np.ndarray:
        return self.points[self.part_mask]

    @property
    def part_normals(self) -> np.ndarray:
        return self.normals[self.part_mask]


def normal_variation(points: np.ndarray, normals: np.ndarray,
                     k: int = CURVATURE_NEIGHBOURS) -> np.ndarray:
    """``1 − min_j n_i·n_j`` over the ``k`` nearest neighbours of each point (module docstring)."""
    k = min(k, len(points) - 1)
    if k < 1:
        return np.zeros(len(points))
    _, idx = cKDTree(points).query(points, k=k + 1)
    dots = np.einsum("ij,ikj->ik", normals, normals[idx[:, 1:]])
    dots = np.where(dots < OPPOSITE_SKIN_DOT, np.inf, dots)
    lowest = dots.min(axis=1)
    return 1.0 - np.where(np.isfinite(lowest), lowest, 1.0)


def affordance_path(name: str) -> Path | None:
    """The affordance annotation of object ``name`` (``.npy`` preferred, then ``.txt``)."""
    for ext in (".npy", ".txt"):
        p = AFFORDANCE_DIR / f"{name}{ext}"
        if p.is_file():
            return p
    return None


def _read_affordance(path: Path, n_points: int) -> np.ndarray:
    try:
        idx = np.load(path) if path.suffix == ".npy" else np.loadtxt(path, dtype=np.int64, ndmin=1)
    except (OSError, ValueError) as exc:
        raise ObjectCloudError(f"{path}: unreadable affordance annotation ({exc})") from None
    idx = np.asarray(idx).ravel()
    if not np.issubdtype(idx.dtype, np.integer) or idx.size == 0:
        raise ObjectCloudError(f"{path}: expected a non-empty list of integer point indices")
    if idx.min() < 0 or idx.max() >= n_points:
        raise ObjectCloudError(f"{path}: point indices must lie in [0, {n_points}) "
                               f"(the cloud has {n_points} points)")
    mask = np.zeros(n_points, dtype=bool)
    mask[idx] = True
    return mask


def object_cloud(obj: ObjectAsset, n_points: int = 1024, seed: int = 0,
                 curvature_threshold: float = 0.7, affordance: bool | Path | None = None, *,
                 cache: bool = True) -> ObjectCloud:
    """``cloud_full`` and ``cloud_part`` of ``obj`` (see the module docstring).

    Args:
        obj: the object.
        n_points: Poisson-disk samples (paper: 1024).
        seed: sampler seed.
        curvature_threshold: points with a larger normal variation leave ``cloud_part``.
        affordance: ``None`` uses ``configs/affordance/<name>.*`` when present, ``True``
            requires it, ``False`` ignores it, a path names the file.
        cache: read/write the disk cache.

    Raises:
        ObjectCloudError: no point is left in ``cloud_part`` (the message names the object and
            the threshold), a required annotation is missing, or it is malformed.
    """
    if n_points < 4:
        raise ObjectCloudError(f"n_points must be >= 4, got {n_points}")
    if isinstance(affordance, Path):
        aff = affordance
    elif affordance is False:
        aff = None
    else:
        aff = affordance_path(obj.name)
        if affordance is True and aff is None:
            raise ObjectCloudError(f"object {obj.name!r}: no affordance annotation in "
                                   f"{AFFORDANCE_DIR} (<name>.npy or <name>.txt)")
    mesh = obj.surface_mesh()
    v = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    h = hashlib.sha256()
    h.update(v.tobytes())
    h.update(f.tobytes())
    h.update(json.dumps({"format": FORMAT_VERSION, "n": n_points, "seed": seed,
                         "thr": curvature_threshold, "k": CURVATURE_NEIGHBOURS}).encode())
    if aff is not None:
        h.update(aff.read_bytes())
    key = h.hexdigest()[:24]
    path = cache_dir() / "object_clouds" / f"{obj.name}-{key}.npz"
    arrays: dict[str, np.ndarray] | None = None
    if cache and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in ("points", "normals", "curvature")}
        except (OSError, ValueError, KeyError) as exc:
            log.warning("ignoring a damaged object cloud cache file %s: %s", path, exc)
    if arrays is None:
        pts, nrm = poisson_disk_sample(v, f, n_points=n_points, seed=seed)
        arrays = {"points": pts, "normals": nrm, "curvature": normal_variation(pts, nrm)}
        if cache:
            buf = io.BytesIO()
            np.savez(buf, **arrays)  # type: ignore[arg-type]  # numpy stubs type **kwds as allow_pickle's bool
            with atomic_path(path) as tmp:
                tmp.write_bytes(buf.getbuffer())
    pts, nrm, curv = arrays["points"], arrays["normals"], arrays["curvature"]
    if aff is not None:
        mask = _read_affordance(aff, len(pts))
        source = "affordance"
    else:
        mask = curv <= curvature_threshold
        source = "curvature"
    if not mask.any():
        raise ObjectCloudError(
            f"object {obj.name!r}: no graspable part left ({source} filter"
            + (f", curvature_threshold {curvature_threshold}: every point's normal variation "
               f"exceeds it; raise the threshold" if source == "curvature" else f", {aff}")
            + ")")
    com = np.asarray(obj.com_m, dtype=float)
    for a in (pts, nrm, mask, curv, com):
        a.flags.writeable = False
    log.info("object cloud of %s: %d points, %d graspable (%s)", obj.name, len(pts),
             int(mask.sum()), source)
    return ObjectCloud(name=obj.name, points=pts, normals=nrm, part_mask=mask, curvature=curv,
                       source=source, com_m=com, max_radius_m=float(obj.max_radius_m),
                       z_min_m=float(v[:, 2].min()), key=key)
