"""Lighter triangle meshes for the browser viewer: vertex clustering to a face budget.

Why: a hand's visual meshes hold 50 k (Shadow) to 450 k (LEAP) triangles and a scanned YCB
object 16 k; a self-contained viewer page carries them base64-encoded, and a browser draws a
few tens of thousands of triangles smoothly even on a software rasteriser. Vertex clustering
(snap vertices to a cubic grid, merge each cell's vertices at their mean, drop collapsed
triangles) keeps the silhouette to about one cell and costs one ``np.unique``: exactly what a
picture needs, and nothing the simulation uses (it reads the model, never these meshes).
Units: metres.
"""

from __future__ import annotations

import numpy as np

__all__ = ["cluster_vertices", "within_budget"]


def cluster_vertices(vertices: np.ndarray, faces: np.ndarray,
                     cell_m: float) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` with vertices merged per ``cell_m`` grid cell (at the cell's mean)
    and the triangles that collapsed, or repeat another, removed."""
    v = np.asarray(vertices, float).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if not len(v) or not len(f):
        return v, f
    keys = np.floor(v / cell_m).astype(np.int64)
    _, cell = np.unique(keys, axis=0, return_inverse=True)
    cell = cell.ravel()
    counts = np.bincount(cell)
    merged = np.column_stack([np.bincount(cell, weights=v[:, k]) for k in range(3)]) / counts[:, None]
    f = cell[f]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(first)]
    used, f = np.unique(f, return_inverse=True)
    return merged[used], f.reshape(-1, 3)


def within_budget(vertices: np.ndarray, faces: np.ndarray,
                  max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """The mesh itself when it has at most ``max_faces`` triangles, else clustered on a grid
    that starts at 1/400 of its bounding-box diagonal and grows by √2 until it fits."""
    v = np.asarray(vertices, float).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if len(f) <= max_faces or not len(v):
        return v, f
    cell = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))) / 400 or 1e-4
    while True:
        cv, cf = cluster_vertices(v, f, cell)
        if len(cf) <= max_faces:
            return cv, cf
        cell *= np.sqrt(2.0)
