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

from sim.transforms import quat_to_mat1
from teleop.retarget.surface import ObjectSurface

__all__ = ["Pose", "snap_distances", "snap_pad_targets", "snap_to_surface", "snap_weight"]

Array = np.ndarray
#: A rigid pose: position (3,) metres and quaternion (4,) wxyz.
Pose = tuple[Array, Array]


def _band(d: Array, snap_m: float) -> tuple[Array, Array]:
    """Where ``d`` lies in the blend band, u = (d − a) / a clipped to [0, 1], and the Hermite
    rise 3u² − 2u³ there."""
    a = 0.5 * snap_m
    u = np.clip((d - a) / a, 0.0, 1.0)
    return u, u * u * (3.0 - 2.0 * u)


def snap_weight(signed_m: Array, snap_m: float) -> Array:
    """How much of the object a target at signed distance ``signed_m`` follows, per point: the
    module docstring's w (1 over the inner half and behind the surface, the Hermite blend down
    to 0 at ``snap_m``, 0 beyond). What the press is scaled by, and what blends a snapped
    target into the simulated hand's frame (:func:`snap_pad_targets`)."""
    d = np.asarray(signed_m, dtype=float)
    return np.where(d >= snap_m, 0.0, 1.0 - _band(d, snap_m)[1])


def snap_distances(signed_m: Array, snap_m: float, press_m: Array | float = 0.0) -> Array:
    """Signed distance after snapping (the module docstring's f, or f_p with a press
    ``press_m``, per point or one for all), per point (metres)."""
    d = np.asarray(signed_m, dtype=float)
    u, rise = _band(d, snap_m)
    blend = (snap_m * rise + 0.5 * snap_m * u * u * (u - 1.0)
             - np.asarray(press_m, float) * (1.0 - rise))
    return np.where(d >= snap_m, d, blend)


def snap_to_surface(points_m: Array, normals: Array, signed_m: Array, snap_m: float,
                    press_m: Array | float = 0.0) -> tuple[Array, Array]:
    """Points (n, 3) moved along their surface ``normals`` (n, 3) from signed distance
    ``signed_m`` (n,) to :func:`snap_distances`; also how far each moved (n,), metres."""
    moved = np.asarray(signed_m, dtype=float) - snap_distances(signed_m, snap_m, press_m)
    return points_m - moved[:, None] * normals, moved


def snap_pad_targets(surface: ObjectSurface, targets: Array, base: Pose, snap_m: float,
                     press_m: Array | float = 0.0, sim_base: Pose | None = None
                     ) -> tuple[Array, Array]:
    """``targets`` (n, 3) of a hand whose base is at ``base`` (position, quaternion wxyz, in the
    surface's world), in that base frame, snapped onto ``surface`` (:func:`snap_to_surface`),
    and how far each moved (metres).

    With ``sim_base`` (where the simulated hand's base actually is) each snapped target is
    blended, by its :func:`snap_weight`, into that frame: the IK then puts the pads on the
    object where the simulated hand is (a base that lags its command, or gives way to the
    fingers' squeeze, no longer leaves them short of it); targets beyond ``snap_m`` keep the
    commanded frame, so fingers away from the object keep the operator's posture.
    """
    r_b = quat_to_mat1(np.asarray(base[1], float))
    world = base[0] + targets @ r_b.T
    _, normals, signed = surface.query(world)
    world, moved = snap_to_surface(world, normals, signed, snap_m, press_m)
    local = (world - base[0]) @ r_b
    if sim_base is None:
        return local, moved
    in_sim = (world - sim_base[0]) @ quat_to_mat1(np.asarray(sim_base[1], float))
    return local + snap_weight(signed, snap_m)[:, None] * (in_sim - local), moved
