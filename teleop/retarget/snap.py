"""Pad targets snapped onto the object surface (:func:`snap_pad_targets`).

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

The operator's own pads decide too (``operator_snap_m``). The robot target of a pad is the
person's pad scaled about the wrist, and the scaling moves it *off* the surface where the
person's pad is near it: on real Quest captures the robot thumb target sat 11.7 mm (free
object) / 17.5 mm (held object) from the surface while the person's thumb pad was 6.5 mm from
it, and a person's pads on a virtual object stop 3–8 mm short. So with the operator's pads'
signed distances e, the target goes to

    g(d, e) = (1 − W)·f_p(d) − W·(p + t),   W = w(e; operator_snap_m) · w(d; 2·snap_m),

t (``operator_depth_m``) into the surface (and the press p further) wherever the person's
pad is within operator_snap_m / 2 of it, whatever the scaling did, and exactly as before
where the person's pad is beyond operator_snap_m. t is a touch, not a squeeze: a target on
the surface leaves the simulated pad the IK's 1–3 mm short of it, so the finger the person put
on the object never touches it and nothing (contacts, the assist) follows; the simulated
contact stops the finger t in. The second factor leaves alone a target more than 2·snap_m
from the surface whatever the person's pad does: that robot finger is elsewhere (on the
object's far side, under it while the hand reaches), and pulling it across would sweep the
object away (measured: a reaching little finger lifted an apple 24 mm before the closure).
g is C¹ in both distances and monotonic as the hand closes (f_p ≥ −p and W only rises). The
target keeps its own nearest surface point (where the robot finger reaches the object); only
its distance along the normal follows the person.

Points and distances in metres, in whatever frame the surface was queried in.
"""

from __future__ import annotations

import numpy as np

from sim.transforms import quat_to_mat1
from teleop.retarget.surface import ObjectSurface

__all__ = ["Pose", "snap_distances", "snap_pad_targets", "snap_weight"]

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


def snap_pad_targets(surface: ObjectSurface, targets: Array, base: Pose, snap_m: float,
                     press_m: Array | float = 0.0, sim_base: Pose | None = None,
                     operator_pads_m: Array | None = None, operator_snap_m: float = 0.0,
                     operator_depth_m: float = 0.0) -> tuple[Array, Array]:
    """``targets`` (n, 3) of a hand whose base is at ``base`` (position, quaternion wxyz, in the
    surface's world), in that base frame, moved along their surface normals to the snapped
    distance (:func:`snap_distances`), and how far each moved (metres). ``operator_pads_m``
    (n, 3): the operator's own pad points in the surface's world, whose distances pull the
    targets on within ``operator_snap_m``, ``operator_depth_m`` past the surface (module
    docstring; None or 0: the targets' own distances alone).

    With ``sim_base`` (where the simulated hand's base actually is) each snapped target is
    blended, by its :func:`snap_weight`, into that frame: the IK then puts the pads on the
    object where the simulated hand is (a base that lags its command, or gives way to the
    fingers' squeeze, no longer leaves them short of it); targets beyond ``snap_m`` keep the
    commanded frame, so fingers away from the object keep the operator's posture.
    """
    r_b = quat_to_mat1(np.asarray(base[1], float))
    world = base[0] + targets @ r_b.T
    _, normals, signed = surface.query(world)
    goal = snap_distances(signed, snap_m, press_m)
    weight = snap_weight(signed, snap_m)
    if operator_pads_m is not None and operator_snap_m > 0.0:
        w_op = (snap_weight(surface.query(operator_pads_m)[2], operator_snap_m)
                * snap_weight(signed, 2.0 * snap_m))
        goal = (1.0 - w_op) * goal - w_op * (np.asarray(press_m, float) + operator_depth_m)
        weight = np.maximum(weight, w_op)
    moved = signed - goal
    world = world - moved[:, None] * normals
    local = (world - base[0]) @ r_b
    if sim_base is None:
        return local, moved
    in_sim = (world - sim_base[0]) @ quat_to_mat1(np.asarray(sim_base[1], float))
    return local + weight[:, None] * (in_sim - local), moved
