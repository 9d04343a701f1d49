"""Retarget an operator's tracked hand (:class:`teleop.messages.HandState`) to a robot hand.

Why this shape: teleop drives a *floating* robot hand, so the problem splits cleanly in two.
The hand's base pose is not solved for at all: it is placed so that the robot's wrist follows
the operator's wrist (position and orientation, with a configurable offset and motion scale).
Only the finger joints are solved, by differential IK with mink on the hand-only model
(``Hand.model``, fixed base), one position-only ``FrameTask`` per fingertip pulp site, a
``PostureTask`` toward the hand's open pose, a ``ConfigurationLimit`` and solver ``daqp``,
warm-started from the previous frame (DESIGN §6). Everything hand-specific (which operator joint
drives which robot finger, where the operator's wrist sits in the robot's palm frame, which side)
lives in ``configs/teleop.toml`` ``[retarget]``; nothing here names a hand.

Frames and correspondence
    The operator's OpenXR WRIST joint frame (after ingest: +x distal along the hand, +z out of
    the back of the hand, see :mod:`teleop.input.frames`) is mapped onto the robot's ``frame_palm``
    (DESIGN §3 and every hand config: +y the palm normal out of the pulp side, +z toward the
    fingers, x = y × z) by the
    convention rotation ``x_wrist → z_palm, y_wrist → −x_palm, z_wrist → −y_palm``, then by the
    per-hand extra rotation ``wrist_rpy_deg``; the operator's wrist point lands on the per-hand
    point ``wrist_pos_m`` of frame_palm (for the Shadow Hand, its wrist joint). Fingertips are
    taken relative to the operator's wrist in that frame, scaled by ``scale`` about the wrist
    point, and become targets in the hand's base frame.

Scale calibration (:meth:`Retargeter.calibrate_scale`)
    scale = robot length / operator length × ``scale`` (config). The robot length is the
    straight-line distance from ``wrist_pos_m`` to the pulp site of ``scale_finger`` at the
    open pose (fingers straight). The operator length is the sum of the bone lengths from the
    wrist through that finger's OpenXR chain to its tip joint, median over the frames: unlike
    the wrist-to-tip distance, a bone chain does not change when the operator curls the finger,
    so any stretch of tracking calibrates, not only flat-hand frames. Palm width was rejected:
    it is short (≈ 8 cm), so tracking noise weighs more than twice as much, and the hand
    configs name no knuckle points to measure it on the robot.

Pinch-aware mapping
    Tracked tip joints sit at the *centre* of the fingertip (OpenXR radius ≈ 7–9 mm to the skin)
    while the robot's targets are pulp *surface* points, so pure scaling leaves a touching pinch
    about two radii apart on the robot (≈ 1.6 cm). Below ``pinch_release_gap_m`` of skin gap
    (tip distance minus both radii) between the thumb and a finger, their targets are pulled
    together symmetrically: the target distance is d − w·(r_thumb + r_finger) with
    w = 1 − gap / release, which is continuous and monotonic in d, equals d at the release gap
    and becomes the skin gap (0 when touching) as the fingers close. This is the usual
    "pinch snapping" of teleop retargeters, made radius-aware instead of using fixed distances.
    The thumb is the robot finger driven by OpenXR ``thumb_tip``. Moving the absolute targets
    is not enough: the operator's thumb often sits where the robot's thumb cannot go, and the
    IK then parks the thumb at a joint limit ~2 cm from the finger. So while a pair pinches, a
    thumb–finger *distance* task (cost ``pinch_cost`` × w) makes the IK favour the pinch over
    the absolute positions (DexPilot's idea); a distance, not a vector, leaves the approach
    direction to the robot's own pinch geometry.

Solver settings
    One IK iteration per frame suffices with warm starting (2–3 change the errors by < 0.5 mm
    on the Quest capture, see ``benchmarks/bench_retarget.py``) and keeps the median step near
    0.5 ms on one core. ``damping`` (1e-3, Levenberg–Marquardt on Δq) is what makes one
    full Gauss–Newton step per frame stable: with 1e-6 the thumb limit-cycles between two
    poses around a pinch instead of converging.

Coupled joints
    Coupled joints (Shadow FJ1 = FJ2, from the hand config's ``coupled_to``) are linear
    equality constraints of the QP (``constraints=``), so every IK step already moves the pair
    together and the fingertip tasks are solved *with* the coupling instead of being broken by
    it afterwards; ``Hand.fill_coupled`` then removes the last floating-point drift. Joints of no
    finger (the Shadow wrist) are frozen at the open pose with mink's ``DofFreezingTask``: the
    floating base already provides the wrist pose, and letting the IK bend the wrist would move
    the palm away from the operator's.

Missing data
    A frame without the hand, an untracked hand, invalid or non-finite wrist/fingertip joints
    or a failed QP solve hold the last output (``held=True``) and count the reason
    (:attr:`Retargeter.held_counts`); nothing raises in the tracking loop.

Quaternions are wxyz everywhere here; positions metres; joint values radians.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import mink
import mujoco
import numpy as np

from sim.config import Section, load_toml
from sim.errors import ConfigError, DexaugError
from sim.hand.model import Hand
from sim.paths import CONFIG_DIR
from sim.transforms import axis_angle_to_quat, mat_to_quat, pose_inv, pose_mul, quat_mul
from teleop.messages import JOINT_INDEX, OPENXR_JOINTS, WRIST, HandFrame, HandState

logger = logging.getLogger(__name__)

Array = np.ndarray

TELEOP_CONFIG = CONFIG_DIR / "teleop.toml"

#: Operator wrist axes expressed in frame_palm (columns: x, y, z of the wrist frame):
#: x_wrist (distal) → z_palm, y_wrist → −x_palm, z_wrist (dorsal) → −y_palm.
WRIST_TO_PALM_CONVENTION: Array = np.array([[0.0, -1.0, 0.0],
                                            [0.0, 0.0, -1.0],
                                            [1.0, 0.0, 0.0]])
WRIST_TO_PALM_CONVENTION.setflags(write=False)

#: Why a frame was held (the keys of :attr:`Retargeter.held_counts`).
HOLD_REASONS = ("no_hand", "untracked", "invalid_joints", "solver_failed")


class RetargetError(DexaugError):
    """Retargeting cannot proceed (e.g. no usable frame to calibrate the scale from)."""


# --- configuration --------------------------------------------------------------------------


@dataclass(frozen=True)
class HandMapping:
    """``[retarget.hands.<hand>]``: how one robot hand is driven.

    side: the operator hand ("left"/"right"). fingers: robot finger name → OpenXR joint name.
    scale_finger: the robot finger whose wrist→pulp length calibrates the scale. wrist_pos_m:
    the operator's wrist point in the robot's frame_palm (metres). wrist_quat_wxyz: extra
    rotation of the operator's wrist frame before the convention map (from ``wrist_rpy_deg``).
    """

    hand: str
    side: str
    fingers: dict[str, str]
    scale_finger: str
    wrist_pos_m: Array
    wrist_quat_wxyz: Array
    where: str


@dataclass(frozen=True)
class RetargetConfig:
    """``configs/teleop.toml`` ``[retarget]`` (see the file for what each key does)."""

    file: Path
    solver: str
    iterations: int
    dt_s: float
    fingertip_cost: float
    posture_cost: float
    task_lm_damping: float
    damping: float
    limit_gain: float
    filter_time_constant_s: float | None
    filter_alpha: float | None
    scale: float
    operator_hand_length_m: float
    wrist_position_scale: float
    world_offset_m: Array
    pinch_release_gap_m: float
    pinch_cost: float
    hands: dict[str, HandMapping] = field(default_factory=dict)

    def hand(self, name: str) -> HandMapping:
        """The mapping of robot hand ``name``; a missing table is a ConfigError naming it."""
        try:
            return self.hands[name]
        except KeyError:
            raise ConfigError(f"{self.file}: retarget.hands.{name}: missing table (no "
                              f"retargeting mapping for hand {name!r}; configured: "
                              f"{sorted(self.hands)})") from None


_RETARGET_KEYS = {"solver", "iterations", "dt_s", "fingertip_cost", "posture_cost",
                  "task_lm_damping", "damping", "limit_gain", "filter_time_constant_s",
                  "filter_alpha", "scale", "operator_hand_length_m", "wrist_position_scale",
                  "world_offset_m", "pinch_release_gap_m", "pinch_cost", "hands"}
_HAND_KEYS = {"side", "fingers", "scale_finger", "wrist_pos_m", "wrist_rpy_deg"}


def _rpy_deg_to_quat_wxyz(rpy_deg: Sequence[float]) -> Array:
    """Rotation about fixed x, then y, then z (degrees) as a wxyz quaternion."""
    rx, ry, rz = np.deg2rad(np.asarray(rpy_deg, dtype=float))
    qx = axis_angle_to_quat(np.array([1.0, 0.0, 0.0]), rx)
    qy = axis_angle_to_quat(np.array([0.0, 1.0, 0.0]), ry)
    qz = axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), rz)
    return quat_mul(qz, quat_mul(qy, qx))


def _hand_mapping(name: str, sec: Section) -> HandMapping:
    sec.reject_unknown(_HAND_KEYS)
    side = sec.str("side")
    if side not in ("left", "right"):
        raise sec.error("side", f"expected 'left' or 'right', got {side!r}")
    fingers_sec = sec.section("fingers")
    fingers: dict[str, str] = {}
    for finger in fingers_sec.data:
        joint = fingers_sec.str(finger)
        if joint not in JOINT_INDEX or joint in ("palm", "wrist"):
            raise fingers_sec.error(finger, f"unknown OpenXR finger joint {joint!r}; expected "
                                    f"one of {list(OPENXR_JOINTS[2:])}")
        fingers[finger] = joint
    if not fingers:
        raise fingers_sec.error(None, "expected at least one finger = \"<openxr joint>\"")
    if len(set(fingers.values())) != len(fingers):
        raise fingers_sec.error(None, "two robot fingers are driven by the same OpenXR joint")
    scale_finger = sec.str("scale_finger")
    if scale_finger not in fingers:
        raise sec.error("scale_finger", f"{scale_finger!r} is not one of the mapped fingers "
                        f"{sorted(fingers)}")
    return HandMapping(hand=name, side=side, fingers=fingers, scale_finger=scale_finger,
                       wrist_pos_m=np.array(sec.floats("wrist_pos_m", 3)),
                       wrist_quat_wxyz=_rpy_deg_to_quat_wxyz(
                           sec.floats("wrist_rpy_deg", 3, [0.0, 0.0, 0.0])),
                       where=sec.where())


def load_retarget_config(path: Path | str | None = None) -> RetargetConfig:
    """Read and check ``[retarget]`` of ``configs/teleop.toml`` (or ``path``).

    Other top-level tables of the file belong to other loaders and are ignored here; unknown
    keys inside ``[retarget]`` are refused (a typo would otherwise silently use a default).
    Errors are :class:`ConfigError` naming the file and the dotted key.
    """
    root = load_toml(TELEOP_CONFIG if path is None else path)
    sec = root.section("retarget")
    sec.reject_unknown(_RETARGET_KEYS)
    solver = sec.str("solver", "daqp")
    import qpsolvers

    if solver not in qpsolvers.available_solvers:
        raise sec.error("solver", f"QP solver {solver!r} is not installed; available: "
                        f"{sorted(qpsolvers.available_solvers)}")
    tau = sec.float("filter_time_constant_s", None, min=0.0)
    alpha = sec.float("filter_alpha", None, min=0.0, max=1.0)
    if tau is not None and alpha is not None:
        raise sec.error("filter_alpha", "give either filter_time_constant_s or filter_alpha, "
                        "not both")
    if alpha is not None and alpha <= 0.0:
        raise sec.error("filter_alpha", "expected 0 < alpha <= 1 (1 = no filtering)")
    hands_sec = sec.section("hands", {})
    hands = {name: _hand_mapping(name, hands_sec.section(name)) for name in hands_sec.data}
    return RetargetConfig(
        file=Path(root.file), solver=solver,
        iterations=_bounded_int(sec, "iterations", 2, 1, 10),
        dt_s=_positive(sec, "dt_s", 0.011),
        fingertip_cost=_positive(sec, "fingertip_cost", 1.0),
        posture_cost=sec.float("posture_cost", 0.01, min=0.0),
        task_lm_damping=sec.float("task_lm_damping", 0.0, min=0.0),
        damping=sec.float("damping", 1e-6, min=0.0),
        limit_gain=_positive(sec, "limit_gain", 0.95, max=1.0),
        filter_time_constant_s=None if alpha is not None else (0.015 if tau is None else tau),
        filter_alpha=alpha,
        scale=_positive(sec, "scale", 1.0),
        operator_hand_length_m=_positive(sec, "operator_hand_length_m", 0.19),
        wrist_position_scale=sec.float("wrist_position_scale", 1.0),
        world_offset_m=np.array(sec.floats("world_offset_m", 3, [0.0, 0.0, 0.0])),
        pinch_release_gap_m=sec.float("pinch_release_gap_m", 0.03, min=0.0),
        pinch_cost=sec.float("pinch_cost", 5.0, min=0.0),
        hands=hands,
    )


def _positive(sec: Section, key: str, default: float, max: float | None = None) -> float:
    value = sec.float(key, default, max=max)
    if value <= 0.0:
        raise sec.error(key, f"expected a number > 0, got {value}")
    return value


def _bounded_int(sec: Section, key: str, default: int, lo: int, hi: int) -> int:
    value = sec.int(key, default, min=lo)
    if value > hi:
        raise sec.error(key, f"expected an integer in [{lo}, {hi}], got {value}")
    return value


# --- results --------------------------------------------------------------------------------


@dataclass(frozen=True)
class RetargetResult:
    """One retargeted frame.

    q: (nq,) full joint vector, radians, in ``Hand.joint_names`` order (filtered, coupled,
    within limits). base_pos_m / base_quat_wxyz: where to put the hand model's base (its model
    frame, the root) in the world so the robot's wrist follows the operator's wrist.
    palm_pos_m / palm_quat_wxyz: the resulting frame_palm pose in the world. tip_targets_m,
    tip_positions_m: (nfingers, 3) the fingertip targets (scaled, pinch-adjusted operator
    fingertips) and the achieved pulp sites of ``q``, both in the hand's base frame.
    tip_errors_m: (nfingers,) their distances. held: this frame repeats the last output, for
    ``reason`` (one of :data:`HOLD_REASONS`). time_s: the frame's timestamp (None if unknown).
    The arrays are read-only: a held frame shares them with the frame it repeats.
    """

    q: Array
    base_pos_m: Array
    base_quat_wxyz: Array
    palm_pos_m: Array
    palm_quat_wxyz: Array
    tip_targets_m: Array
    tip_positions_m: Array
    tip_errors_m: Array
    held: bool = False
    reason: str | None = None
    time_s: float | None = None


@dataclass(frozen=True)
class RetargetTrace:
    """:func:`retarget_frames` over a recording: per-frame arrays, first axis = frame.

    step_time_s is the wall time of each :meth:`Retargeter.step` call (seconds)."""

    finger_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    t_s: Array
    q: Array
    base_pos_m: Array
    base_quat_wxyz: Array
    palm_pos_m: Array
    palm_quat_wxyz: Array
    tip_targets_m: Array
    tip_positions_m: Array
    tip_errors_m: Array
    held: Array
    step_time_s: Array

    def as_dict(self) -> dict[str, Array]:
        """Plain arrays (for ``np.savez``)."""
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


# --- the QP's linear coupling constraint -----------------------------------------------------


class _CouplingConstraint(mink.Task):
    """q_follower − coef · q_leader = 0 for every coupled pair, as QP equality rows (passed via
    ``solve_ik(constraints=...)``); the error feedback removes any drift."""

    def __init__(self, model: mujoco.MjModel, pairs: Sequence[tuple[int, int, float]]) -> None:
        super().__init__(cost=np.ones(len(pairs)), gain=1.0)
        self._follower_q = np.array([model.jnt_qposadr[f] for f, _, _ in pairs])
        self._leader_q = np.array([model.jnt_qposadr[lead] for _, lead, _ in pairs])
        self._coef = np.array([c for _, _, c in pairs])
        self._jac = np.zeros((len(pairs), model.nv))
        for row, (f, lead, c) in enumerate(pairs):
            self._jac[row, model.jnt_dofadr[f]] += 1.0
            self._jac[row, model.jnt_dofadr[lead]] -= c

    def compute_error(self, configuration: mink.Configuration) -> Array:
        qpos = configuration.data.qpos
        return qpos[self._follower_q] - self._coef * qpos[self._leader_q]

    def compute_jacobian(self, configuration: mink.Configuration) -> Array:
        del configuration
        return self._jac


class _PinchTask(mink.Task):
    """Thumb-to-finger pulp distances: |p_finger − p_thumb| − target for every non-thumb
    finger, one row each. Its per-finger cost follows the pinch weight, so while the operator
    pinches the IK cares most about how far apart thumb and finger are, which the robot can
    realise, rather than about absolute fingertip positions, which it often cannot (human and
    robot thumbs differ): the DexPilot idea, on pulp sites. A distance rather than a vector
    leaves the approach direction to the robot's own pinch geometry; a fixed direction taken
    from the operator can pin the thumb against a joint limit on the wrong side of the finger.
    """

    def __init__(self, model: mujoco.MjModel, thumb_site: int,
                 finger_sites: Sequence[int]) -> None:
        n = len(finger_sites)
        super().__init__(cost=np.zeros(n), gain=1.0)
        self._model = model
        self._thumb = thumb_site
        self._fingers = np.asarray(finger_sites)
        self.target_m = np.zeros(n)
        self._jac_thumb = np.empty((3, model.nv))
        self._jac_finger = np.empty((3, model.nv))
        self._jac = np.empty((n, model.nv))

    def set_weights(self, cost_per_finger: Array) -> None:
        self.cost[:] = cost_per_finger

    def _vectors(self, configuration: mink.Configuration) -> tuple[Array, Array]:
        x = configuration.data.site_xpos
        v = x[self._fingers] - x[self._thumb]
        return v, np.sqrt(np.einsum("ij,ij->i", v, v))

    def compute_error(self, configuration: mink.Configuration) -> Array:
        return self._vectors(configuration)[1] - self.target_m

    def compute_jacobian(self, configuration: mink.Configuration) -> Array:
        m, d = self._model, configuration.data
        v, dist = self._vectors(configuration)
        u = v / np.maximum(dist, 1e-9)[:, None]
        mujoco.mj_jacSite(m, d, self._jac_thumb, None, self._thumb)
        for k, sid in enumerate(self._fingers):
            mujoco.mj_jacSite(m, d, self._jac_finger, None, int(sid))
            self._jac_finger -= self._jac_thumb
            np.dot(u[k], self._jac_finger, out=self._jac[k])
        return self._jac


# --- the retargeter -------------------------------------------------------------------------


class Retargeter:
    """Operator hand → robot hand joint vector and floating-base pose, one frame at a time.

    Stateful on purpose: the IK is warm-started from the previous frame and the output is
    low-pass filtered, so feed frames in time order; :meth:`reset` starts over (same results
    for the same frames: the whole pipeline is deterministic).
    """

    def __init__(self, hand: Hand, config: RetargetConfig | None = None) -> None:
        self.hand = hand
        self.config = config if config is not None else load_retarget_config()
        mapping = self.config.hand(hand.name)
        self.mapping = mapping
        unknown = sorted(set(mapping.fingers) - set(hand.finger_names))
        if unknown:
            raise ConfigError(f"{mapping.where}.fingers: unknown finger(s) {unknown} of hand "
                              f"{hand.name!r}; its fingers are {list(hand.finger_names)}")
        cfg = self.config
        m = hand.model
        self.model = m
        #: Robot fingers driven here, in hand-config order, and their OpenXR joints.
        self.finger_names: tuple[str, ...] = tuple(f for f in hand.finger_names
                                                   if f in mapping.fingers)
        self._tip_idx = np.array([JOINT_INDEX[mapping.fingers[f]] for f in self.finger_names])
        self._site_ids = np.array([m.site(hand.config.finger(f).site_name).id
                                   for f in self.finger_names])
        self._needed = np.concatenate([[WRIST], self._tip_idx])
        thumb = [i for i, f in enumerate(self.finger_names) if mapping.fingers[f] == "thumb_tip"]
        self._thumb_row = thumb[0] if thumb else None
        self._other_rows = np.array([i for i in range(len(self.finger_names))
                                     if i != self._thumb_row])

        # rest posture: the hand's open pose; joints of no finger are frozen there
        self.q_rest = hand.open_pose.copy()
        in_finger = {j for f in hand.config.fingers for j in f.joints}
        frozen = [j for j in range(m.njnt) if m.joint(j).name not in in_finger]
        self.frozen_joints = tuple(m.joint(j).name for j in frozen)
        pairs = [(m.joint(fol).id, m.joint(lead).id, coef) for f in hand.config.fingers
                 for fol, (lead, coef) in f.coupled_to.items()]

        # mink problem, built once and reused every frame
        self.configuration = mink.Configuration(m, self.q_rest)
        self._tasks: list[mink.FrameTask] = []
        for sid in self._site_ids:
            task = mink.FrameTask(int(sid), "site", position_cost=cfg.fingertip_cost,
                                  orientation_cost=0.0, lm_damping=cfg.task_lm_damping)
            task.set_target(mink.SE3.identity())
            self._tasks.append(task)
        # targets are written in place each frame (no SE3 objects in the loop)
        self._targets = [t.transform_target_to_world.wxyz_xyz for t in self._tasks]
        self._posture = mink.PostureTask(m, cost=cfg.posture_cost)
        self._posture.set_target(self.q_rest)
        self._all_tasks: list[mink.Task] = [*self._tasks, self._posture]
        self._limits = [mink.ConfigurationLimit(m, gain=cfg.limit_gain)]
        self._constraints: list[mink.Task] = []
        if frozen:
            self._constraints.append(mink.DofFreezingTask(
                m, dof_indices=[int(m.jnt_dofadr[j]) for j in frozen]))
        if pairs:
            self._constraints.append(_CouplingConstraint(m, pairs))
        self._out_data = mujoco.MjData(m)
        self._pinch_task: _PinchTask | None = None
        if self._thumb_row is not None and cfg.pinch_release_gap_m > 0.0 and len(
                self._other_rows):
            self._pinch_task = _PinchTask(m, int(self._site_ids[self._thumb_row]),
                                          [int(self._site_ids[k]) for k in self._other_rows])

        # fixed transforms: base ← palm (frozen wrist joints), palm ← operator wrist
        p_bp, q_bp = (a[0] for a in hand.palm_pose(self.q_rest))
        self._p_bp, self._q_bp = p_bp, q_bp                  # frame_palm in the base frame
        q_pw = mat_to_quat(WRIST_TO_PALM_CONVENTION)
        q_pw = quat_mul(q_pw, mapping.wrist_quat_wxyz)
        p_pw = mapping.wrist_pos_m
        self._r_bw = _quat_to_mat(quat_mul(q_bp, q_pw))       # operator wrist axes in base
        self._p_bw = p_bp + _quat_to_mat(q_bp) @ p_pw        # operator wrist point in base
        p_wp, q_wp = pose_inv(p_pw, q_pw)
        self._p_wp, self._q_wp = p_wp, q_wp                  # palm in the operator wrist frame
        p_pb, q_pb = pose_inv(p_bp, q_bp)
        self._p_wb, self._q_wb = pose_mul(p_wp, q_wp, p_pb, q_pb)  # base in the wrist frame

        # scale: robot reference length over operator reference length
        tip_palm = hand.fingertip_sites(self.q_rest, frame="palm")[0, hand.finger_names.index(
            mapping.scale_finger)]
        self.robot_length_m = float(np.linalg.norm(tip_palm - p_pw))
        self._scale_chain = _operator_chain(mapping.fingers[mapping.scale_finger])
        self.operator_length_m = cfg.operator_hand_length_m
        self._set_scale()
        self.held_counts: dict[str, int] = dict.fromkeys(HOLD_REASONS, 0)
        self.reset()

    # ------------------------------------------------------------------------------ state

    def reset(self) -> None:
        """Forget the past: IK back to the rest posture, filter empty, hold counts zeroed
        (the calibrated scale is kept)."""
        self.configuration.update(self.q_rest.copy())
        self._q_out: Array | None = None
        self._last_time: float | None = None
        self.held_counts = dict.fromkeys(HOLD_REASONS, 0)
        self.frames_seen = 0
        nf = len(self.finger_names)
        nan3 = np.full((nf, 3), np.nan)
        # before any hand was seen: rest posture, base at the world origin
        self._last = RetargetResult(
            q=self.q_rest.copy(), base_pos_m=np.zeros(3), base_quat_wxyz=np.array([1.0, 0, 0, 0]),
            palm_pos_m=self._p_bp.copy(), palm_quat_wxyz=self._q_bp.copy(), tip_targets_m=nan3,
            tip_positions_m=nan3.copy(), tip_errors_m=np.full(nf, np.nan), held=True)

    def _set_scale(self) -> None:
        self.scale = self.robot_length_m / self.operator_length_m * self.config.scale
        self._m_wb = self.scale * self._r_bw.T       # rel_wrist @ M → base-frame offset

    @property
    def held_frames(self) -> int:
        """Frames held so far (all reasons)."""
        return sum(self.held_counts.values())

    # ------------------------------------------------------------------------- calibration

    def calibrate_scale(self, frames: Iterable[HandFrame | HandState]) -> float:
        """Set the fingertip scale for this operator from tracked frames and return it.

        The operator length is the median over usable frames of the bone-chain length wrist →
        ``scale_finger``'s OpenXR tip (see the module docstring for why); frames missing the
        hand or any chain joint are skipped. Raises :class:`RetargetError` when none is usable.
        """
        lengths = []
        idx = np.array([JOINT_INDEX[j] for j in self._scale_chain])
        for item in frames:
            hs = item.hand(self.mapping.side) if isinstance(item, HandFrame) else item
            if hs is None or not hs.tracked or not hs.valid[idx].all():
                continue
            pts = hs.positions[idx]
            if not np.isfinite(pts).all():
                continue
            lengths.append(float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()))
        if not lengths:
            raise RetargetError(f"cannot calibrate the scale: no frame has a tracked "
                                f"{self.mapping.side} hand with valid joints "
                                f"{list(self._scale_chain)}")
        self.operator_length_m = float(np.median(lengths))
        self._set_scale()
        logger.info("scale calibrated from %d frames: operator %s length %.4f m, robot %.4f m, "
                    "scale %.4f", len(lengths), self._scale_chain[-1], self.operator_length_m,
                    self.robot_length_m, self.scale)
        return self.scale

    # ----------------------------------------------------------------------------- per frame

    def step_frame(self, frame: HandFrame) -> RetargetResult:
        """:meth:`step` with this hand's side of a :class:`HandFrame` and its device time."""
        return self.step(frame.hand(self.mapping.side), frame.device_time_s)

    def step(self, hand: HandState | None, time_s: float | None = None) -> RetargetResult:
        """Retarget one tracking sample (None: the hand is absent from this frame)."""
        self.frames_seen += 1
        if hand is None:
            return self._hold("no_hand", time_s)
        if not hand.tracked:
            return self._hold("untracked", time_s)
        pos = hand.positions
        need = self._needed
        q_w = hand.orientations_wxyz[WRIST]
        if not (hand.valid[need].all() and np.isfinite(pos[need]).all()
                and np.isfinite(q_w).all()):
            return self._hold("invalid_joints", time_s)
        norm = math.sqrt(float(q_w @ q_w))
        if norm < 0.5:
            return self._hold("invalid_joints", time_s)
        q_w = q_w / norm
        r_w = _quat_to_mat(q_w)
        p_w = pos[WRIST]
        rel = (pos[self._tip_idx] - p_w) @ r_w        # fingertips in the operator wrist frame
        pinch = None
        if self._pinch_task is not None:
            rel, pinch = self._pinch(rel, hand.radii[self._tip_idx])
        targets = self._p_bw + rel @ self._m_wb       # base frame, scaled about the wrist

        q_ik = self._solve(targets, pinch)
        if q_ik is None:
            return self._hold("solver_failed", time_s)

        q_out = self._filter(q_ik, time_s)
        data = self._out_data
        data.qpos[:] = q_out
        mujoco.mj_kinematics(self.model, data)
        tips = data.site_xpos[self._site_ids].copy()
        wrist_world = self.config.world_offset_m + self.config.wrist_position_scale * p_w
        palm_p, palm_q = _pose_mul1(wrist_world, r_w, q_w, self._p_wp, self._q_wp)
        base_p, base_q = _pose_mul1(wrist_world, r_w, q_w, self._p_wb, self._q_wb)
        errors = np.linalg.norm(tips - targets, axis=1)
        for arr in (q_out, base_p, base_q, palm_p, palm_q, targets, tips, errors):
            arr.setflags(write=False)  # results are shared by held frames: read-only
        self._last = RetargetResult(
            q=q_out, base_pos_m=base_p, base_quat_wxyz=base_q, palm_pos_m=palm_p,
            palm_quat_wxyz=palm_q, tip_targets_m=targets, tip_positions_m=tips,
            tip_errors_m=errors, held=False, reason=None, time_s=time_s)
        return self._last

    def _pinch(self, rel: Array, radii: Array) -> tuple[Array, Array | None]:
        """Pull thumb and finger targets together below the release skin gap (module
        docstring); also the pinch weight w per non-thumb finger (None when none pinches)."""
        th = self._thumb_row
        others = self._other_rows
        v = rel[others] - rel[th]
        d = np.sqrt(np.einsum("ij,ij->i", v, v))
        r_sum = radii[others] + radii[th]
        if not np.isfinite(r_sum).all():             # no radius: use the centre distance
            r_sum = np.where(np.isfinite(r_sum), r_sum, 0.0)
        gap = d - r_sum
        w = np.clip(1.0 - gap / self.config.pinch_release_gap_m, 0.0, 1.0)
        active = w > 0.0
        if not active.any():
            return rel, None
        d_new = np.maximum(d - w * r_sum, 0.0)
        half = np.where(d > 1e-9, 0.5 * (d - d_new) / np.maximum(d, 1e-9), 0.0)
        delta = v * half[:, None]                     # move each finger half the way
        rel = rel.copy()
        rel[others] -= delta
        rel[th] += delta.sum(axis=0) / int(active.sum())
        return rel, w

    def _solve(self, targets: Array, pinch: Array | None) -> Array | None:
        """A few mink IK iterations toward ``targets`` (base frame), warm-started, with the
        thumb–finger task weighted by the pinch weights ``pinch`` when given; the new joint
        vector, or None when the QP fails (the IK state is then restored)."""
        cfg = self.config
        conf = self.configuration
        data = conf.data
        q_before = data.qpos.copy()
        for t, tgt in zip(self._targets, targets, strict=True):
            t[4:] = tgt
        tasks = self._all_tasks
        if pinch is not None and self._pinch_task is not None:
            diff = targets[self._other_rows] - targets[self._thumb_row]
            self._pinch_task.target_m[:] = np.sqrt(np.einsum("ij,ij->i", diff, diff))
            self._pinch_task.set_weights(cfg.pinch_cost * pinch)
            tasks = [*self._all_tasks, self._pinch_task]
        try:
            for _ in range(cfg.iterations):
                # target orientation := current site orientation, so that with orientation
                # cost 0 the task error is exactly the position error (no se(3) log coupling)
                for t, sid in zip(self._targets, self._site_ids, strict=True):
                    mujoco.mju_mat2Quat(t[:4], data.site_xmat[sid])
                v = mink.solve_ik(conf, tasks, cfg.dt_s, cfg.solver,
                                  damping=cfg.damping, limits=self._limits,
                                  constraints=self._constraints)
                mujoco.mj_integratePos(self.model, data.qpos, v, cfg.dt_s)
                conf.update()
        except (mink.NoSolutionFound, ValueError) as exc:
            logger.debug("IK failed (%s); holding the last output", exc)
            conf.update(q_before)
            return None
        q = data.qpos.copy()
        if not np.isfinite(q).all():
            conf.update(q_before)
            return None
        return q

    def _filter(self, q_ik: Array, time_s: float | None) -> Array:
        """First-order low-pass on the joint vector, then coupling and limits exactly."""
        cfg = self.config
        if self._q_out is None:
            q = q_ik
        else:
            if cfg.filter_alpha is not None:
                alpha = cfg.filter_alpha
            else:
                tau = cfg.filter_time_constant_s or 0.0
                dt = (time_s - self._last_time if time_s is not None
                      and self._last_time is not None and time_s > self._last_time
                      else cfg.dt_s)
                alpha = 1.0 if tau <= 0.0 else 1.0 - math.exp(-dt / tau)
            q = self._q_out + alpha * (q_ik - self._q_out)
        q = self.hand.fill_coupled(self.hand.clip(q))
        self._q_out = q
        if time_s is not None:
            self._last_time = time_s
        return q

    def _hold(self, reason: str, time_s: float | None) -> RetargetResult:
        self.held_counts[reason] += 1
        logger.debug("frame held (%s)", reason)
        return replace(self._last, held=True, reason=reason, time_s=time_s)


