"""Hand keypoint trajectories (21 MediaPipe/MANO keypoints or 25/26 OpenXR joints per frame,
positions only) → :class:`teleop.messages.HandFrame`: the geometry of the offline importer.

Why: offline human data (MediaPipe on a video, MANO fits, other trackers) gives joint
*positions* only, in its own frame, without the radii and joint orientations the OpenXR joint
set carries. This module completes each frame into the 26 OpenXR joints the teleop chain
expects, so such data retargets and drives the bridge like a headset capture.

Joint order assumed (and checked by :func:`check_keypoints`): MediaPipe's 21 hand landmarks —
0 wrist; thumb 1 CMC, 2 MCP, 3 IP, 4 tip; then MCP, PIP, DIP, tip of index (5–8), middle
(9–12), ring (13–16) and little (17–20). They map onto OpenXR as CMC → ``thumb_metacarpal``,
thumb MCP → ``thumb_proximal``, IP → ``thumb_distal``; finger MCP → ``*_proximal``, PIP →
``*_intermediate``, DIP → ``*_distal``. MANO keypoints come in this (OpenPose) order from
FreiHAND, HO-3D or DexYCB; MANO's native order (index, middle, little, ring, thumb, then the
tips) must be reordered first, and is refused as it is. OpenXR input is 26 joints (PALM
first, ``XrHandJointEXT`` order) or 25 (WebXR order: the same without PALM).

What is not measured is completed from the parametric human hand's anthropometry
(:mod:`teleop.synthetic.human_hand`):

- **finger metacarpal bases** (21-keypoint input only; the long fingers' ``*_metacarpal``
  joints): on the wrist → MCP line at the template hand's fraction of that distance (≈ 0.37–0.48);
  PALM then sits at the centre of the middle metacarpal, as OpenXR defines it;
- **radii**: the template hand's joint radii scaled to the measured hand length (median bone
  chain wrist → middle tip), since retargeting pinches on skin gaps;
- **orientations** (OpenXR axes after :mod:`teleop.input.frames`' conversion: local +X along
  the bone toward the fingertip, +Z dorsal): the WRIST frame starts from the palm plane — +X
  from the wrist to the middle MCP, +Z the normal of the plane through the wrist and the index
  and little MCPs on the back of the hand (which side that is depends on the handedness, so
  the side is always explicit) — turned by the fixed rotation that makes this rule exact on
  the template hand (its knuckles arch, so the plane rolls ≈ 7°). Every other joint carries
  the frame of the bone distal to it (tips: the distal bone): +X along the bone, +Y its
  flexion axis made perpendicular to the bone — for a finger the lateral axis of its
  metacarpal (palm normal × metacarpal, the template's own rule), for the thumb the
  template's thumb flexion axis, fixed in the wrist frame. Flexion turns a bone about that
  axis, so the frames stay defined in a fist. From 21 of the Quest 3 capture's joints these
  rules give the runtime's own WRIST frame within ≈ 1.5° (median), the finger phalanges
  within ≈ 2–11° and the thumb within ≈ 10–25° (``tests/test_trajectory_import.py``); the
  retargeter reads only the WRIST orientation.

Coordinates (``space``): ``"world"`` — already the MuJoCo world convention of the operator's
tracking space (+Z up, metres); ``"xr"`` — an OpenXR/WebXR reference space (+Y up, −Z
forward), rotated by :data:`teleop.input.frames.XR_TO_MUJOCO`; ``"hand"`` — only the hand's
shape is meaningful (MediaPipe world landmarks: metres about the hand centre; datasets with
the global motion removed): the whole trajectory is moved rigidly so that its mean wrist pose
sits at ``anchor`` (default: in front of the operator, 25 cm above the table, palm down,
fingers forward), keeping any rotation of the hand over time. Positions must be metres:
pixels and millimetres fail the hand-length check, MediaPipe's normalised image landmarks
their own fingerprint (the wrist's z is exactly 0). Frames with missing keypoints (NaN) become
untracked frames. Quaternions wxyz in memory, as everywhere.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from sim.errors import DexaugError
from sim.transforms import axis_angle_to_mat, cross, mat_to_quat, rpy_deg_to_mat
from teleop.input.frames import XR_TO_MUJOCO
from teleop.messages import JOINT_INDEX, NUM_JOINTS, OPENXR_JOINTS, PALM, WRIST, HandFrame, HandState
from teleop.synthetic.human_hand import (
    FINGERS,
    LONG_FINGERS,
    REFERENCE_HAND_LENGTH_M,
    TEMPLATE_WRIST_M,
    HandPose,
    HumanHand,
)

__all__ = ["FORMATS", "HAND_LENGTH_RANGE_M", "MEDIAPIPE_TO_OPENXR", "SPACES", "Anchor",
           "KeypointError", "check_keypoints", "hand_length_m", "joint_rotations",
           "keypoint_frames", "openxr_positions", "to_world", "usable_frames", "wrist_rotations"]

Array = np.ndarray

#: Input layouts: 21 MediaPipe/MANO keypoints, or OpenXR joints (26 with PALM, 25 without).
FORMATS: tuple[str, ...] = ("mediapipe", "openxr")
#: Input coordinate spaces (see the module docstring).
SPACES: tuple[str, ...] = ("hand", "xr", "world")
#: OpenXR joint index of each MediaPipe landmark, in MediaPipe order.
MEDIAPIPE_TO_OPENXR: tuple[int, ...] = tuple(JOINT_INDEX[n] for n in (
    "wrist", "thumb_metacarpal", "thumb_proximal", "thumb_distal", "thumb_tip",
    *(f"{f}_{k}" for f in LONG_FINGERS for k in ("proximal", "intermediate", "distal", "tip"))))
#: Plausible adult hand length (bone chain wrist → middle tip, metres): outside it the input
#: is not metres (pixels, millimetres, centimetres) or not a hand.
HAND_LENGTH_RANGE_M = (0.10, 0.30)
#: Clearest dorsal curl (metres) the long fingertips may show, median over frames, before the
#: declared side is called wrong: fingers curl toward the palm, so tips far on the back of the
#: hand mean a mirrored hand (wrong side, or left-handed coordinates).
_MAX_DORSAL_CURL_M = 0.01

_CHAINS: dict[str, tuple[int, ...]] = {
    f: tuple(JOINT_INDEX[n] for n in OPENXR_JOINTS if n.startswith(f"{f}_")) for f in FINGERS}
#: Where each long finger's metacarpal base sits on the wrist → MCP line (template hand).
_METACARPAL_FRACTION: dict[str, float] = {
    f: float(np.dot(TEMPLATE_WRIST_M[f"{f}_metacarpal"], TEMPLATE_WRIST_M[f"{f}_proximal"])
             / np.dot(TEMPLATE_WRIST_M[f"{f}_proximal"], TEMPLATE_WRIST_M[f"{f}_proximal"]))
    for f in LONG_FINGERS}
_HEAD_POS_M = (0.0, 0.0, 1.25)     # a seated operator's head, as the synthetic operator's
_HEAD_PITCH_DEG = 30.0             # looking down at the table


class KeypointError(DexaugError):
    """A keypoint trajectory is not usable: wrong shape, not metres, joints out of the assumed
    order, or a hand of the other side."""


@dataclass(frozen=True)
class Anchor:
    """Where ``space="hand"`` input goes: the mean wrist pose in the tracking space (metres;
    wrist axes +X distal, +Y toward the thumb for a right hand, +Z dorsal, as columns)."""

    wrist_pos_m: Array = field(default_factory=lambda: np.array([0.15, 0.0, 1.05]))
    wrist_rot: Array = field(default_factory=lambda: np.eye(3))

    @classmethod
    def from_rpy(cls, wrist_pos_m: Sequence[float], wrist_rpy_deg: Sequence[float]) -> Anchor:
        """The anchor at ``wrist_pos_m`` turned by fixed-axis roll, pitch, yaw (degrees)."""
        return cls(np.asarray(wrist_pos_m, float), rpy_deg_to_mat(np.asarray(wrist_rpy_deg, float)))


def _unit(v: Array) -> Array:
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)


def openxr_positions(points: Array, fmt: str) -> Array:
    """Input positions (T,J,3) metres → the 26 OpenXR joint positions (T,26,3) in the same
    space; 21-keypoint input gets its finger metacarpals (and so PALM) from the template."""
    pts = np.asarray(points, dtype=float)
    if fmt == "openxr" and pts.shape[1] == NUM_JOINTS:
        return pts.copy()
    out = np.full((len(pts), NUM_JOINTS, 3), np.nan)
    if fmt == "openxr":
        out[:, 1:] = pts
    else:
        out[:, list(MEDIAPIPE_TO_OPENXR)] = pts
        wrist = out[:, WRIST]
        for f in LONG_FINGERS:
            mcp = out[:, JOINT_INDEX[f"{f}_proximal"]]
            out[:, JOINT_INDEX[f"{f}_metacarpal"]] = wrist + _METACARPAL_FRACTION[f] * (mcp - wrist)
    mid_mc, mid_mcp = out[:, JOINT_INDEX["middle_metacarpal"]], out[:, JOINT_INDEX["middle_proximal"]]
    out[:, PALM] = 0.5 * (mid_mc + mid_mcp)
    return out


def _palm_plane_frames(pos: Array, side: str) -> Array:
    """The raw palm-plane frames (T,3,3): x wrist → middle MCP, z the dorsal normal of the
    plane through the wrist and the index and little MCPs (sign by ``side``), y = z × x."""
    w = pos[:, WRIST]
    x = _unit(pos[:, JOINT_INDEX["middle_proximal"]] - w)
    n = cross(pos[:, JOINT_INDEX["little_proximal"]] - w, pos[:, JOINT_INDEX["index_proximal"]] - w)
    y = _unit(cross(n if side == "right" else -n, x))
    return np.stack([x, y, cross(x, y)], axis=-1)


def _template_calibration(side: str) -> tuple[Array, Array]:
    """What the rules of :func:`joint_rotations` need from the template hand of ``side``: the
    rotation taking its palm-plane frame onto its true wrist frame (the knuckles arch, so the
    plane rolls ≈ 7°), and its thumb's flexion axis in the wrist frame."""
    pos, rot = HumanHand(REFERENCE_HAND_LENGTH_M, side).joints_in_wrist(HandPose.relaxed())
    return _palm_plane_frames(pos[None], side)[0].T, rot[JOINT_INDEX["thumb_metacarpal"], :, 1]


