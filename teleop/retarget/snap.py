"""Pad targets snapped onto the object surface (:func:`snap_to_surface`).

Why: the operator's pads touch the real object, but after scaling, tracking error and the
different finger proportions their robot targets land millimetres off the simulated surface
(the issue measured 7.5–11 mm), in front of it (the robot finger stops short, no contact) or
behind it (it presses through). A target in front of the surface at signed distance d is
moved along the surface normal to distance f(d):

    f(d) = 0                                  for d ≤ a = snap_m / 2 (onto the surface),
    f(d) = snap_m·(3u² − 2u³) + a·(u³ − u²)   for a < d < snap_m, u = (d − a) / a,
    f(d) = d                                  beyond snap_m (fingers not meant to touch),

the cubic Hermite blend with f(a) = 0, f'(a) = 0, f(snap_m) = snap_m, f'(snap_m) = 1: the
target does not jump when the operator's pad crosses either threshold, its motion is C¹, and f
is monotonic (slope ≤ 25/9), so closing the hand always moves the target closer. A full snap
over the inner half, not a blend from the surface on, because tracked human pads stop 3–7 mm
short of the object they hold (hand-model and tracking error): those must land on it, not 1–2
mm off. Targets behind the surface (d < 0) are put onto it: the operator pressing into an
object means "touch it", and the simulated contact stops the finger there anyway.

With a press p (the bridge's grasp assist, :mod:`teleop.bridge.grasp_assist`) the snapped
targets go p *behind* the surface instead, f_p(d) = f(d) − p·w(d) with w = 1 over the inner
half and the same Hermite blend down to 0 at snap_m (w(d) = 1 − (3u² − 2u³)): still C¹ and
monotonic (w only falls), and targets beyond snap_m keep d, so fingers away from the object
never move for it.

Points and distances in metres, in whatever frame the surface was queried in.
"""

from __future__ import annotations

import numpy as np

__all__ = ["snap_distances", "snap_to_surface"]

Array = np.ndarray


def snap_distances(signed_m: Array, snap_m: float, press_m: Array | float = 0.0) -> Array:
    """Signed distance after snapping (the module docstring's f, or f_p with a press
    ``press_m``, per point or one for all), per point (metres)."""
    d = np.asarray(signed_m, dtype=float)
    a = 0.5 * snap_m
    u = np.clip((d - a) / a, 0.0, 1.0)
    rise = u * u * (3.0 - 2.0 * u)
    blend = snap_m * rise + a * u * u * (u - 1.0) - np.asarray(press_m, float) * (1.0 - rise)
    return np.where(d >= snap_m, d, blend)


def snap_to_surface(points_m: Array, normals: Array, signed_m: Array, snap_m: float,
                    press_m: Array | float = 0.0) -> tuple[Array, Array]:
    """Points (n, 3) moved along their surface ``normals`` (n, 3) from signed distance
    ``signed_m`` (n,) to :func:`snap_distances`; also how far each moved (n,), metres."""
    moved = np.asarray(signed_m, dtype=float) - snap_distances(signed_m, snap_m, press_m)
    return points_m - moved[:, None] * normals, moved
