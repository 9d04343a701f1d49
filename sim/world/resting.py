"""Stable resting poses of an object on a table, found physically: drop it, let it settle, cluster.

Why physics rather than geometry alone: which faces an object really comes to rest on, and how
often, depends on its mass distribution, its collision hull and MuJoCo's contacts — the same
simulation the teleop bridge places it in. Half the real grasps start from an object on its
side, so the bridge must offer every pose the object can really lie in, not only upright.

Method (:func:`resting_poses`): the object (its collision geoms, the scene's
:class:`~sim.world.object_spec.ContactParams` and :class:`~sim.world.scene.PhysicsOptions`) is
dropped onto a plane from the six axis-aligned orientations (so the box faces and the upright
pose are always tried) and from ``drops`` orientations drawn uniformly (a seeded generator),
its lowest point ``drop_height_m`` above the plane; each drop runs until the object's fastest
point (linear speed plus angular speed times its bounding radius) stayed below
``settle_speed_mps`` for ``settle_still_s``, or ``settle_timeout_s`` (drops that never settle
are left out). A settled orientation is known up to a yaw about the table normal by the
direction, in the object frame, that points down into the table (``down``). Settled ``down``
directions closer than ``cluster_deg`` are one pose; for an object with a continuous symmetry
axis (a can, a bottle: its collision hull rotated about a principal axis by arbitrary angles
stays within ``symmetry_tol`` of its size) only the angle between ``down`` and that axis
counts, so a can lying on its side is one pose whichever way it rolled. Each cluster is
represented by its medoid (a real settled state) and re-dropped from that orientation: a pose
that does not stay within ``stable_deg`` is dropped as unstable. Poses are ranked by ``share``
(the fraction of the random drops that reached them), then by the height of the centre of mass
(lower first).

A pose's orientation (:attr:`RestPose.quat_wxyz`) is the shortest rotation taking ``down`` onto
the world's −z; :meth:`RestPose.quat_at_yaw` adds a yaw about the table normal. For an object
whose frame is upright (z up, as YCB meshes are) the upright pose is the identity.

Results are deterministic for a seed and cached as JSON in ``sim.paths.cache_dir()/resting``,
keyed by a SHA-256 of the compiled object (geoms, meshes, inertia), the parameters, the
physics and contact settings and :data:`FORMAT_VERSION`. Units: metres, seconds, degrees.
The search itself (drop world, symmetry test, clustering) is :mod:`sim.world.rest_drop`.

Limits: a nearly round object (an apple) comes to rest in many slightly different ways, and
each is offered; drops still moving after ``settle_timeout_s`` (a bottle rocking on its
shoulder) are left out of the shares.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import math
import os
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import mujoco
import numpy as np
import trimesh

from sim.paths import cache_dir
from sim.world.object_spec import ContactParams
from sim.world.objects import ObjectAsset
from sim.world.rest_drop import (
    DOWN,
    DropWorld,
    RestParams,
    clusters,
    drop_starts,
    pose_angle_deg,
    rot_mat,
    shortest_arc,
    symmetry_axis,
)
from sim.world.scene import PhysicsOptions

__all__ = ["FORMAT_VERSION", "RestParams", "RestPose", "RestPoses", "rest_placement",
           "resting_poses"]

logger = logging.getLogger(__name__)
Array = np.ndarray
Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


def _vec3(v: Iterable[Any]) -> Vec3:
    """``v``'s entries as a tuple of floats (three, as the caller's data has them)."""
    return cast(Vec3, tuple(map(float, v)))


def _quat(v: Iterable[Any]) -> Quat:
    """``v``'s entries as a tuple of floats (four, as the caller's data has them)."""
    return cast(Quat, tuple(map(float, v)))

FORMAT_VERSION = 1


@dataclass(frozen=True)
class RestPose:
    """One stable way the object lies on the table, up to a yaw (module docstring).

    ``down``: unit vector in the object frame pointing into the table; ``quat_wxyz``: the
    object's orientation at yaw 0; ``com_height_m``: its centre of mass above the table top;
    ``share``: fraction of the random drops that settled here; ``upright``: the object's z axis
    points up within ``stable_deg``; ``drift_deg``: how far the re-drop moved it."""

    down: tuple[float, float, float]
    quat_wxyz: tuple[float, float, float, float]
    com_height_m: float
    share: float
    upright: bool
    drift_deg: float

    def quat_at_yaw(self, yaw_deg: float) -> Array:
        """The orientation (wxyz) turned by ``yaw_deg`` about the world z axis."""
        half = math.radians(yaw_deg) / 2
        out = np.empty(4)
        mujoco.mju_mulQuat(out, np.array([math.cos(half), 0.0, 0.0, math.sin(half)]),
                           np.asarray(self.quat_wxyz, float))
        return out

    def to_json(self) -> dict[str, Any]:
        return {"down": [round(v, 6) for v in self.down],
                "quat_wxyz": [round(v, 6) for v in self.quat_wxyz],
                "com_height_m": round(self.com_height_m, 6), "share": round(self.share, 6),
                "upright": self.upright, "drift_deg": round(self.drift_deg, 3)}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RestPose:
        return cls(down=_vec3(d["down"]), quat_wxyz=_quat(d["quat_wxyz"]),
                   com_height_m=float(d["com_height_m"]), share=float(d["share"]),
                   upright=bool(d["upright"]), drift_deg=float(d["drift_deg"]))


@dataclass(frozen=True)
class RestPoses:
    """An object's resting poses, best first, and how they were found (``seconds``: the wall
    time of the computation, ``cached``: read from the cache)."""

    object_name: str
    poses: tuple[RestPose, ...]
    drops: int
    settled: int
    symmetry_axis: tuple[float, float, float] | None
    seconds: float
    cached: bool
    key: str

    def __len__(self) -> int:
        return len(self.poses)

    def __getitem__(self, index: int) -> RestPose:
        return self.poses[index]

    def check_index(self, index: Any, where: str) -> int:
        """``index`` if it is an int naming one of the poses; ValueError naming ``where``."""
        if isinstance(index, bool) or not isinstance(index, int | np.integer) or \
                not 0 <= int(index) < len(self.poses):
            raise ValueError(f"{where}: expected a resting pose index 0..{len(self.poses) - 1} of "
                             f"{self.object_name} ({len(self.poses)} poses), got {index!r}")
        return int(index)

    def upright_index(self) -> int | None:
        """The index of the upright pose, None when the object cannot stand upright."""
        return next((i for i, p in enumerate(self.poses) if p.upright), None)


def _compute(obj: ObjectAsset, p: RestParams, physics: PhysicsOptions,
             contact: ContactParams) -> tuple[list[RestPose], int, int, Array | None]:
    world = DropWorld(obj, physics, contact)
    hull = trimesh.convex.convex_hull(world.verts)
    axis = symmetry_axis(hull, p.symmetry_tol)
    starts, first_random = drop_starts(p)
    downs, randoms = [], []
    for k, quat in enumerate(starts):
        q, settled = world.drop(quat, p)
        if settled:
            downs.append(rot_mat(q).T @ DOWN)
            randoms.append(k >= first_random)
    if not downs:
        raise RuntimeError(f"{obj.name}: none of {len(starts)} drops came to rest within "
                           f"{p.settle_timeout_s} s (simulated)")
    poses = []
    for members in clusters(downs, axis, p.cluster_deg):
        medoid = min(members, key=lambda i: (sum(pose_angle_deg(downs[i], downs[j], axis)
                                                 for j in members), i))
        down = downs[medoid]
        quat = shortest_arc(down, DOWN)
        q_after, settled = world.drop(quat, p)
        drift = pose_angle_deg(rot_mat(q_after).T @ DOWN, down, axis)
        if not settled or drift > p.stable_deg:
            logger.debug("%s: pose down=%s is not stable (drift %.1f deg)", obj.name,
                         np.round(down, 3), drift)
            continue
        up = rot_mat(quat)[:, 2]
        poses.append(RestPose(down=_vec3(down), quat_wxyz=_quat(quat),
                              com_height_m=world.com_height_m(quat),
                              share=sum(randoms[i] for i in members) / max(p.drops, 1),
                              upright=bool(up[2] >= math.cos(math.radians(p.stable_deg))),
                              drift_deg=drift))
    poses.sort(key=lambda r: (-r.share, r.com_height_m))
    return poses, len(starts), len(downs), axis


# --------------------------------------------------------------------------------------- cache


def _hash_array(h: Any, a: Array) -> None:
    a = np.ascontiguousarray(a)
    h.update(f"{a.dtype}{a.shape}".encode())
    h.update(a.tobytes())


def _key(obj: ObjectAsset, p: RestParams, physics: PhysicsOptions, contact: ContactParams) -> str:
    """Cache key: the compiled object's collision and inertia arrays, and every setting."""
    m = obj.model
    h = hashlib.sha256()
    h.update(f"dexaug-resting-v{FORMAT_VERSION}".encode())
    for name in ("geom_type", "geom_size", "geom_pos", "geom_quat", "geom_contype",
                 "geom_conaffinity", "geom_dataid", "mesh_vert", "mesh_face", "body_mass",
                 "body_ipos", "body_iquat", "body_inertia"):
        _hash_array(h, getattr(m, name))
    settings = {"params": dataclasses.asdict(p), "physics": dataclasses.asdict(physics),
                "contact": dataclasses.asdict(contact)}
    h.update(json.dumps(settings, sort_keys=True, default=str).encode())
    return h.hexdigest()


