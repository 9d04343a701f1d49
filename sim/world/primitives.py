"""Procedural objects built in code: the embedded defaults that need no asset files.

They let every part of dexaug (scene, validator, augmenter, tests, demos) run on a machine
without the YCB set, and they give shapes with known dimensions for checks. Each primitive is a
``mujoco.MjSpec`` with the same layout as a loaded YCB object (see ``sim.world.object_spec``): one body
``object`` with a free joint ``object_free`` at the object frame, collision geoms (group 3,
contype = conaffinity = 1, real masses) and visual geoms (group 2, no collisions, no mass).
Contact parameters are left at MuJoCo's defaults here; ``ObjectAsset.spec`` sets them.

The object frame of every primitive is the centre of its axis-aligned bounding box, +z up
(the axis of the cylinder and of the bowl). Units: metres, kilograms, kg/m³.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh

from sim.errors import AssetError

BOX_SIZE_M = (0.06, 0.06, 0.10)          # full edge lengths x, y, z
BOX_MASS_KG = 0.25                       # a packaged food box (about 690 kg/m³)
CYLINDER_RADIUS_M = 0.033                # a food can (YCB 005 tomato soup can is r 3.3 cm)
CYLINDER_HEIGHT_M = 0.10
CYLINDER_MASS_KG = 0.35                  # about 1020 kg/m³, a full can
SPHERE_RADIUS_M = 0.035
SPHERE_MASS_KG = 0.15                    # about 840 kg/m³, a soft ball
BOWL_RADIUS_M = 0.08                     # outer wall faces, from the axis
BOWL_HEIGHT_M = 0.05                     # outer bottom to rim
BOWL_WALL_M = 0.004                      # wall and bottom thickness
BOWL_SEGMENTS = 24                       # wall pieces (MuJoCo collides meshes by convex hull)
BOWL_DENSITY_KG_M3 = 900.0               # polypropylene; gives about 0.16 kg

_COLLISION_RGBA = (0.4, 0.5, 0.6, 0.5)


@dataclass(frozen=True)
class Primitive:
    """A procedural object: its name, what it stands for, its bounding box and its builder."""

    name: str
    description: str
    extents_m: tuple[float, float, float]   # full AABB edge lengths of the surface, object frame
    build: Callable[[], mujoco.MjSpec]


def _new_spec(name: str) -> tuple[mujoco.MjSpec, mujoco.MjsBody]:
    spec = mujoco.MjSpec()
    spec.modelname = name
    body = spec.worldbody.add_body(name="object")
    body.add_freejoint(name="object_free")
    return spec, body


def _collision(body: mujoco.MjsBody, name: str, **kwargs: object) -> mujoco.MjsGeom:
    return body.add_geom(name=name, contype=1, conaffinity=1, group=3, rgba=list(_COLLISION_RGBA),
                         **kwargs)


def _visual(body: mujoco.MjsBody, name: str, rgba: tuple[float, ...], **kwargs: object) -> mujoco.MjsGeom:
    return body.add_geom(name=name, contype=0, conaffinity=0, group=2, mass=0.0, rgba=list(rgba),
                         **kwargs)


def _single(name: str, geom_type: mujoco.mjtGeom, size: list[float], mass_kg: float,
            rgba: tuple[float, ...]) -> mujoco.MjSpec:
    spec, body = _new_spec(name)
    _collision(body, "collision", type=geom_type, size=size, mass=mass_kg)
    _visual(body, "visual", rgba, type=geom_type, size=size)
    return spec


def build_box() -> mujoco.MjSpec:
    """A 6 × 6 × 10 cm box of 0.25 kg (a cereal or sugar box)."""
    half = [s / 2 for s in BOX_SIZE_M]
    return _single("box", mujoco.mjtGeom.mjGEOM_BOX, half, BOX_MASS_KG, (0.80, 0.62, 0.40, 1.0))


def build_cylinder() -> mujoco.MjSpec:
    """An upright cylinder, radius 3.3 cm, height 10 cm, 0.35 kg (a food can)."""
    size = [CYLINDER_RADIUS_M, CYLINDER_HEIGHT_M / 2]
    return _single("cylinder", mujoco.mjtGeom.mjGEOM_CYLINDER, size, CYLINDER_MASS_KG,
                   (0.75, 0.15, 0.12, 1.0))


def build_sphere() -> mujoco.MjSpec:
    """A sphere of radius 3.5 cm and 0.15 kg (a soft ball)."""
    return _single("sphere", mujoco.mjtGeom.mjGEOM_SPHERE, [SPHERE_RADIUS_M, 0.0, 0.0], SPHERE_MASS_KG,
                   (0.95, 0.55, 0.10, 1.0))


def bowl_surface() -> trimesh.Trimesh:
    """The bowl's closed, outward-oriented surface in the object frame (metres).

    A profile (outer bottom, outer wall, rim, inner wall, inner bottom) revolved into
    ``BOWL_SEGMENTS`` flat sections whose outer faces lie exactly ``BOWL_RADIUS_M`` from the axis,
    so it coincides with the collision pieces (one clean surface for sampling object clouds,
    instead of overlapping pieces with inner faces).
    """
    n, t, h = BOWL_SEGMENTS, BOWL_WALL_M, BOWL_HEIGHT_M
    to_vertex = 1.0 / np.cos(np.pi / n)   # face distance → polygon vertex distance
    profile = np.array([[0.0, 0.0], [BOWL_RADIUS_M, 0.0], [BOWL_RADIUS_M, h], [BOWL_RADIUS_M - t, h],
                        [BOWL_RADIUS_M - t, t], [0.0, t]])
    profile[:, 0] *= to_vertex
    mesh = trimesh.creation.revolve(profile, sections=n)
    mesh.apply_translation([0.0, 0.0, -h / 2])
    return mesh


def build_bowl() -> mujoco.MjSpec:
    """A thin-walled bowl (radius 8 cm, height 5 cm, 4 mm walls) from 25 convex pieces.

    MuJoCo collides a mesh by its convex hull, so a concave bowl is a flat polygonal bottom plus
    a ring of thin wall boxes; the visual geom is the single surface of ``bowl_surface``.
    """
    n, t, h = BOWL_SEGMENTS, BOWL_WALL_M, BOWL_HEIGHT_M
    spec, body = _new_spec("bowl")
    bottom = trimesh.creation.cylinder(radius=BOWL_RADIUS_M / np.cos(np.pi / n), height=t, sections=n)
    spec.add_mesh(name="bowl_bottom", uservert=bottom.vertices.ravel().tolist(),
                  userface=bottom.faces.ravel().tolist())
    _collision(body, "collision_bottom", type=mujoco.mjtGeom.mjGEOM_MESH, meshname="bowl_bottom",
               pos=[0.0, 0.0, -h / 2 + t / 2], density=BOWL_DENSITY_KG_M3)
    wall_half = [t / 2, BOWL_RADIUS_M * np.tan(np.pi / n), (h - t) / 2]
    wall_z = -h / 2 + t + wall_half[2]
    for k in range(n):
        angle = (2 * k + 1) * np.pi / n          # face centres lie between polygon vertices
        r = BOWL_RADIUS_M - t / 2
        quat = [np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)]   # wxyz, about +z
        _collision(body, f"collision_wall_{k}", type=mujoco.mjtGeom.mjGEOM_BOX, size=wall_half,
                   pos=[r * np.cos(angle), r * np.sin(angle), wall_z], quat=quat,
                   density=BOWL_DENSITY_KG_M3)
    surface = bowl_surface()
    spec.add_mesh(name="bowl_surface", uservert=surface.vertices.ravel().tolist(),
                  userface=surface.faces.ravel().tolist())
    _visual(body, "visual", (0.25, 0.45, 0.75, 1.0), type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname="bowl_surface")
    return spec


_BOWL_EXTENT_XY = 2 * BOWL_RADIUS_M / np.cos(np.pi / BOWL_SEGMENTS)   # polygon vertices on ±x, ±y

PRIMITIVES: dict[str, Primitive] = {
    p.name: p for p in (
        Primitive("box", "box 6 × 6 × 10 cm, 0.25 kg", BOX_SIZE_M, build_box),
        Primitive("cylinder", "cylinder r 3.3 cm × 10 cm, 0.35 kg (a can)",
                  (2 * CYLINDER_RADIUS_M, 2 * CYLINDER_RADIUS_M, CYLINDER_HEIGHT_M), build_cylinder),
        Primitive("sphere", "sphere r 3.5 cm, 0.15 kg", (2 * SPHERE_RADIUS_M,) * 3, build_sphere),
        Primitive("bowl", "bowl r 8 cm × 5 cm, 4 mm walls, about 0.16 kg",
                  (_BOWL_EXTENT_XY, _BOWL_EXTENT_XY, BOWL_HEIGHT_M), build_bowl),
    )
}


def primitive_spec(name: str) -> mujoco.MjSpec:
    """A fresh spec of the primitive ``name`` (one of ``PRIMITIVES``)."""
    try:
        return PRIMITIVES[name].build()
    except KeyError:
        raise AssetError(f"unknown primitive {name!r}; available: {', '.join(PRIMITIVES)}") from None
