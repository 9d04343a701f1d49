"""The table of FSG's table mode: a plane in the object frame that palms and fingertips stay above.

The paper's table mode assumes an upright object on a horizontal table (DESIGN §3: the table
surface is the object frame's X-O-Z plane); a demonstration records the table where the object
really lay — on its side, tilted — so the plane is general: an upward unit normal in the object
frame and the height of the surface along it. Units: metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from augment.fsg.params import FsgError

__all__ = ["TablePlane"]


@dataclass(frozen=True)
class TablePlane:
    """``up``: unit normal (object frame) pointing from the table into the object's side;
    ``height_m``: ``up · p`` for every point p of the table surface."""

    up: np.ndarray
    height_m: float

    def __post_init__(self) -> None:
        up = np.asarray(self.up, float)
        if up.shape != (3,) or not np.isfinite(up).all() or abs(np.linalg.norm(up) - 1.0) > 1e-6:
            raise FsgError(f"table plane: expected a unit normal (3 numbers), got {self.up!r}")
        if not np.isfinite(self.height_m):
            raise FsgError(f"table plane: height must be finite, got {self.height_m}")
        object.__setattr__(self, "up", up)

    @classmethod
    def horizontal(cls, z_m: float) -> TablePlane:
        """The plane z = ``z_m`` with object +z up: an upright object resting on a table at
        its lowest point, the paper's table mode."""
        return cls(np.array([0.0, 0.0, 1.0]), float(z_m))

    @classmethod
    def through(cls, point: np.ndarray, up: np.ndarray) -> TablePlane:
        """The plane through ``point`` (object frame) with normal ``up`` (normalised here)."""
        up = np.asarray(up, float)
        norm = float(np.linalg.norm(up))
        if not norm > 0:
            raise FsgError(f"table plane: the normal {up.tolist()} has no direction")
        up = up / norm
        return cls(up, float(np.asarray(point, float) @ up))

    def elevation_m(self, points: np.ndarray) -> np.ndarray:
        """Signed height of ``points`` (..., 3), object frame, above the table (metres)."""
        return np.asarray(points) @ self.up - self.height_m