_TEMPLATE = {side: _template_calibration(side) for side in ("left", "right")}


def wrist_rotations(pos: Array, side: str) -> Array:
    """WRIST frames (T,3,3) of positions (T,26,3): the palm-plane frame, corrected by the
    template hand's (exact on the template; within ≈ 1.5° of the Quest 3 runtime's wrist)."""
    return _palm_plane_frames(pos, side) @ _TEMPLATE[side][0]


def joint_rotations(pos: Array, side: str) -> Array:
    """Orientation matrices (T,26,3,3) of all joints from positions (T,26,3) (module
    docstring: WRIST from the palm plane, the others from their bone and flexion axis)."""
    r_wrist = wrist_rotations(pos, side)
    rot = np.full((*pos.shape[:2], 3, 3), np.nan)
    rot[:, WRIST] = r_wrist
    for f, chain in _CHAINS.items():
        bones = _unit(np.diff(pos[:, list(chain)], axis=1))          # (T, len-1, 3)
        # flexion axis: the thumb's is fixed in the palm, a finger's ⊥ palm normal and metacarpal
        axis = (r_wrist @ _TEMPLATE[side][1] if f == "thumb"
                else _unit(cross(r_wrist[..., 2], bones[:, 0])))
        x = np.concatenate([bones, bones[:, -1:]], axis=1)            # tips: the distal bone
        y = _unit(axis[:, None] - np.einsum("tjk,tk->tj", x, axis)[..., None] * x)
        rot[:, list(chain)] = np.stack([x, y, cross(x, y)], axis=-1)
    rot[:, PALM] = rot[:, JOINT_INDEX["middle_metacarpal"]]
    return rot


