"""A parametric adult human hand producing the 26 OpenXR joints: :class:`HumanHand`, its joint
angles :class:`HandPose`, and the anthropometric constants they are built from.

Why a model, not a recording: the synthetic operator must put a fingertip exactly where the
retargeter maps it onto a robot grasp, which needs a hand whose joint angles can be solved for
(:meth:`HumanHand.fit_finger`) and whose size can be changed.

26 OpenXR joints (PALM first). The geometry (joint positions of a straight-ish adult right hand
in the wrist frame, bone lengths, joint radii) is :data:`TEMPLATE_WRIST_M`, taken from
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

Units: metres, radians.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from sim.transforms import axis_angle_to_mat, frame_from_x
from teleop.messages import JOINT_INDEX, NUM_JOINTS, OPENXR_JOINTS

__all__ = ["FINGERS", "FINGER_LIMITS", "LONG_FINGERS", "PHALANX_M", "RADII_M",
           "REFERENCE_HAND_LENGTH_M", "TEMPLATE_WRIST_M", "THUMB_LIMITS", "THUMB_PRONATION_RAD",
           "TIP_RADII_M", "HandPose", "HumanHand", "finger_of", "lerp_pose"]

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

_Y_AXIS = np.array([0.0, 1.0, 0.0])
_Z_AXIS = np.array([0.0, 0.0, 1.0])


def _rotations(axis: Array, angles_rad: ArrayLike) -> Array:
    """Rotation matrices (n,3,3) about one unit ``axis`` by each of ``angles_rad`` (n,)."""
    angles = np.asarray(angles_rad, dtype=float)
    return axis_angle_to_mat(np.broadcast_to(axis, (len(angles), 3)), angles)


def finger_of(openxr_joint: str) -> str:
    """"index_tip" → "index"."""
    return openxr_joint.split("_", 1)[0]


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
        self._mc_frames: dict[str, Array] = {}
        for f in LONG_FINGERS:
            self._mc_frames[f] = frame_from_x(
                self._pts[f"{f}_proximal"] - self._pts[f"{f}_metacarpal"], _Z_AXIS)
        d = self._pts["thumb_proximal"] - self._pts["thumb_metacarpal"]
        zt = _rotations(d / np.linalg.norm(d), [-self._thumb_sign * THUMB_PRONATION_RAD])[0] @ _Z_AXIS
        self._mc_frames["thumb"] = frame_from_x(d, zt)
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
        angles = np.array([pose.fingers[f] for f in LONG_FINGERS])   # (4, 4)
        t = pose.thumb
        # abduction toward the thumb side: about +z for a right hand, −z for a left one (the
        # thumb's CMC abduction: about +z for both); flexion about +y. Rows: the long fingers,
        # then the thumb; flexion rows are MCP, PIP, DIP per long finger, then the thumb's three.
        abd = _rotations(_Z_AXIS, [*(self._thumb_sign * angles[:, 0]), t[0]])
        flex = _rotations(_Y_AXIS, [*angles[:, 1:].ravel(), *t[1:]])
        for k, f in enumerate(LONG_FINGERS):
            r_mc = self._mc_frames[f]
            base, mcp = self._pts[f"{f}_metacarpal"], self._pts[f"{f}_proximal"]
            r_pp = r_mc @ abd[k] @ flex[3 * k]
            r_mp = r_pp @ flex[3 * k + 1]
            r_dp = r_mp @ flex[3 * k + 2]
            lp, lm, ld = self._lengths[f]
            p_pip = mcp + r_pp[:, 0] * lp
            p_dip = p_pip + r_mp[:, 0] * lm
            p_tip = p_dip + r_dp[:, 0] * ld
            for kind, p, r in (("metacarpal", base, r_mc), ("proximal", mcp, r_pp),
                               ("intermediate", p_pip, r_mp), ("distal", p_dip, r_dp),
                               ("tip", p_tip, r_dp)):
                i = JOINT_INDEX[f"{f}_{kind}"]
                pos[i], rot[i] = p, r
        r_mc = self._mc_frames["thumb"] @ abd[4] @ flex[12]
        cmc = self._pts["thumb_metacarpal"]
        l_mc = float(np.linalg.norm(self._pts["thumb_proximal"] - cmc))
        p_mcp = cmc + r_mc[:, 0] * l_mc
        r_pp = r_mc @ flex[13]
        r_dp = r_pp @ flex[14]
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