def _pose_mul1(p_a: Array, r_a: Array, q_a: Array, p_b: Array,
               q_b: Array) -> tuple[Array, Array]:
    """T_a ∘ T_b for single poses (r_a: q_a's matrix, already at hand): the per-frame path
    avoids the batched helpers of sim.transforms, whose overhead dominates at this size."""
    q = np.empty(4)
    mujoco.mju_mulQuat(q, q_a, q_b)
    return p_a + r_a @ p_b, q


def _quat_to_mat(q_wxyz: Array) -> Array:
    """3×3 rotation of one unit quaternion (wxyz), via MuJoCo (cheaper than the batched one)."""
    out = np.empty(9)
    mujoco.mju_quat2Mat(out, np.ascontiguousarray(q_wxyz, dtype=float))
    return out.reshape(3, 3)


def _operator_chain(tip_joint: str) -> tuple[str, ...]:
    """OpenXR joints from the wrist along ``tip_joint``'s finger up to it (e.g. wrist,
    middle_metacarpal, …, middle_tip)."""
    prefix = tip_joint.rsplit("_", 1)[0] + "_"
    chain = [j for j in OPENXR_JOINTS[:JOINT_INDEX[tip_joint] + 1] if j.startswith(prefix)]
    return ("wrist", *chain)