def usable_frames(pos: Array, side: str) -> Array:
    """(T,) True where positions (T,26,3) make a hand: all finite, and a palm that spans a
    plane (a frame of coincident points has no orientation)."""
    return np.isfinite(pos).all(axis=(1, 2)) & np.isfinite(wrist_rotations(pos, side)).all(axis=(1, 2))


def hand_length_m(pos: Array) -> float:
    """Median over frames of the bone chain wrist → middle tip (metres; what the retargeter
    calibrates its scale on), NaN frames left out."""
    idx = [WRIST, *_CHAINS["middle"]]
    lengths = np.linalg.norm(np.diff(pos[:, idx], axis=1), axis=-1).sum(axis=1)
    return float(np.nanmedian(lengths)) if np.isfinite(lengths).any() else math.nan


def check_keypoints(pos: Array, side: str, where: str) -> None:
    """Refuse positions (T,26,3) that are not a ``side`` hand in metres in the assumed joint
    order, naming ``where`` (the file) and the check that failed."""
    ok = usable_frames(pos, side)
    if not ok.any():
        raise KeypointError(f"{where}: keypoints: no frame has a whole hand (all keypoints finite, "
                            "the knuckles apart)")
    p = pos[ok]
    length = hand_length_m(p)
    lo, hi = HAND_LENGTH_RANGE_M
    if not lo <= length <= hi:
        raise KeypointError(f"{where}: keypoints: the wrist → middle-tip bone chain is {length:.4g} "
                            f"(median), expected a human hand in metres ({lo}–{hi} m); MediaPipe "
                            "image landmarks (normalised) or pixels/millimetres are not accepted: "
                            "give world landmarks in metres")
    mc = {f: p[:, JOINT_INDEX[f"{f}_proximal"]] for f in LONG_FINGERS}
    thumb = p[:, JOINT_INDEX["thumb_metacarpal"]]
    order_ok = (np.median(np.einsum("ti,ti->t", mc["index"] - mc["middle"], mc["little"] - mc["middle"])) < 0
                and np.median(np.linalg.norm(thumb - mc["index"], axis=1)
                              - np.linalg.norm(thumb - mc["little"], axis=1)) < 0)
    if not order_ok:
        raise KeypointError(f"{where}: keypoints: the joints are not in the assumed order (wrist, "
                            "thumb CMC/MCP/IP/tip, then MCP, PIP, DIP, tip of index, middle, ring, "
                            "little): the index and little knuckles must flank the middle one and "
                            "the thumb base be nearer the index knuckle")
    z = wrist_rotations(p, side)[..., 2]
    curl = np.mean([np.einsum("ti,ti->t", p[:, JOINT_INDEX[f"{f}_tip"]] - mc[f], z)
                    for f in LONG_FINGERS], axis=0)
    if np.median(curl) > _MAX_DORSAL_CURL_M:
        raise KeypointError(f"{where}: keypoints: as a {side} hand the fingertips curl "
                            f"{np.median(curl) * 1e3:.0f} mm toward the back of the hand "
                            "(median): the side is wrong, or the coordinates are mirrored")


