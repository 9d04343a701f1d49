"""Triangle meshes of a compiled model's geoms, in their body frame.

Object geometry (surface, collision hull, radius) is read back from the compiled model rather
than the source files: MuJoCo re-centres meshes on their centroid and moves the geom to
compensate, so vertices are taken from ``mesh_vert`` and placed with ``geom_pos``/``geom_quat``;
primitive geoms (box, sphere, ellipsoid, cylinder, capsule) are tessellated. Units: metres.
"""

from __future__ import annotations

from typing import cast

import mujoco
import numpy as np
import trimesh

from sim.errors import AssetError

__all__ = ["concatenate", "geom_mesh"]


def concatenate(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh of ``meshes`` (pieces may overlap); an empty mesh for none."""
    if not meshes:
        return trimesh.Trimesh()
    if len(meshes) == 1:
        return meshes[0]
    # trimesh annotates concatenate() as any Geometry; of Trimesh pieces it makes a Trimesh
    return cast(trimesh.Trimesh, trimesh.util.concatenate(meshes))


def geom_mesh(model: mujoco.MjModel, g: int, *, hull: bool) -> trimesh.Trimesh:
    """Geom ``g`` as a triangle mesh in its body frame (metres); with ``hull`` a mesh geom gives
    its convex hull (what MuJoCo collides with)."""
    kind, size = model.geom_type[g], model.geom_size[g]
    t = mujoco.mjtGeom
    if kind == t.mjGEOM_MESH:
        mid = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        vertices = model.mesh_vert[v0:v0 + nv].astype(np.float64)
        if hull:
            mesh = trimesh.convex.convex_hull(vertices)
        else:
            mesh = trimesh.Trimesh(vertices, model.mesh_face[f0:f0 + nf].copy(), process=True)
    elif kind == t.mjGEOM_BOX:
        mesh = trimesh.creation.box(extents=2 * size)
    elif kind == t.mjGEOM_SPHERE:
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=size[0])
    elif kind == t.mjGEOM_ELLIPSOID:
        mesh = trimesh.creation.icosphere(subdivisions=3)
        mesh.apply_scale(size)
    elif kind == t.mjGEOM_CYLINDER:
        mesh = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=64)
    elif kind == t.mjGEOM_CAPSULE:
        mesh = trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[32, 32])
    else:
        raise AssetError(f"geom {g} of the object has type {t(kind).name}, which has no surface mesh")
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[g])
    transform = np.eye(4)
    transform[:3, :3] = rot.reshape(3, 3)
    transform[:3, 3] = model.geom_pos[g]
    mesh.apply_transform(transform)
    return mesh
