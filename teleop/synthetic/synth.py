"""A synthetic operator: grasp episodes as hand-tracking frames, without a headset.

Why: the teleop chain (retargeting, bridge, recording, demo extraction) needs repeatable input
with a known ground truth — an object, where it stands, when the grasp happens — and real
captures have neither a known object pose nor a grasp moment. This module plays the operator:
a parametric human hand (:class:`HumanHand`) performs approach → close → lift → hold → release
→ retreat on an object, and the result goes through the same "sensor" a headset is (noise,
dropouts, timestamp jitter) to become :class:`teleop.messages.HandFrame` objects in the MuJoCo
world, exactly what ingest produces from a real Quest.

The human hand
    26 OpenXR joints (PALM first). Its geometry (joint positions of a straight-ish adult right
    hand in the wrist frame, bone lengths, joint radii) is :data:`TEMPLATE_WRIST_M`, taken from
    anthropometric ratios (metacarpal : proximal : middle : distal phalanx of the middle finger
    ≈ 0.62 : 0.42 : 0.26 : 0.23 of its 0.10 m ray, hand length wrist → middle tip ≈ 0.19 m;
    index/ring ≈ 0.96 of middle, little ≈ 0.79, thumb tip level with the index proximal
    phalanx) and cross-checked against the Quest 3 WebXR capture in the shared assets (same
    joint layout to a few millimetres). ``hand_length_m`` scales it uniformly. A left hand is
    the mirror image (y → −y). Each finger has abduction (about the dorsal axis, at the MCP
    joint) and flexion at MCP, PIP and DIP (about the finger's lateral axis, positive toward
    the palm); the thumb has CMC abduction and flexion (opposition), MCP and IP flexion.
    Joint frames follow :mod:`teleop.input.frames` after conversion: local +X along the bone toward
    the fingertip, +Z out of the back of the hand (dorsal), +Y = Z × X; a joint carries the
    frame of the bone distal to it (tips: the distal bone). PALM sits at the middle
    metacarpal's centre with the metacarpal's frame, WRIST carries the hand frame itself.

The grasp
    With a reference grasp (``configs/hands/<hand>/grasps.toml``) for the object, the episode is
    built so that the *retargeted* robot reproduces it: the wrist pose is the inverse of the
    retargeter's wrist correspondence (operator wrist = robot palm pose ∘ (palm ← wrist), see
    :mod:`teleop.retarget.retargeter`), and each operator fingertip is placed where the retargeter's
    scaling maps it onto the reference grasp's robot pulp site, by a small bounded
    least-squares fit of that finger's human joint angles (with a weak prior toward natural
    DIP ≈ 0.7·PIP coupling). The robot pulp sites of a reference grasp lie on the object
    surface, so retargeting puts the robot fingertips on it up to the human hand's reach
    residual and the IK error. Without a reference grasp, a generic side grasp is used: palm
    facing the object's centre from the operator's side (−x world), fingers up, and the
    closure level (open → power grasp) that brings the mapped fingertips closest to the object
    surface (trimesh proximity), a one-parameter search that needs no IK.

The sensor
    Frames at ``rate_hz`` (Quest: 72–90 Hz) with Gaussian timestamp jitter (kept monotonic)
    and a receive latency; per-joint Gaussian position noise and small random rotations of
    every joint frame (white, per frame); bursts of lost tracking (hand present, untracked, all
    joints invalid) whose long-run fraction of frames is ``dropout_fraction``. All randomness
    comes from one ``numpy.random.Generator`` seeded by ``seed``: same seed, same frames.

Settings live in ``configs/teleop.toml`` ``[synth]`` (:func:`load_synth_config`). Units: metres,
seconds, radians (degrees only in ``*_deg`` keys); quaternions wxyz in memory.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from sim.config import load_toml
from sim.errors import ConfigError
from sim.hand.model import Hand
from sim.transforms import mat_to_quat, quat_to_mat
from teleop.messages import JOINT_INDEX, NUM_JOINTS, OPENXR_JOINTS, HandFrame, HandState
from teleop.retarget.retargeter import TELEOP_CONFIG, WRIST_TO_PALM_CONVENTION, load_retarget_config

logger = logging.getLogger(__name__)

Array = np.ndarray

FINGERS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "little")
LONG_FINGERS: tuple[str, ...] = FINGERS[1:]

#: Reference adult right hand (wrist → middle tip ≈ 0.188 m along the straight hand), joint
#: positions in the operator wrist frame (+x distal, +y toward the thumb, +z dorsal), metres.
#: Finger joints are given for the straight finger; flexion is applied on top.
TEMPLATE_WRIST_M: dict[str, tuple[float, float, float]] = {
    "wrist": (0.0, 0.0, 0.0),
    "thumb_metacarpal": (0.034, 0.030, -0.015),
    "index_metacarpal": (0.036, 0.020, -0.009),
    "middle_metacarpal": (0.035, 0.004, -0.007),
    "ring_metacarpal": (0.035, -0.015, -0.006),
    "little_metacarpal": (0.034, -0.023, -0.009),
    "index_proximal": (0.096, 0.024, -0.007),
    "middle_proximal": (0.096, 0.002, -0.003),
    "ring_proximal": (0.089, -0.018, -0.006),
    "little_proximal": (0.078, -0.034, -0.012),
    "thumb_proximal": (0.055, 0.052, -0.029),
}
#: Phalanx lengths (proximal, intermediate, distal-joint → tip), metres, reference hand; the
#: thumb has (proximal phalanx, distal phalanx → tip) and its metacarpal from the joints above.
PHALANX_M: dict[str, tuple[float, ...]] = {
    "index": (0.039, 0.024, 0.022),
    "middle": (0.043, 0.026, 0.024),
    "ring": (0.040, 0.025, 0.023),
    "little": (0.031, 0.019, 0.021),
    "thumb": (0.033, 0.025),
}
REFERENCE_HAND_LENGTH_M = 0.188
#: Joint radii (metres) by joint kind; tips by finger (OpenXR reports the fingertip's
#: half-thickness: ≈ 7–9 mm).
RADII_M: dict[str, float] = {"palm": 0.021, "wrist": 0.021, "metacarpal": 0.019,
                             "proximal": 0.011, "intermediate": 0.009, "distal": 0.008}
TIP_RADII_M: dict[str, float] = {"thumb": 0.0095, "index": 0.0085, "middle": 0.0085,
                                 "ring": 0.008, "little": 0.0075}
#: Thumb nail turned this far (radians) from the back of the hand toward the thumb side: the
#: relaxed thumb's pad faces the index finger, not the table.
THUMB_PRONATION_RAD = 0.9

#: Human joint limits (radians): per long finger (abduction, MCP, PIP, DIP); thumb (CMC
#: abduction, CMC flexion, MCP, IP).
FINGER_LIMITS = (np.array([-0.35, -0.35, 0.0, -0.1]), np.array([0.35, 1.6, 1.9, 1.4]))
THUMB_LIMITS = (np.array([-0.7, -0.4, -0.3, -0.3]), np.array([0.9, 1.4, 1.1, 1.4]))


# --- configuration ------------------------------------------------------------------------------


@dataclass(frozen=True)
class SynthConfig:
    """``[synth]`` of ``configs/teleop.toml``: the synthetic operator and its sensor.

    Timing: rate_hz (frames per second), time_jitter_s (std of device timestamps), latency_s
    and latency_jitter_s (receive − device time). Noise: position_noise_m (per joint, per
    axis), orientation_noise_deg (per joint, per axis of a small random rotation). Dropouts:
    dropout_fraction (long-run fraction of untracked frames), dropout_burst_frames (min, max
    length of a burst, uniform). Hand: hand_length_m (wrist → middle tip, straight hand).
    tip_surface_snap_m: reference pulp sites closer than this to the object surface are put
    on it before the operator's fingers are fitted (0: imitate the reference exactly).
    Episode: approach_distance_m (start of the wrist, back along the palm normal and up),
    lift_height_m, and the phase durations in seconds. Scene: object_pos_m / object_rpy_deg
    (object frame in the world when the caller gives none), head_pos_m, head_pitch_deg
    (looking down).
    """

    rate_hz: float = 72.0
    time_jitter_s: float = 0.0015
    latency_s: float = 0.025
    latency_jitter_s: float = 0.004
    position_noise_m: float = 0.0025
    orientation_noise_deg: float = 2.0
    dropout_fraction: float = 0.03
    dropout_burst_frames: tuple[int, int] = (2, 10)
    hand_length_m: float = 0.185
    tip_surface_snap_m: float = 0.02
    approach_distance_m: float = 0.25
    lift_height_m: float = 0.10
    still_s: float = 0.4
    approach_s: float = 1.5
    close_s: float = 0.8
    settle_s: float = 0.4
    lift_s: float = 1.0
    hold_s: float = 1.0
    release_s: float = 0.8
    retreat_s: float = 0.8
    object_pos_m: tuple[float, float, float] = (0.45, 0.0, 0.80)
    object_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    head_pos_m: tuple[float, float, float] = (0.0, 0.0, 1.25)
    head_pitch_deg: float = 30.0


_SYNTH_FLOATS = {"rate_hz": (1.0, 1000.0), "time_jitter_s": (0.0, 0.1), "latency_s": (0.0, 5.0),
                 "latency_jitter_s": (0.0, 1.0), "position_noise_m": (0.0, 0.1),
                 "orientation_noise_deg": (0.0, 45.0), "dropout_fraction": (0.0, 0.9),
                 "hand_length_m": (0.10, 0.30), "tip_surface_snap_m": (0.0, 0.1),
                 "approach_distance_m": (0.0, 2.0),
                 "lift_height_m": (0.0, 1.0), "still_s": (0.0, 60.0),
                 "approach_s": (0.05, 60.0), "close_s": (0.05, 60.0), "settle_s": (0.0, 60.0),
                 "lift_s": (0.05, 60.0), "hold_s": (0.0, 60.0), "release_s": (0.05, 60.0),
                 "retreat_s": (0.0, 60.0), "head_pitch_deg": (-90.0, 90.0)}
_SYNTH_VECTORS = ("object_pos_m", "object_rpy_deg", "head_pos_m")


def load_synth_config(path: Path | str | None = None) -> SynthConfig:
    """Read ``[synth]`` of ``configs/teleop.toml`` (or ``path``); keys left out keep the
    :class:`SynthConfig` defaults, unknown keys are refused (a typo would silently keep a
    default), bad values are :class:`ConfigError` naming the file and key."""
    root = load_toml(TELEOP_CONFIG if path is None else path)
    sec = root.section("synth", {})
    sec.reject_unknown({*_SYNTH_FLOATS, *_SYNTH_VECTORS, "dropout_burst_frames"})
    values: dict[str, Any] = {}
    for key, (lo, hi) in _SYNTH_FLOATS.items():
        if key in sec:
            values[key] = sec.float(key, min=lo, max=hi)
    for key in _SYNTH_VECTORS:
        if key in sec:
            values[key] = tuple(sec.floats(key, 3))
    if "dropout_burst_frames" in sec:
        burst = sec.floats("dropout_burst_frames", 2)
        if not (1 <= burst[0] <= burst[1]) or any(b != int(b) for b in burst):
            raise sec.error("dropout_burst_frames", f"expected two integers 1 <= min <= max, "
                            f"got {burst}")
        values["dropout_burst_frames"] = (int(burst[0]), int(burst[1]))
    return SynthConfig(**values)


# --- small rotation helpers (matrices; quaternions only at the boundary) -------------------------


def _rot(axis: Array, angle_rad: float) -> Array:
    """Rotation matrix about unit ``axis`` by ``angle_rad`` (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle_rad) * k + (1.0 - math.cos(angle_rad)) * (k @ k)


