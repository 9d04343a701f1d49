"""WebXR hand joints → :class:`teleop.messages.HandFrame`: the one boundary between conventions.

Why here: WebXR (the browser page on the Quest) and IWER recordings (:mod:`teleop.input.iwer`)
both speak the WebXR convention — 25 joints without PALM, xyzw quaternions, +Y up, −Z forward.
This module is the one boundary where that becomes dexaug's convention: 26 OpenXR joints with a
synthesised PALM, MuJoCo world (+Z up), wxyz quaternions (see :mod:`teleop.input.frames` for the
rotation). Units: metres.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from teleop.input import frames
from teleop.messages import NUM_JOINTS, PALM, WRIST, HandFrame, HandState, MessageError

__all__ = ["NUM_WEBXR_JOINTS", "WEBXR_JOINTS", "from_webxr_joints", "hand_frame_from_webxr",
           "webxr_to_openxr_arrays"]

Array = np.ndarray

#: The 25 WebXR ``XRHandJoint`` names, in the spec's order (= OpenXR order without PALM, so
#: OpenXR index = WebXR index + 1).
WEBXR_JOINTS: tuple[str, ...] = (
    "wrist",
    "thumb-metacarpal", "thumb-phalanx-proximal", "thumb-phalanx-distal", "thumb-tip",
    "index-finger-metacarpal", "index-finger-phalanx-proximal",
    "index-finger-phalanx-intermediate", "index-finger-phalanx-distal", "index-finger-tip",
    "middle-finger-metacarpal", "middle-finger-phalanx-proximal",
    "middle-finger-phalanx-intermediate", "middle-finger-phalanx-distal", "middle-finger-tip",
    "ring-finger-metacarpal", "ring-finger-phalanx-proximal",
    "ring-finger-phalanx-intermediate", "ring-finger-phalanx-distal", "ring-finger-tip",
    "pinky-finger-metacarpal", "pinky-finger-phalanx-proximal",
    "pinky-finger-phalanx-intermediate", "pinky-finger-phalanx-distal", "pinky-finger-tip",
)
NUM_WEBXR_JOINTS = len(WEBXR_JOINTS)
_WEBXR_MIDDLE_METACARPAL = WEBXR_JOINTS.index("middle-finger-metacarpal")
_WEBXR_MIDDLE_PROXIMAL = WEBXR_JOINTS.index("middle-finger-phalanx-proximal")


def webxr_to_openxr_arrays(positions: Array, quats_xyzw: Array,
                            radii: Array) -> tuple[Array, Array, Array, Array]:
    """Vectorised core of :func:`from_webxr_joints` over leading dims (...,25,·) → (...,26,·)
    arrays (positions, orientations wxyz, radii, valid) in the MuJoCo world; inputs in the XR
    reference space (positions metres, quaternions xyzw, radii metres)."""
    p = frames.xr_to_mujoco_positions(positions)
    q = frames.quat_normalize_wxyz(frames.xr_to_mujoco_quat_wxyz(quats_xyzw))
    r = np.asarray(radii, dtype=float)
    valid = np.isfinite(p).all(-1) & np.isfinite(q).all(-1) & np.isfinite(r) & (r >= 0)
    lead = p.shape[:-2]
    pos = np.full((*lead, NUM_JOINTS, 3), np.nan)
    quat = np.full((*lead, NUM_JOINTS, 4), np.nan)
    rad = np.full((*lead, NUM_JOINTS), np.nan)
    ok = np.zeros((*lead, NUM_JOINTS), dtype=bool)
    pos[..., 1:, :] = p
    quat[..., 1:, :] = q
    rad[..., 1:] = r
    ok[..., 1:] = valid
    # PALM: OpenXR puts it at the centre of the middle-finger metacarpal bone, i.e. halfway
    # between the metacarpal joint (its base) and the proximal phalanx joint (the knuckle);
    # orientation and radius are the middle metacarpal's (the bone it lies on).
    mc, px = _WEBXR_MIDDLE_METACARPAL, _WEBXR_MIDDLE_PROXIMAL
    pos[..., PALM, :] = 0.5 * (p[..., mc, :] + p[..., px, :])
    quat[..., PALM, :] = q[..., mc, :]
    rad[..., PALM] = r[..., mc]
    ok[..., PALM] = valid[..., mc] & valid[..., px]
    pos[~ok] = np.nan
    quat[~ok] = np.nan
    rad[~ok] = np.nan
    return pos, quat, rad, ok


def from_webxr_joints(positions: Array, quats_xyzw: Array, radii: Array) -> HandState:
    """One hand's 25 WebXR joints in the XR reference space → a 26-joint :class:`HandState`
    in the MuJoCo world.

    positions: (25,3) metres; quats_xyzw: (25,4); radii: (25,) metres, all in WebXR joint order
    (:data:`WEBXR_JOINTS`). Joints with NaN/inf values, a zero quaternion or a negative radius
    (how a sender marks a joint the runtime did not report) become ``valid=False`` with NaN
    values; PALM is synthesised from the middle metacarpal (valid only when that bone's two
    joints are); ``tracked`` is False when the wrist is missing. Quaternions are normalised
    (the IWER recorder rounds them to 1e-3).
    """
    p = np.asarray(positions, dtype=float)
    q = np.asarray(quats_xyzw, dtype=float)
    r = np.asarray(radii, dtype=float)
    for name, arr, shape in (("positions", p, (NUM_WEBXR_JOINTS, 3)),
                             ("quats_xyzw", q, (NUM_WEBXR_JOINTS, 4)),
                             ("radii", r, (NUM_WEBXR_JOINTS,))):
        if arr.shape != shape:
            raise MessageError(f"WebXR {name}: expected shape {shape} (25 WebXR joints), "
                               f"got {arr.shape}")
    pos, quat, rad, ok = webxr_to_openxr_arrays(p, q, r)
    return HandState(pos, quat, rad, ok, tracked=bool(ok[WRIST]))


def hand_frame_from_webxr(seq: int, time_s: float, head_position_xr: ArrayLike,
                           head_quat_xyzw: ArrayLike,
                           hands_xr: dict[str, tuple[Array, Array, Array]],
                           *, receive_time_s: float | None = None,
                           source: str = "webxr") -> HandFrame:
    """Build a :class:`HandFrame` from one WebXR frame as a page sends it: head pose and, per
    side, (positions (25,3), quats_xyzw (25,4), radii (25,)) in the reference space (the
    page already asked for joint poses relative to the reference space, not the ray)."""
    head_p, head_q = frames.xr_to_mujoco_pose(np.asarray(head_position_xr, dtype=float),
                                              np.asarray(head_quat_xyzw, dtype=float))
    sides = {}
    for side, (p, q, r) in hands_xr.items():
        if side not in ("left", "right"):
            raise MessageError(f"hand side must be 'left' or 'right', got {side!r}")
        sides[side] = from_webxr_joints(p, q, r)
    return HandFrame(seq=seq, device_time_s=time_s,
                     receive_time_s=time_s if receive_time_s is None else receive_time_s,
                     head_position=head_p,
                     head_orientation_wxyz=frames.quat_normalize_wxyz(head_q),
                     left=sides.get("left"), right=sides.get("right"), source=source)
