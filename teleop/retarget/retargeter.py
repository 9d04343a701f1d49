"""Retarget an operator's tracked hand (:class:`teleop.messages.HandState`) to a robot hand.

Why this shape: teleop drives a *floating* robot hand, so the problem splits cleanly in two.
The hand's base pose is not solved for at all: it is placed so that the robot's wrist follows
the operator's wrist (position and orientation, with a configurable offset and motion scale).
Only the finger joints are solved, by differential IK with mink on the hand-only model
(``Hand.model``, fixed base), one position-only ``FrameTask`` per fingertip pulp site, a
``PostureTask`` toward the hand's open pose, a ``ConfigurationLimit`` and solver ``daqp``,
warm-started from the previous frame (DESIGN §6). The solver settings are ``configs/teleop.toml``
``[retarget]``; everything hand-specific (which operator joint drives which robot finger, where
the operator's wrist sits in the robot's palm frame, which side) is the hand's own
``configs/hands/<hand>/retarget.toml`` (:mod:`teleop.retarget.config`); nothing here names a hand.

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
    is not enough, so while a pair pinches the thumb–finger distance task
    (:class:`teleop.retarget.tasks.PinchTask`, cost ``pinch_cost`` × w) joins the IK.

Solver settings
    One IK iteration per frame suffices with warm starting (2–3 change the errors by < 0.5 mm
    on the Quest capture, see ``benchmarks/bench_retarget.py``) and keeps the median step near
    0.5 ms on one core. ``damping`` (1e-3, Levenberg–Marquardt on Δq) is what makes one
    full Gauss–Newton step per frame stable: with 1e-6 the thumb limit-cycles between two
    poses around a pinch instead of converging.

Coupled joints and the wrist
    Coupled joints are QP equality constraints (:class:`teleop.retarget.tasks.CouplingConstraint`);
    ``Hand.fill_coupled`` then removes the last floating-point drift. Joints of no finger (the
    Shadow wrist) are frozen at the open pose with mink's ``DofFreezingTask``: the floating base
    already provides the wrist pose, and letting the IK bend the wrist would move the palm away
    from the operator's.

Missing data
    A frame without the hand, an untracked hand, invalid or non-finite wrist/fingertip joints
    or a failed QP solve hold the last output (``held=True``) and count the reason
    (:attr:`Retargeter.held_counts`); nothing raises in the tracking loop.

Quaternions are wxyz everywhere here; positions metres; joint values radians.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import replace

import mink
import mujoco
import numpy as np

from sim.errors import ConfigError, DexaugError
from sim.hand.model import Hand
from sim.transforms import mat_to_quat, pose_inv, pose_mul, pose_mul1, quat_mul, quat_to_mat1
from teleop.messages import JOINT_INDEX, OPENXR_JOINTS, WRIST, HandFrame, HandState
from teleop.retarget.config import WRIST_TO_PALM_CONVENTION, RetargetConfig, load_retarget_config
from teleop.retarget.result import HOLD_REASONS, RetargetResult
from teleop.retarget.tasks import CouplingConstraint, PinchTask

__all__ = ["RetargetError", "Retargeter"]

logger = logging.getLogger(__name__)

Array = np.ndarray


class RetargetError(DexaugError):
    """Retargeting cannot proceed (e.g. no usable frame to calibrate the scale from)."""


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
            raise ConfigError(f"{mapping.file}: fingers: unknown finger(s) {unknown} of hand "
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
            self._constraints.append(CouplingConstraint(m, pairs))
        self._out_data = mujoco.MjData(m)
        self._pinch_task: PinchTask | None = None
        if self._thumb_row is not None and cfg.pinch_release_gap_m > 0.0 and len(
                self._other_rows):
            self._pinch_task = PinchTask(m, int(self._site_ids[self._thumb_row]),
                                         [int(self._site_ids[k]) for k in self._other_rows])

        # fixed transforms: base ← palm (frozen wrist joints), palm ← operator wrist
        p_bp, q_bp = (a[0] for a in hand.palm_pose(self.q_rest))
        self._p_bp, self._q_bp = p_bp, q_bp                  # frame_palm in the base frame
        q_pw = mat_to_quat(WRIST_TO_PALM_CONVENTION)
        q_pw = quat_mul(q_pw, mapping.wrist_quat_wxyz)
        p_pw = mapping.wrist_pos_m
        self._r_bw = quat_to_mat1(quat_mul(q_bp, q_pw))       # operator wrist axes in base
        self._p_bw = p_bp + quat_to_mat1(q_bp) @ p_pw        # operator wrist point in base
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
        r_w = quat_to_mat1(q_w)
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
        palm_p, palm_q = pose_mul1(wrist_world, r_w, q_w, self._p_wp, self._q_wp)
        base_p, base_q = pose_mul1(wrist_world, r_w, q_w, self._p_wb, self._q_wb)
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


def _operator_chain(tip_joint: str) -> tuple[str, ...]:
    """OpenXR joints from the wrist along ``tip_joint``'s finger up to it (e.g. wrist,
    middle_metacarpal, …, middle_tip)."""
    prefix = tip_joint.rsplit("_", 1)[0] + "_"
    chain = [j for j in OPENXR_JOINTS[:JOINT_INDEX[tip_joint] + 1] if j.startswith(prefix)]
    return ("wrist", *chain)
