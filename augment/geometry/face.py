"""The contact-face record of AutoWS (paper section 3.1) and the error raised while building one.

A :class:`ContactFace` is a planar circle or axis-aligned rectangle on a fingertip, in the frame of
the cloud it was grown from (metres). It is built by :func:`augment.geometry.contact_face.contact_face`
and carried into ``frame_palm`` by AutoWS; FSG uses :meth:`ContactFace.contains` to collect the
object points a face touches. It lives apart from the algorithm so that the cloud checks
(:mod:`augment.geometry.pulp`) and the inscribed shapes (:mod:`augment.geometry.inscribed`) can
raise :class:`ContactFaceError` without depending on the face-growing code.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from sim.errors import DexaugError

__all__ = ["CentreMode", "ContactFace", "ContactFaceError", "ShapeKind"]

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