def _refuse_image_landmarks(pts: Array, where: str) -> None:
    """MediaPipe's image landmarks have a fingerprint no metric data has: z is depth relative to
    the wrist, so the wrist's z is exactly 0 in every frame while its x, y (normalised image
    coordinates) are not. Their scale can pass for metres, so they are caught here."""
    wrist = pts[np.isfinite(pts).all(axis=(1, 2)), 0]
    if len(wrist) and (wrist[:, 2] == 0).all() and (np.abs(wrist[:, :2]) > 1e-6).any(axis=1).all():
        raise KeypointError(f"{where}: keypoints: these are MediaPipe image landmarks (the wrist has "
                            "z = 0 and normalised x, y in every frame); give world landmarks in metres")


def to_world(pos: Array, space: str, side: str, anchor: Anchor | None = None) -> tuple[Array, Array]:
    """The rigid map (R (3,3), t (3,)) taking ``space`` coordinates of the ``side`` hand's
    positions (T,26,3) to the tracking space (MuJoCo convention): p_world = R p + t."""
    if space == "world":
        return np.eye(3), np.zeros(3)
    if space == "xr":
        return XR_TO_MUJOCO.copy(), np.zeros(3)
    anchor = anchor or Anchor()
    ok = usable_frames(pos, side)
    # chordal mean of the wrist rotations: the rotation nearest their sum (SVD projection)
    u, _, vt = np.linalg.svd(wrist_rotations(pos[ok], side).sum(axis=0))
    mean_rot = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    rot = anchor.wrist_rot @ mean_rot.T
    return rot, anchor.wrist_pos_m - rot @ pos[ok, WRIST].mean(axis=0)