def _rotvec_mats(rotvecs: Array) -> Array:
    """Rotation matrices (...,3,3) of rotation vectors (...,3) (radians)."""
    v = np.asarray(rotvecs, dtype=float)
    th = np.linalg.norm(v, axis=-1)[..., None, None]
    k = np.zeros((*v.shape[:-1], 3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(th > 1e-12, np.sin(th) / np.where(th > 0, th, 1.0), 1.0)
        c = np.where(th > 1e-12, (1.0 - np.cos(th)) / np.where(th > 0, th * th, 1.0), 0.5)
    return np.eye(3) + s * k + c * (k @ k)


def _frame(x: Array, z_hint: Array) -> Array:
    """Right-handed frame (columns x, y, z) with x along ``x`` and z as close to ``z_hint``."""
    x = np.asarray(x, dtype=float) / np.linalg.norm(x)
    z = np.asarray(z_hint, dtype=float) - (np.dot(z_hint, x)) * x
    z /= np.linalg.norm(z)
    return np.column_stack([x, np.cross(z, x), z])


def _slerp_mat(r0: Array, r1: Array, s: float) -> Array:
    """Rotation a fraction ``s`` of the way from r0 to r1 (geodesic)."""
    q0, q1 = mat_to_quat(r0), mat_to_quat(r1)
    if float(q0 @ q1) < 0.0:
        q1 = -q1
    d = float(np.clip(q0 @ q1, -1.0, 1.0))
    if d > 0.9995:
        q = q0 + s * (q1 - q0)
    else:
        th = math.acos(d)
        q = (math.sin((1 - s) * th) * q0 + math.sin(s * th) * q1) / math.sin(th)
    return quat_to_mat(q / np.linalg.norm(q))


def _min_jerk(s: Array | float) -> Array:
    """Minimum-jerk time scaling 10s³ − 15s⁴ + 6s⁵ (zero velocity and acceleration at the
    ends): how people move between two poses."""
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s)


# --- the human hand -----------------------------------------------------------------------------


@dataclass(frozen=True)
class HandPose:
    """Joint angles of :class:`HumanHand`, radians. fingers: per long finger (abduction, MCP,
    PIP, DIP), flexion positive toward the palm, abduction positive toward the thumb side;
    thumb: (CMC abduction, CMC flexion, MCP, IP)."""

    fingers: dict[str, Array]
    thumb: Array

    def vector(self) -> Array:
        """All angles as one vector (thumb, index, middle, ring, little), for interpolation."""
        return np.concatenate([self.thumb, *(self.fingers[f] for f in LONG_FINGERS)])

    @classmethod
    def from_vector(cls, v: Array) -> HandPose:
        v = np.asarray(v, dtype=float)
        return cls({f: v[4 + 4 * i:8 + 4 * i].copy() for i, f in enumerate(LONG_FINGERS)},
                   v[:4].copy())

    @classmethod
    def relaxed(cls) -> HandPose:
        """A relaxed open hand (fingers slightly curled, thumb beside the index)."""
        return cls({f: np.array([0.0, 0.12, 0.18, 0.10]) for f in LONG_FINGERS},
                   np.array([0.1, 0.1, 0.1, 0.1]))

    @classmethod
    def power(cls) -> HandPose:
        """A closed power grasp (fist around a cylinder), the end of the generic closure."""
        return cls({f: np.array([0.0, 1.1, 1.4, 0.9]) for f in LONG_FINGERS},
                   np.array([0.4, 0.9, 0.6, 0.6]))


def lerp_pose(a: HandPose, b: HandPose, s: float) -> HandPose:
    """Joint-space interpolation, s in [0, 1]."""
    return HandPose.from_vector((1.0 - s) * a.vector() + s * b.vector())


class HumanHand:
    """A parametric adult human hand producing the 26 OpenXR joints (see the module docstring).

    hand_length_m: wrist → middle fingertip of the straight hand (adults ≈ 0.17–0.21 m).
    side: "right" or "left" (mirror image). Positions and orientations come out in the wrist
    frame (:meth:`joints_in_wrist`) or in the world given a wrist pose (:meth:`joints`).
    """

    def __init__(self, hand_length_m: float = 0.185, side: str = "right") -> None:
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        self.side = side
        self.hand_length_m = float(hand_length_m)
        k = self.hand_length_m / REFERENCE_HAND_LENGTH_M
        mirror = np.array([1.0, -1.0 if side == "left" else 1.0, 1.0])
        self._pts = {n: k * np.asarray(p) * mirror for n, p in TEMPLATE_WRIST_M.items()}
        self._lengths = {f: k * np.asarray(v) for f, v in PHALANX_M.items()}
        self._thumb_sign = mirror[1]
        z = np.array([0.0, 0.0, 1.0])
        self._mc_frames: dict[str, Array] = {}
        for f in LONG_FINGERS:
            self._mc_frames[f] = _frame(self._pts[f"{f}_proximal"] - self._pts[f"{f}_metacarpal"],
                                        z)
        d = self._pts["thumb_proximal"] - self._pts["thumb_metacarpal"]
        zt = _rot(d, -self._thumb_sign * THUMB_PRONATION_RAD) @ z
        self._mc_frames["thumb"] = _frame(d, zt)
        self.radii = np.empty(NUM_JOINTS)
        for i, name in enumerate(OPENXR_JOINTS):
            finger, _, kind = name.partition("_")
            self.radii[i] = (TIP_RADII_M[finger] if kind == "tip" else
                             RADII_M.get(kind or finger, RADII_M["distal"]))
        self.radii *= k

    def joints_in_wrist(self, pose: HandPose) -> tuple[Array, Array]:
        """Joint positions (26,3) metres and orientation matrices (26,3,3) in the wrist frame."""
        pos = np.zeros((NUM_JOINTS, 3))
        rot = np.tile(np.eye(3), (NUM_JOINTS, 1, 1))
        for f in LONG_FINGERS:
            a = pose.fingers[f]
            r_mc = self._mc_frames[f]
            base, mcp = self._pts[f"{f}_metacarpal"], self._pts[f"{f}_proximal"]
            # abduction toward the thumb side: about +z for a right hand, −z for a left one
            r_pp = r_mc @ _rot([0, 0, 1], self._thumb_sign * a[0]) @ _rot([0, 1, 0], a[1])
            r_mp = r_pp @ _rot([0, 1, 0], a[2])
            r_dp = r_mp @ _rot([0, 1, 0], a[3])
            lp, lm, ld = self._lengths[f]
            p_pip = mcp + r_pp[:, 0] * lp
            p_dip = p_pip + r_mp[:, 0] * lm
            p_tip = p_dip + r_dp[:, 0] * ld
            for kind, p, r in (("metacarpal", base, r_mc), ("proximal", mcp, r_pp),
                               ("intermediate", p_pip, r_mp), ("distal", p_dip, r_dp),
                               ("tip", p_tip, r_dp)):
                i = JOINT_INDEX[f"{f}_{kind}"]
                pos[i], rot[i] = p, r
        t = pose.thumb
        r_mc = self._mc_frames["thumb"] @ _rot([0, 0, 1], t[0]) @ _rot([0, 1, 0], t[1])
        cmc = self._pts["thumb_metacarpal"]
        l_mc = float(np.linalg.norm(self._pts["thumb_proximal"] - cmc))
        p_mcp = cmc + r_mc[:, 0] * l_mc
        r_pp = r_mc @ _rot([0, 1, 0], t[2])
        r_dp = r_pp @ _rot([0, 1, 0], t[3])
        lp, ld = self._lengths["thumb"]
        p_ip = p_mcp + r_pp[:, 0] * lp
        p_tip = p_ip + r_dp[:, 0] * ld
        for kind, p, r in (("metacarpal", cmc, r_mc), ("proximal", p_mcp, r_pp),
                           ("distal", p_ip, r_dp), ("tip", p_tip, r_dp)):
            i = JOINT_INDEX[f"thumb_{kind}"]
            pos[i], rot[i] = p, r
        im, ip = JOINT_INDEX["middle_metacarpal"], JOINT_INDEX["middle_proximal"]
        pos[JOINT_INDEX["palm"]] = 0.5 * (pos[im] + pos[ip])
        rot[JOINT_INDEX["palm"]] = rot[im]
        return pos, rot

    def joints(self, pose: HandPose, wrist_pos_m: Array,
               wrist_rot: Array) -> tuple[Array, Array]:
        """Joint positions (26,3) metres and orientation matrices (26,3,3) in the world, for
        the wrist frame at ``wrist_pos_m`` with axes ``wrist_rot`` (columns)."""
        pos, rot = self.joints_in_wrist(pose)
        return wrist_pos_m + pos @ wrist_rot.T, np.einsum("ij,njk->nik", wrist_rot, rot)

    def tip(self, pose: HandPose, finger: str) -> Array:
        """One fingertip joint in the wrist frame (metres)."""
        return self.joints_in_wrist(pose)[0][JOINT_INDEX[f"{finger}_tip"]]

    def chain_length_m(self, finger: str = "middle") -> float:
        """Bone-chain length wrist → ``finger`` tip (what ``Retargeter.calibrate_scale``
        measures; independent of the pose)."""
        pos, _ = self.joints_in_wrist(HandPose.relaxed())
        names = ["wrist", *(n for n in OPENXR_JOINTS if n.startswith(f"{finger}_"))]
        pts = pos[[JOINT_INDEX[n] for n in names]]
        return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())

    def fit_finger(self, finger: str, target_wrist_m: Array, start: HandPose) -> tuple[Array, float]:
        """Joint angles (4,) of ``finger`` that put its tip joint nearest ``target_wrist_m``
        (wrist frame, metres), within human limits, with a weak prior toward DIP ≈ 0.7·PIP
        (fingers) and small angles; also the remaining distance (metres)."""
        from scipy.optimize import least_squares

        lo, hi = THUMB_LIMITS if finger == "thumb" else FINGER_LIMITS
        x0 = np.clip(start.thumb if finger == "thumb" else start.fingers[finger], lo, hi)
        prior_w = 0.002  # metres of tip error worth one radian of prior violation

        def pose_of(x: Array) -> HandPose:
            if finger == "thumb":
                return replace(start, thumb=x)
            return replace(start, fingers={**start.fingers, finger: x})

        def residual(x: Array) -> Array:
            err = self.tip(pose_of(x), finger) - target_wrist_m
            prior = (np.array([x[0], 0.0, 0.0, 0.0]) if finger == "thumb"
                     else np.array([x[0], x[3] - 0.7 * x[2], 0.0, 0.0]))
            return np.concatenate([err, prior_w * prior])

        sol = least_squares(residual, x0, bounds=(lo, hi), xtol=1e-10, ftol=1e-10)
        x = sol.x
        return x, float(np.linalg.norm(self.tip(pose_of(x), finger) - target_wrist_m))