def _cache_file(name: str, key: str) -> Path:
    safe = "".join(c if c.isalnum() or c in "_-" else "_" for c in name)[:80]
    return cache_dir() / "resting" / f"{safe}-{key[:24]}.json"


def _read_cache(path: Path, key: str) -> dict[str, Any] | None:
    try:
        doc = json.loads(path.read_text())
        if doc.get("key") == key and doc.get("format_version") == FORMAT_VERSION:
            return doc
        logger.warning("%s: a stale resting-pose cache (key or format differs): recomputed", path)
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        logger.warning("%s: unreadable resting-pose cache (%s): recomputed", path, exc)
    return None


def _write_cache(path: Path, doc: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, path)


def resting_poses(obj: ObjectAsset, params: RestParams | None = None, *,
                  physics: PhysicsOptions | None = None, contact: ContactParams | None = None,
                  use_cache: bool = True) -> RestPoses:
    """The stable resting poses of ``obj``, best first (module docstring); read from the cache
    when computed before with the same object and settings. RuntimeError when no drop settles."""
    p, physics, contact = params or RestParams(), physics or PhysicsOptions(), contact or ContactParams()
    t0 = time.perf_counter()
    key = _key(obj, p, physics, contact)
    path = _cache_file(obj.name, key)
    doc = _read_cache(path, key) if use_cache else None
    cached = doc is not None
    if doc is None:
        poses, drops, settled, axis = _compute(obj, p, physics, contact)
        doc = {"format_version": FORMAT_VERSION, "key": key, "object": obj.name, "drops": drops,
               "settled": settled, "symmetry_axis": None if axis is None else axis.tolist(),
               "seconds": round(time.perf_counter() - t0, 3),
               "poses": [r.to_json() for r in poses]}
        if use_cache:
            try:
                _write_cache(path, doc)
            except OSError as exc:
                logger.warning("%s: resting poses not cached: %s", path, exc)
        logger.info("%s: %d resting poses from %d drops (%d settled) in %.2f s", obj.name,
                    len(poses), drops, settled, time.perf_counter() - t0)
    axis_doc = doc["symmetry_axis"]
    return RestPoses(object_name=obj.name,
                     poses=tuple(RestPose.from_json(r) for r in doc["poses"]),
                     drops=int(doc["drops"]), settled=int(doc["settled"]),
                     symmetry_axis=None if axis_doc is None else _vec3(axis_doc),
                     seconds=time.perf_counter() - t0, cached=cached, key=key)


def rest_placement(obj: ObjectAsset, pose: RestPose, xy_m: Array, yaw_deg: float, *,
                   top_z_m: float = 0.0, clearance_m: float = 1e-3) -> tuple[Array, Array]:
    """Where to put ``obj`` to lie in ``pose`` turned by ``yaw_deg`` at ``xy_m`` (world x, y):
    its origin's world position, its lowest collision point ``clearance_m`` above ``top_z_m``,
    and its orientation (wxyz)."""
    quat = pose.quat_at_yaw(yaw_deg)
    low = float((obj.collision_mesh().vertices @ rot_mat(quat).T)[:, 2].min())
    return np.array([float(xy_m[0]), float(xy_m[1]), top_z_m - low + clearance_m]), quat