def keypoint_frames(points: Array, *, fmt: str, side: str, fps: float, space: str,
                    anchor: Anchor | None = None, where: str = "trajectory",
                    source: str = "import") -> tuple[list[HandFrame], Array, Array]:
    """Frames of a keypoint trajectory ``points`` (T,J,3) metres, ``fmt`` layout, one ``side``
    hand in ``space`` (module docstring), at ``fps`` frames per second from device time 0.

    Frames with a non-finite keypoint or a degenerate palm are untracked (the hand lost, as a
    headset reports it).
    Returns the frames and the rigid map (R, t) used (for object poses in the same space).
    Raises :class:`KeypointError` naming ``where`` on unusable input."""
    pts = np.asarray(points, dtype=float)
    want = {"mediapipe": (21,), "openxr": (NUM_JOINTS, NUM_JOINTS - 1)}
    if fmt not in want:
        raise KeypointError(f"{where}: format {fmt!r}: expected one of {list(FORMATS)}")
    if space not in SPACES:
        raise KeypointError(f"{where}: space {space!r}: expected one of {list(SPACES)}")
    if side not in ("left", "right"):
        raise KeypointError(f"{where}: side {side!r}: expected 'left' or 'right'")
    if pts.ndim != 3 or pts.shape[0] < 1 or pts.shape[1] not in want[fmt] or pts.shape[2] != 3:
        raise KeypointError(f"{where}: keypoints: expected shape (frames, {' or '.join(map(str, want[fmt]))}"
                            f", 3) for format {fmt!r}, got {pts.shape}")
    if not (math.isfinite(fps) and fps > 0):
        raise KeypointError(f"{where}: fps: expected a frame rate > 0, got {fps}")
    if fmt == "mediapipe":
        _refuse_image_landmarks(pts, where)
    raw = openxr_positions(pts, fmt)
    check_keypoints(raw, side, where)
    rot_map, t_map = to_world(raw, space, side, anchor)
    pos = raw @ rot_map.T + t_map
    quats = mat_to_quat(joint_rotations(pos, side).reshape(-1, 3, 3)).reshape(len(pos), NUM_JOINTS, 4)
    radii = HumanHand(hand_length_m(pos), side).radii
    head_q = mat_to_quat(axis_angle_to_mat(np.array([[0.0, 1.0, 0.0]]),
                                           np.array([math.radians(_HEAD_PITCH_DEG)]))[0])
    usable = usable_frames(pos, side) & np.isfinite(quats).all(axis=(1, 2))
    frames = []
    for i in range(len(pos)):
        state = (HandState(pos[i], quats[i], radii.copy(), np.ones(NUM_JOINTS, bool)) if usable[i]
                 else HandState.untracked())
        t = i / fps
        frames.append(HandFrame(seq=i, device_time_s=t, receive_time_s=t,
                                head_position=np.array(_HEAD_POS_M), head_orientation_wxyz=head_q,
                                left=state if side == "left" else None,
                                right=state if side == "right" else None, source=source))
    return frames, rot_map, t_map