# --- the episode --------------------------------------------------------------------------------


@dataclass
class SynthEpisode:
    """A synthetic grasp episode.

    frames: the tracking frames (MuJoCo world, valid per :func:`teleop.messages.validate`).
    grasp_time_s: device time of the grasp moment (fingers closed, before the lift).
    phases: phase name → (start, end) device time, seconds. object_name, object_pos_m,
    object_quat_wxyz: the object and its world pose before the lift. reference_grasp: the name
    of the reference grasp imitated (None: generic side grasp). grasp_wrist_pos_m /
    grasp_wrist_quat_wxyz: the operator wrist pose at the grasp (noise-free).
    target_palm_pos_m / target_palm_quat_wxyz: where the retargeted robot palm should be at
    the grasp (world). fit_residual_m: per human finger, how far its tip stays from the
    position that maps onto the wanted robot fingertip (metres, operator scale); for a generic
    grasp instead ``mean_surface_m``, the mean distance of the mapped fingertips to the surface.
    Phases: still, approach, close (the grasp mark at its end), grasp (fingers closed, object
    not yet moved), lift, hold, release, retreat, end.
    tracked: per frame, whether the hand is tracked. side: the operator hand.
    """

    frames: list[HandFrame]
    grasp_time_s: float
    phases: dict[str, tuple[float, float]]
    object_name: str
    object_pos_m: Array
    object_quat_wxyz: Array
    reference_grasp: str | None
    grasp_wrist_pos_m: Array
    grasp_wrist_quat_wxyz: Array
    target_palm_pos_m: Array
    target_palm_quat_wxyz: Array
    fit_residual_m: dict[str, float]
    tracked: Array
    side: str
    seed: int
    metadata: dict[str, Any] = field(default_factory=dict)