# --- offline --------------------------------------------------------------------------------


def retarget_frames(retargeter: Retargeter, frames: Sequence[HandFrame]) -> RetargetTrace:
    """Run ``retargeter`` over a recording (in order, from its current state) and stack the
    results; the per-step wall time is recorded for latency statistics."""
    results: list[RetargetResult] = []
    times = np.empty(len(frames))
    for i, frame in enumerate(frames):
        t0 = time.perf_counter()
        results.append(retargeter.step_frame(frame))
        times[i] = time.perf_counter() - t0
    nf = len(retargeter.finger_names)

    def stack(name: str, shape: tuple[int, ...]) -> Array:
        if not results:
            return np.empty((0, *shape))
        return np.stack([getattr(r, name) for r in results])

    return RetargetTrace(
        finger_names=retargeter.finger_names, joint_names=retargeter.hand.joint_names,
        t_s=np.array([f.device_time_s for f in frames], dtype=float),
        q=stack("q", (retargeter.hand.nq,)), base_pos_m=stack("base_pos_m", (3,)),
        base_quat_wxyz=stack("base_quat_wxyz", (4,)), palm_pos_m=stack("palm_pos_m", (3,)),
        palm_quat_wxyz=stack("palm_quat_wxyz", (4,)),
        tip_targets_m=stack("tip_targets_m", (nf, 3)),
        tip_positions_m=stack("tip_positions_m", (nf, 3)),
        tip_errors_m=stack("tip_errors_m", (nf,)),
        held=np.array([r.held for r in results], dtype=bool), step_time_s=times)


def summarise_errors(trace: RetargetTrace) -> dict[str, object]:
    """Fingertip error statistics (metres) per finger over the frames not held, plus frame
    counts and per-step latency (seconds): what ``dexaug retarget FILE`` reports."""
    live = ~trace.held
    err = trace.tip_errors_m[live]
    per_finger = {}
    for k, name in enumerate(trace.finger_names):
        e = err[:, k] if len(err) else np.empty(0)
        per_finger[name] = ({"median_m": float(np.median(e)), "p95_m": float(np.percentile(e, 95)),
                             "max_m": float(e.max())} if len(e) else
                            {"median_m": math.nan, "p95_m": math.nan, "max_m": math.nan})
    st = trace.step_time_s[live]
    return {
        "frames": len(trace.held), "held": int(trace.held.sum()),
        "fingers": per_finger,
        "step_median_s": float(np.median(st)) if len(st) else math.nan,
        "step_p99_s": float(np.percentile(st, 99)) if len(st) else math.nan,
    }
