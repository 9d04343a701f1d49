"""The simulation and geometry behind :mod:`sim.world.resting`: drop an object onto a plane,
tell settled orientations apart up to a yaw, cluster them.

Why apart: the search (a drop world, the start orientations, the symmetry test and the
clustering, described in :mod:`sim.world.resting`) is one job; naming, ranking and caching its
result is another. Units: metres, seconds, degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh

from sim.world.object_spec import ContactParams
from sim.world.objects import ObjectAsset
from sim.world.scene import PhysicsOptions

__all__ = ["DOWN", "DropWorld", "RestParams", "clusters", "drop_starts", "pose_angle_deg",
           "rot_mat", "shortest_arc", "symmetry_axis"]

Array = np.ndarray
DOWN = np.array([0.0, 0.0, -1.0])
#: yaw-free angles (degrees) at which a hull rotated about an axis is compared with itself:
#: no multiple of 90, 120 or 180 (a box's or a prism's discrete symmetries)
_SYMMETRY_ANGLES_DEG = (37.0, 101.0, 223.0)


@dataclass(frozen=True)
class RestParams:
    """How resting poses are searched (:mod:`sim.world.resting`); every field is part of the
    cache key."""

    drops: int = 48
    seed: int = 0
    drop_height_m: float = 0.01
    settle_speed_mps: float = 0.005
    settle_still_s: float = 0.3
    settle_timeout_s: float = 4.0
    cluster_deg: float = 12.0
    stable_deg: float = 5.0
    #: a continuous symmetry: rotated hull points within this fraction of the hull's size
    symmetry_tol: float = 0.03

    def __post_init__(self) -> None:
        if self.drops < 0:
            raise ValueError(f"RestParams.drops: expected >= 0, got {self.drops}")
        for name in ("drop_height_m", "settle_speed_mps", "settle_timeout_s", "cluster_deg",
                     "stable_deg", "symmetry_tol"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"RestParams.{name}: expected a finite number > 0, got {value}")


def shortest_arc(a: Array, b: Array) -> Array:
    """The shortest rotation (wxyz) taking unit vector ``a`` onto unit vector ``b`` (about x when
    they are opposite and the axis is free)."""
    c = float(np.dot(a, b))
    axis = np.cross(a, b)
    if np.linalg.norm(axis) < 1e-9:
        if c > 0:
            return np.array([1.0, 0.0, 0.0, 0.0])
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.array([0.0, *axis])
    q = np.array([1.0 + c, *axis])
    return q / np.linalg.norm(q)


def rot_mat(quat: Array) -> Array:
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(quat, float))
    return mat.reshape(3, 3)


def symmetry_axis(hull: trimesh.Trimesh, tol: float) -> Array | None:
    """A principal axis of ``hull`` about which it is continuously symmetric (module docstring),
    through its centroid; None when there is none."""
    pts = hull.vertices - hull.centroid
    size = float(np.linalg.norm(pts, axis=1).max())
    samples = trimesh.sample.sample_surface_even(hull, 400, seed=0)[0] - hull.centroid
    _, vecs = np.linalg.eigh(np.cov(pts.T))
    for axis in vecs.T:
        worst = 0.0
        for deg in _SYMMETRY_ANGLES_DEG:
            half = math.radians(deg) / 2
            r = rot_mat(np.array([math.cos(half), *(math.sin(half) * axis)]))
            _, dist, _ = trimesh.proximity.closest_point_naive(hull, samples @ r.T + hull.centroid)
            worst = max(worst, float(dist.max()))
        if worst <= tol * size:
            return axis / np.linalg.norm(axis)
    return None


def pose_angle_deg(a: Array, b: Array, axis: Array | None) -> float:
    """How far apart two ``down`` directions are as resting poses (module docstring)."""
    if axis is None:
        return math.degrees(math.acos(float(np.clip(np.dot(a, b), -1.0, 1.0))))
    ea = math.acos(float(np.clip(np.dot(a, axis), -1.0, 1.0)))
    eb = math.acos(float(np.clip(np.dot(b, axis), -1.0, 1.0)))
    return math.degrees(abs(ea - eb))


def _set_options(spec: mujoco.MjSpec, physics: PhysicsOptions) -> None:
    """The solver settings of ``physics`` that a free object on a plane depends on (those a
    :class:`sim.world.scene.Scene` sets, less the sparse Jacobian, which changes no result)."""
    o = spec.option
    o.timestep = physics.timestep_s
    o.integrator = {"euler": mujoco.mjtIntegrator.mjINT_EULER,
                    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
                    "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                    "rk4": mujoco.mjtIntegrator.mjINT_RK4}[physics.integrator]
    o.cone = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC,
              "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}[physics.cone]
    o.impratio = physics.impratio
    o.noslip_iterations = physics.noslip_iterations
    o.iterations = physics.solver_iterations


class DropWorld:
    """The object alone above a plane (z = 0), for dropping it."""

    def __init__(self, obj: ObjectAsset, physics: PhysicsOptions, contact: ContactParams) -> None:
        spec = mujoco.MjSpec()
        _set_options(spec, physics)
        spec.worldbody.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1],
                                friction=list(contact.friction), solref=list(contact.solref))
        spec.attach(obj.spec(contact), prefix="obj/", frame=spec.worldbody.add_frame())
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.qadr = m.joint("obj/object_free").qposadr[0]
        self.dadr = m.joint("obj/object_free").dofadr[0]
        body = m.body("obj/object").id
        self.com = m.body_ipos[body].copy()
        self.verts = obj.collision_mesh().vertices
        self.radius = float(np.linalg.norm(self.verts, axis=1).max())

    def drop(self, quat: Array, p: RestParams) -> tuple[Array, bool]:
        """Drop the object from orientation ``quat``; its final orientation and whether it
        settled."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        quat = np.asarray(quat, float) / np.linalg.norm(quat)
        z = -float((self.verts @ rot_mat(quat).T)[:, 2].min()) + p.drop_height_m
        d.qpos[self.qadr:self.qadr + 3] = [0.0, 0.0, z]
        d.qpos[self.qadr + 3:self.qadr + 7] = quat
        dt = float(m.opt.timestep)
        still_steps = max(1, math.ceil(p.settle_still_s / dt))
        max_steps = math.ceil(p.settle_timeout_s / dt)
        a, still = self.dadr, 0
        for _ in range(max_steps):
            mujoco.mj_step(m, d)
            v = d.qvel
            speed = math.sqrt(v[a] ** 2 + v[a + 1] ** 2 + v[a + 2] ** 2) + self.radius * \
                math.sqrt(v[a + 3] ** 2 + v[a + 4] ** 2 + v[a + 5] ** 2)
            still = still + 1 if speed < p.settle_speed_mps else 0
            if still >= still_steps:
                break
        q = d.qpos[self.qadr + 3:self.qadr + 7].copy()
        return q / np.linalg.norm(q), still >= still_steps

    def com_height_m(self, quat: Array) -> float:
        """The centre of mass above the plane with the object resting in ``quat``."""
        r = rot_mat(quat)
        return float((r @ self.com)[2] - (self.verts @ r.T)[:, 2].min())


def drop_starts(p: RestParams) -> tuple[list[Array], int]:
    """The drop orientations: six axis-aligned (each face down), then ``drops`` uniform
    random ones; and the index the random ones start at."""
    axis_aligned = [shortest_arc(v, DOWN) for v in np.vstack([np.eye(3), -np.eye(3)])]
    rng = np.random.default_rng(p.seed)
    random = [q / np.linalg.norm(q) for q in rng.normal(size=(p.drops, 4))]
    return axis_aligned + random, len(axis_aligned)


def clusters(downs: list[Array], axis: Array | None, tol_deg: float) -> list[list[int]]:
    """Single-linkage clusters (index lists, in order of first member) of ``downs``."""
    n = len(downs)
    label = list(range(n))

    def root(i: int) -> int:
        while label[i] != i:
            label[i] = label[label[i]]
            i = label[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            if pose_angle_deg(downs[i], downs[j], axis) < tol_deg:
                a, b = root(i), root(j)
                label[max(a, b)] = min(a, b)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    return [groups[k] for k in sorted(groups)]