def _rpy_mat(rpy_deg: Sequence[float]) -> Array:
    """Fixed-axis x, y, z rotation (degrees) as a matrix."""
    r, p, y = np.radians(np.asarray(rpy_deg, dtype=float))
    return _rot([0, 0, 1], y) @ _rot([0, 1, 0], p) @ _rot([1, 0, 0], r)


def dropout_mask(n_frames: int, rng: np.random.Generator, fraction: float,
                 burst_frames: tuple[int, int]) -> Array:
    """Boolean (n,) True where the hand is *tracked*. Bursts of lost tracking start with
    probability p per tracked frame and last a uniform number of frames in ``burst_frames``;
    p = f / (L (1 − f)) with L the mean burst length makes the long-run untracked fraction f
    (a tracked run lasts 1/p frames on average, then a burst of L)."""
    tracked = np.ones(n_frames, dtype=bool)
    if fraction <= 0.0 or n_frames == 0:
        return tracked
    lo, hi = burst_frames
    mean_len = 0.5 * (lo + hi)
    p = min(fraction / (mean_len * (1.0 - fraction)), 1.0)
    starts = rng.random(n_frames) < p
    lengths = rng.integers(lo, hi + 1, n_frames)
    i = 0
    while i < n_frames:
        if starts[i]:
            tracked[i:i + lengths[i]] = False
            i += int(lengths[i])
        else:
            i += 1
    return tracked


