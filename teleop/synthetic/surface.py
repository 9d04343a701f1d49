"""Closest points on, and signed distances to, an object's triangle mesh.

The synthetic operator needs them to put reference pulp sites on the object surface and to
score the generic grasp; exact over all triangles (trimesh's per-triangle routine), so no
spatial index (rtree) is needed. Metres, in the mesh's frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["closest_surface_frames", "closest_surface_points", "surface_distance_m"]

Array = np.ndarray


def closest_surface_frames(mesh: Any, points_m: Array) -> tuple[Array, Array, Array]:
    """Closest points (n,3) on a triangle mesh to points (n,3) (same frame, metres), the
    signed distances (n,) and the outward unit normals (n,3) of the closest triangles: exact
    over all triangles (trimesh's per-triangle routine, so no rtree is needed); the distance is
    negative where a point lies behind the closest triangle's outward normal (inside)."""
    from trimesh.triangles import closest_point

    tris = np.asarray(mesh.triangles)
    normals = np.asarray(mesh.face_normals)
    pts = np.asarray(points_m, dtype=float).reshape(-1, 3)
    closest = np.empty_like(pts)
    signed = np.empty(len(pts))
    outward = np.empty_like(pts)
    for i, p in enumerate(pts):
        c = closest_point(tris, np.broadcast_to(p, (len(tris), 3)))
        d = np.linalg.norm(c - p, axis=1)
        j = int(np.argmin(d))
        closest[i], outward[i] = c[j], normals[j]
        signed[i] = d[j] if float((p - c[j]) @ normals[j]) >= 0.0 else -d[j]
    return closest, signed, outward


def closest_surface_points(mesh: Any, points_m: Array) -> tuple[Array, Array]:
    """Closest points (n,3) and signed distances (n,) (:func:`closest_surface_frames`)."""
    closest, signed, _ = closest_surface_frames(mesh, points_m)
    return closest, signed


def surface_distance_m(mesh: Any, points_m: Array) -> Array:
    """Signed distance (n,) metres from points (n,3) to a mesh (see
    :func:`closest_surface_points`)."""
    return closest_surface_points(mesh, points_m)[1]
