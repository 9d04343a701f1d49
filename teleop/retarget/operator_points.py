"""The operator's points that drive the robot: finger pads and phalanx keypoints
(:func:`pad_points`), and the pinch adjustment between thumb and finger targets
(:func:`pinch_adjust`).

Pads
    OpenXR tip joints sit at the *centre* of the fingertip, a joint radius (≈ 7–9 mm) from the
    skin, while the robot's targets are its pulp sites on the pad surface. Driving the pulp site
    to the centre leaves a touching robot finger about one radius short of (or, scaled, past)
    the object, which is most of the 7.5–11 mm the issue measured. The operator's pad point is
    the tip joint moved by its radius along the palmar direction of the distal bone: −z of the
    tip joint's frame (after ingest, +z is dorsal, :mod:`teleop.input.frames`).

Pinch
    Below ``pinch_release_gap_m`` of skin gap (tip-centre distance minus both radii) between the
    thumb and a finger, their targets are pulled together symmetrically so that touching skin
    maps to touching pulps: with w = 1 − gap / release, the target distance becomes
    (1 − w)·d + w·max(gap, 0), d being the targets' own distance. That is continuous and
    monotonic, equals d at the release gap and the skin gap (0 when touching) as the fingers
    close. With centre targets (d = centre distance) it is the former d − w·(r_thumb + r_finger);
    with pad targets of pads that face each other d already is about the skin gap and little
    moves, while pads that meet off-centre (tip to tip) are still brought together.

Positions in metres, in whatever frame the inputs are (the operator wrist frame here).
"""

from __future__ import annotations

import numpy as np

__all__ = ["dorsal_axes", "pad_points", "pinch_adjust"]

Array = np.ndarray


def dorsal_axes(quats_wxyz: Array) -> Array:
    """The local +z axes (n, 3) of joint frames given as quaternions (n, 4) wxyz."""
    w, x, y, z = quats_wxyz.T
    return np.stack([2.0 * (x * z + w * y), 2.0 * (y * z - w * x),
                     1.0 - 2.0 * (x * x + y * y)], axis=1)


def pad_points(positions_m: Array, quats_wxyz: Array, radii_m: Array) -> Array:
    """Pad points (n, 3) of tip joints: positions moved by their radius along −z of their
    frames (a non-finite radius counts as 0: the centre is used)."""
    r = np.where(np.isfinite(radii_m), radii_m, 0.0)
    return positions_m - r[:, None] * dorsal_axes(quats_wxyz)


def pinch_adjust(points: Array, centres: Array, radii_m: Array, thumb: int, others: Array,
                 release_gap_m: float) -> tuple[Array, Array | None]:
    """Thumb and finger target ``points`` (n, 3) pulled together by the skin gap of the tip
    ``centres`` (n, 3) with ``radii_m`` (n,) (module docstring); also the pinch weight w per
    finger of ``others`` (None when none pinches)."""
    vc = centres[others] - centres[thumb]
    r_sum = radii_m[others] + radii_m[thumb]
    r_sum = np.where(np.isfinite(r_sum), r_sum, 0.0)   # no radius: the centre distance
    gap = np.sqrt(np.einsum("ij,ij->i", vc, vc)) - r_sum
    w = np.clip(1.0 - gap / release_gap_m, 0.0, 1.0)
    active = w > 0.0
    if not active.any():
        return points, None
    v = points[others] - points[thumb]
    d = np.sqrt(np.einsum("ij,ij->i", v, v))
    d_new = (1.0 - w) * d + w * np.maximum(gap, 0.0)
    half = np.where(d > 1e-9, 0.5 * (d - d_new) / np.maximum(d, 1e-9), 0.0)
    delta = v * half[:, None]                     # move each finger half the way
    points = points.copy()
    points[others] -= delta
    points[thumb] += delta.sum(axis=0) / int(active.sum())
    return points, w