class _Correspondence:
    """The retargeter's wrist correspondence for one robot hand, used inversely: where the
    operator's wrist must be for the robot palm to land on a pose, and where an operator
    fingertip must be for the robot pulp site to land on a point (see teleop.retarget.retargeter)."""

    def __init__(self, hand: Hand, config_path: Path | str | None) -> None:
        cfg = load_retarget_config(config_path)
        self.config = cfg
        self.mapping = cfg.hand(hand.name)
        # palm ← operator wrist: rotation (columns: wrist axes in frame_palm) and origin
        self.r_pw = WRIST_TO_PALM_CONVENTION @ quat_to_mat(self.mapping.wrist_quat_wxyz)
        self.p_pw = np.asarray(self.mapping.wrist_pos_m, dtype=float)
        tips_open = hand.fingertip_sites(hand.open_pose, frame="palm")[0]
        self.robot_length_m = float(np.linalg.norm(
            tips_open[hand.finger_names.index(self.mapping.scale_finger)] - self.p_pw))

    def scale(self, operator_length_m: float) -> float:
        return self.robot_length_m / operator_length_m * self.config.scale

    def wrist_for_palm(self, palm_pos_m: Array, palm_rot: Array) -> tuple[Array, Array]:
        """Operator wrist (tracking-space position, metres; axes) that puts frame_palm at
        (palm_pos_m, palm_rot) in the world."""
        r_w = palm_rot @ self.r_pw
        wrist_world = palm_pos_m + palm_rot @ self.p_pw
        return (wrist_world - self.config.world_offset_m) / self.config.wrist_position_scale, r_w

    def operator_tip_for(self, tip_palm_m: Array, scale: float) -> Array:
        """Operator fingertip (wrist frame, metres) that maps onto robot point ``tip_palm_m``
        (frame_palm) before the pinch adjustment."""
        return self.r_pw.T @ (np.asarray(tip_palm_m) - self.p_pw) / scale


def _reference_for(hand: Hand, object_name: str, grasp_name: str | None) -> Any:
    from sim.hand.reference_grasps import load_reference_grasps

    try:
        refs = load_reference_grasps(hand)
    except ConfigError as exc:
        logger.info("no reference grasps for %s (%s): generic grasp", hand.name, exc)
        return None
    for ref in refs:
        if (grasp_name is None and ref.object == object_name) or ref.name == grasp_name:
            return ref
    if grasp_name is not None:
        raise ConfigError(f"no reference grasp {grasp_name!r} for hand {hand.name!r} "
                          f"(have {[r.name for r in refs]})")
    return None


def closest_surface_points(mesh: Any, points_m: Array) -> tuple[Array, Array]:
    """Closest points (n,3) on a triangle mesh to points (n,3) (same frame, metres) and the
    signed distances (n,): exact over all triangles (trimesh's per-triangle routine, so no
    rtree is needed), negative where a point lies behind the closest triangle's outward
    normal (inside the object)."""
    from trimesh.triangles import closest_point

    tris = np.asarray(mesh.triangles)
    normals = np.asarray(mesh.face_normals)
    pts = np.asarray(points_m, dtype=float).reshape(-1, 3)
    closest = np.empty_like(pts)
    signed = np.empty(len(pts))
    for i, p in enumerate(pts):
        c = closest_point(tris, np.broadcast_to(p, (len(tris), 3)))
        d = np.linalg.norm(c - p, axis=1)
        j = int(np.argmin(d))
        closest[i] = c[j]
        signed[i] = d[j] if float((p - c[j]) @ normals[j]) >= 0.0 else -d[j]
    return closest, signed


def surface_distance_m(mesh: Any, points_m: Array) -> Array:
    """Signed distance (n,) metres from points (n,3) to a mesh (see
    :func:`closest_surface_points`)."""
    return closest_surface_points(mesh, points_m)[1]


def _generic_grasp(human: HumanHand, corr: _Correspondence, scale: float, object_name: str,
                   obj_pos: Array, obj_rot: Array) -> tuple[Array, Array, HandPose, dict[str, float]]:
    """Side grasp without a reference: palm facing the object's centre from −x (world),
    fingers up; the closure level whose mapped fingertips lie closest to the surface."""
    from sim.world.objects import load_object

    mesh = load_object(object_name).surface_mesh()
    lo, hi = mesh.bounds
    centre_w = obj_pos + obj_rot @ (0.5 * (lo + hi))
    verts_w = mesh.vertices @ obj_rot.T + obj_pos
    reach = float(np.max(centre_w[0] - verts_w[:, 0]))
    # frame_palm: +y (palm normal) toward +x world, +z (fingers) up, x = y × z
    palm_rot = np.column_stack([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    palm_pos = centre_w - np.array([reach + 0.015, 0.0, 0.03])
    wrist_pos, wrist_rot = corr.wrist_for_palm(palm_pos, palm_rot)
    best: tuple[float, HandPose] | None = None
    for s in np.linspace(0.0, 1.0, 21):
        pose = lerp_pose(HandPose.relaxed(), HandPose.power(), float(s))
        pos, _ = human.joints_in_wrist(pose)
        tips_op = pos[[JOINT_INDEX[f"{f}_tip"] for f in FINGERS]]
        tips_palm = corr.p_pw + scale * tips_op @ corr.r_pw.T
        tips_o = (palm_pos + tips_palm @ palm_rot.T - obj_pos) @ obj_rot
        cost = float(np.mean(np.abs(surface_distance_m(mesh, tips_o))))
        if best is None or cost < best[0]:
            best = (cost, pose)
    assert best is not None
    logger.info("generic grasp on %s: mean mapped fingertip distance %.4f m", object_name,
                best[0])
    return wrist_pos, wrist_rot, best[1], {"mean_surface_m": best[0]}


def synthesize(object_name: str, *, hand: Hand | str = "shadow_right", seed: int = 0,
               config: SynthConfig | None = None, object_pos_m: Sequence[float] | None = None,
               object_quat_wxyz: Sequence[float] | None = None, grasp_name: str | None = None,
               retarget_config: Path | str | None = None) -> SynthEpisode:
    """Synthesize one grasp episode of ``object_name`` for robot hand ``hand``.

    The operator hand side and the wrist correspondence come from ``[retarget.hands.<hand>]``
    (``retarget_config``: another teleop.toml); the robot grasp imitated is the hand's
    reference grasp for the object (or ``grasp_name``), else a generic side grasp. The object
    stands at ``object_pos_m`` / ``object_quat_wxyz`` (world; default from the config).
    Deterministic per ``seed``.
    """
    cfg = config or load_synth_config()
    robot = Hand.load(hand) if isinstance(hand, str) else hand
    corr = _Correspondence(robot, retarget_config)
    side = corr.mapping.side
    human = HumanHand(cfg.hand_length_m, side)
    scale = corr.scale(human.chain_length_m(_finger_of(corr.mapping.fingers[
        corr.mapping.scale_finger])))
    obj_pos = np.asarray(object_pos_m if object_pos_m is not None else cfg.object_pos_m, float)
    obj_rot = (quat_to_mat(np.asarray(object_quat_wxyz, float) /
                           np.linalg.norm(object_quat_wxyz)) if object_quat_wxyz is not None
               else _rpy_mat(cfg.object_rpy_deg))

    ref = _reference_for(robot, object_name, grasp_name)
    residual: dict[str, float] = {}
    if ref is not None:
        palm_rot = obj_rot @ quat_to_mat(ref.grasp.palm_quat_wxyz)
        palm_pos = obj_pos + obj_rot @ ref.grasp.palm_pos
        wrist_pos, wrist_rot = corr.wrist_for_palm(palm_pos, palm_rot)
        tips_palm = robot.fingertip_sites(ref.grasp.joints, frame="palm")[0]
        if cfg.tip_surface_snap_m > 0.0:
            tips_palm = _snap_tips(tips_palm, object_name, ref.grasp.palm_pos,
                                   quat_to_mat(ref.grasp.palm_quat_wxyz), cfg.tip_surface_snap_m)
        grasp_pose = HandPose.relaxed()
        for k, robot_finger in enumerate(robot.finger_names):
            joint = corr.mapping.fingers.get(robot_finger)
            if joint is None:
                continue
            finger = _finger_of(joint)
            target = corr.operator_tip_for(tips_palm[k], scale)
            x, res = human.fit_finger(finger, target, grasp_pose)
            grasp_pose = (replace(grasp_pose, thumb=x) if finger == "thumb" else
                          replace(grasp_pose, fingers={**grasp_pose.fingers, finger: x}))
            residual[finger] = res
        _fill_unmapped(grasp_pose, corr.mapping.fingers.values())
        logger.info("reference grasp %s: human fingertip fit residuals (m) %s", ref.name,
                    {k: round(v, 4) for k, v in residual.items()})
    else:
        wrist_pos, wrist_rot, grasp_pose, residual = _generic_grasp(
            human, corr, scale, object_name, obj_pos, obj_rot)
        palm_rot = wrist_rot @ corr.r_pw.T
        palm_pos = (wrist_pos * corr.config.wrist_position_scale + corr.config.world_offset_m
                    - palm_rot @ corr.p_pw)

    # --- trajectory (noise-free), sampled at the frame times
    phases, t_end = _phases(cfg)
    rng = np.random.default_rng(seed)
    n = math.floor(t_end * cfg.rate_hz) + 1
    t_nom = np.arange(n) / cfg.rate_hz
    # palm normal (+y of frame_palm) points at the object: back off against it, and up
    away = -palm_rot[:, 1] + np.array([0.0, 0.0, 0.5])
    away /= np.linalg.norm(away)
    start_pos = wrist_pos + cfg.approach_distance_m * away
    start_rot = _rot([0, 0, 1], 0.35) @ wrist_rot @ _rot([1, 0, 0], -0.3)
    lift = np.array([0.0, 0.0, cfg.lift_height_m])
    open_pose = HandPose.relaxed()

    def at(t: float) -> tuple[Array, Array, HandPose]:
        def s(name: str) -> float:
            a, b = phases[name]
            return float(_min_jerk((t - a) / (b - a))) if b > a else float(t >= b)

        p = start_pos + s("approach") * (wrist_pos - start_pos)
        r = _slerp_mat(start_rot, wrist_rot, s("approach"))
        p = p + s("lift") * lift
        p = p + s("retreat") * cfg.approach_distance_m * away
        closure = s("close") * (1.0 - s("release"))
        return p, r, lerp_pose(open_pose, grasp_pose, closure)

    tracked = dropout_mask(n, rng, cfg.dropout_fraction, cfg.dropout_burst_frames)
    jitter = np.clip(rng.normal(0.0, cfg.time_jitter_s, n), -0.4 / cfg.rate_hz,
                     0.4 / cfg.rate_hz)
    t0 = 10.0  # device clock at the first frame (seconds; any epoch works)
    t_dev = t0 + t_nom + jitter
    t_recv = t_dev + cfg.latency_s + np.abs(rng.normal(0.0, cfg.latency_jitter_s, n))
    head_pos = np.asarray(cfg.head_pos_m, float)
    head_q = mat_to_quat(_rot([0, 1, 0], math.radians(cfg.head_pitch_deg)))
    sigma_rot = math.radians(cfg.orientation_noise_deg)
    frames: list[HandFrame] = []
    for i in range(n):
        # noise is drawn for every frame, tracked or not, so that the dropout pattern does
        # not shift the noise of later frames (frames stay comparable across dropout settings)
        pos_noise = rng.normal(0.0, cfg.position_noise_m, (NUM_JOINTS, 3))
        rot_noise = rng.normal(0.0, sigma_rot, (NUM_JOINTS, 3))
        head_noise = rng.normal(0.0, 0.001, 3)
        if tracked[i]:
            p_w, r_w, pose = at(float(t_nom[i]))
            pos, rot = human.joints(pose, p_w, r_w)
            rot = np.einsum("nij,njk->nik", _rotvec_mats(rot_noise), rot)
            state = HandState(pos + pos_noise, mat_to_quat(rot), human.radii.copy(),
                              np.ones(NUM_JOINTS, bool), tracked=True)
        else:
            state = HandState.untracked()
        frames.append(HandFrame(
            seq=i, device_time_s=float(t_dev[i]), receive_time_s=float(t_recv[i]),
            head_position=head_pos + head_noise, head_orientation_wxyz=head_q,
            left=state if side == "left" else None, right=state if side == "right" else None,
            source=f"synth:{object_name}:seed{seed}"))
    grasp_time = t0 + phases["close"][1]
    logger.info("synthesized %d frames (%.1f s, %d untracked) of %s grasping %s", n, t_end,
                int((~tracked).sum()), side, object_name)
    return SynthEpisode(
        frames=frames, grasp_time_s=grasp_time,
        phases={k: (t0 + a, t0 + b) for k, (a, b) in phases.items()}, object_name=object_name,
        object_pos_m=obj_pos, object_quat_wxyz=mat_to_quat(obj_rot),
        reference_grasp=None if ref is None else ref.name, grasp_wrist_pos_m=wrist_pos,
        grasp_wrist_quat_wxyz=mat_to_quat(wrist_rot), target_palm_pos_m=palm_pos,
        target_palm_quat_wxyz=mat_to_quat(palm_rot), fit_residual_m=residual, tracked=tracked,
        side=side, seed=seed,
        metadata={"hand": robot.name, "object": object_name, "synthetic": True, "seed": seed,
                  "reference_grasp": None if ref is None else ref.name, "side": side,
                  "object_pos_m": obj_pos.tolist(),
                  "object_quat_wxyz": mat_to_quat(obj_rot).tolist(),
                  "joint_names": list(robot.joint_names),
                  "fingers": list(robot.finger_names)})


def _snap_tips(tips_palm: Array, object_name: str, palm_pos_obj: Array, palm_rot_obj: Array,
               max_gap_m: float) -> Array:
    """Reference pulp sites (frame_palm) within ``max_gap_m`` of the object's surface moved
    onto it (closest point). Why: hand-built reference grasps touch the object with whatever
    part of the finger met it first, so their pulp sites sit up to ~1.5 cm off the surface;
    an operator grasping the object puts the finger *pads* on it. Fingers farther away (the
    reference's unused fingers) keep their place."""
    from sim.world.objects import load_object

    mesh = load_object(object_name).surface_mesh()
    tips_obj = palm_pos_obj + tips_palm @ palm_rot_obj.T
    closest, signed = closest_surface_points(mesh, tips_obj)
    snap = np.abs(signed) <= max_gap_m
    tips_obj = np.where(snap[:, None], closest, tips_obj)
    logger.info("reference pulp sites off the surface (m): %s; snapped: %s",
                np.round(signed, 4).tolist(), snap.tolist())
    return (tips_obj - palm_pos_obj) @ palm_rot_obj


def _finger_of(openxr_joint: str) -> str:
    """"index_tip" → "index"."""
    return openxr_joint.split("_", 1)[0]


def _fill_unmapped(pose: HandPose, mapped_joints: Any) -> None:
    """Long fingers no robot finger follows curl like the mean of the mapped ones."""
    mapped = {_finger_of(j) for j in mapped_joints}
    used = [pose.fingers[f] for f in LONG_FINGERS if f in mapped]
    if not used:
        return
    mean = np.mean(used, axis=0)
    for f in LONG_FINGERS:
        if f not in mapped:
            pose.fingers[f] = mean.copy()


def _phases(cfg: SynthConfig) -> tuple[dict[str, tuple[float, float]], float]:
    """Phase name → (start, end) seconds from the episode start, and the total duration."""
    order = (("still", cfg.still_s), ("approach", cfg.approach_s), ("close", cfg.close_s),
             ("grasp", cfg.settle_s), ("lift", cfg.lift_s), ("hold", cfg.hold_s),
             ("release", cfg.release_s), ("retreat", cfg.retreat_s), ("end", 0.3))
    out, t = {}, 0.0
    for name, dur in order:
        out[name] = (t, t + dur)
        t += dur
    return out, t


# --- writing ------------------------------------------------------------------------------------


def write_session(frames: Sequence[HandFrame] | SynthEpisode, path: Path | str,
                  metadata: Mapping[str, Any] | None = None, *,
                  grasp_time_s: float | None = None, overwrite: bool = False) -> Path:
    """Write a synthetic session as MCAP with :class:`teleop.record.recorder.SessionRecorder`:
    ``/hands`` (every frame, logged at its receive time) and ``/events`` (``grasp_mark`` at
    ``grasp_time_s``, device clock; taken from the episode when one is given). Log times are
    the frames' receive times on a fixed epoch, so the file is identical for equal inputs
    apart from the recorder's own creation metadata."""
    from teleop.record.recorder import SessionRecorder

    meta: dict[str, Any] = {}
    if isinstance(frames, SynthEpisode):
        meta.update(frames.metadata)
        if grasp_time_s is None:
            grasp_time_s = frames.grasp_time_s
        frame_list = list(frames.frames)
    else:
        frame_list = list(frames)
    meta.update(metadata or {})
    if not frame_list:
        raise ValueError("no frames to write")
    epoch_ns = 1_700_000_000 * 10**9
    t_first = frame_list[0].receive_time_s

    def log_ns(t_s: float) -> int:
        return epoch_ns + round((t_s - t_first) * 1e9)

    path = Path(path)
    with SessionRecorder(path, metadata=meta, overwrite=overwrite,
                         start_time_ns=epoch_ns) as rec:
        marked = grasp_time_s is None
        for frame in frame_list:
            if not marked and frame.device_time_s >= grasp_time_s:
                rec.write_event("grasp_mark", {"source": "synth", "device_time_s": grasp_time_s},
                                log_time_ns=log_ns(frame.receive_time_s))
                marked = True
            rec.write_hands(frame, log_time_ns=log_ns(frame.receive_time_s))
    logger.info("wrote %d synthetic frames to %s", len(frame_list), path)
    return path
