"""Retarget an operator's tracked hand (:class:`teleop.messages.HandState`) to a robot hand.

Why this shape: teleop drives a *floating* robot hand, so the problem splits cleanly in two.
The hand's base pose is not solved for at all: it is placed so that the robot's wrist follows
the operator's wrist (position and orientation, with a configurable offset and motion scale).
Only the finger joints are solved, by differential IK with mink on the hand-only model
(``Hand.model``, fixed base): one batched position task (:class:`teleop.retarget.tasks.PointsTask`)
over the fingertip pulp sites and the phalanx keypoints, a ``PostureTask`` toward the hand's
open pose, a ``ConfigurationLimit`` and solver ``daqp``, warm-started from the previous frame
(DESIGN §6). The solver settings are ``configs/teleop.toml`` ``[retarget]``; everything
hand-specific (which operator joint drives which robot finger and phalanx, where the operator's
wrist sits in the robot's palm frame, which side) is the hand's own
``configs/hands/<hand>/retarget.toml`` (:mod:`teleop.retarget.config`); nothing here names a hand.

Frames and correspondence
    The operator's OpenXR WRIST joint frame (after ingest: +x distal along the hand, +z out of
    the back of the hand, see :mod:`teleop.input.frames`) is mapped onto the robot's ``frame_palm``
    (DESIGN §3 and every hand config: +y the palm normal out of the pulp side, +z toward the
    fingers, x = y × z) by the convention rotation ``x_wrist → z_palm, y_wrist → −x_palm,
    z_wrist → −y_palm``, then by the per-hand extra rotation ``wrist_rpy_deg``; the operator's
    wrist point lands on the per-hand point ``wrist_pos_m`` of frame_palm (for the Shadow Hand,
    its wrist joint). Operator points are taken relative to the operator's wrist in that frame,
    scaled by ``scale`` about the wrist point, and become targets in the hand's base frame.

Targets (contact-aware)
    The tracked hand is One-Euro smoothed first (:mod:`teleop.retarget.input_filter`). Each
    robot pulp site follows the operator's finger *pad* (``pad_targets``,
    :mod:`teleop.retarget.operator_points`); each robot phalanx body of the hand's
    ``[phalanges]`` follows its OpenXR joint at ``phalanx_cost``, so wraps and hooks bend the
    robot's phalanges too. Near a thumb–finger pinch the targets are pulled together and a
    distance task (:class:`teleop.retarget.tasks.PinchTask`) joins the IK. With an object
    (:meth:`Retargeter.set_object`), targets within ``snap_distance_m`` of its surface or behind
    it, and targets whose *operator* pad is within ``operator_snap_distance_m`` of it, go onto
    it, or ``press_m`` into it (the bridge's grasp assist, :mod:`teleop.retarget.snap`); with
    the simulated base pose (``sim_base``) a snapped pad is solved in *that* frame, so the pads
    reach the object where the simulated hand really is.

Scale calibration (:mod:`teleop.retarget.calibration`)
    scale = robot length / operator length × ``scale``, the operator measured from frames at
    hand (:meth:`Retargeter.calibrate_scale`), else over the first ``calibration_s`` of tracking
    and again on :meth:`Retargeter.recalibrate` (the bridge's control).

Solver settings
    One warm-started IK iteration per frame suffices (``benchmarks/bench_retarget.py``); ``damping``
    1e-3 (Levenberg–Marquardt on Δq) keeps that full step stable (1e-6: the thumb limit-cycles
    around a pinch); the output is low-pass filtered (:mod:`teleop.retarget.joint_filter`).
    Coupled joints are QP equality constraints (:class:`teleop.retarget.tasks.CouplingConstraint`);
    joints of no finger (the Shadow wrist) are frozen at the open pose (the base is the wrist).

Missing data
    No hand, an untracked hand, invalid wrist/fingertip joints or a failed QP solve hold the last
    output (``held=True``, reason counted in :attr:`Retargeter.held_counts`); an invalid phalanx
    joint only drops its task. Nothing raises.

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
from teleop.messages import JOINT_INDEX, WRIST, HandFrame, HandState
from teleop.retarget.calibration import ScaleCalibration, chain_length_m, operator_chain
from teleop.retarget.config import WRIST_TO_PALM_CONVENTION, RetargetConfig, load_retarget_config
from teleop.retarget.input_filter import HandInputFilter
from teleop.retarget.joint_filter import JointFilter
from teleop.retarget.operator_points import pad_points, pinch_adjust
from teleop.retarget.result import HOLD_REASONS, RetargetResult
from teleop.retarget.snap import Pose, snap_pad_targets
from teleop.retarget.surface import ObjectSurface
from teleop.retarget.tasks import CouplingConstraint, PinchTask, PointsTask

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
        links = {b for f in hand.config.fingers for b in f.links}
        bad = sorted(set(mapping.phalanges) - links)
        if bad:
            raise ConfigError(f"{mapping.file}: phalanges: {bad} are not finger links of hand "
                              f"{hand.name!r} (hand.toml [[fingers]] links: {sorted(links)})")
        cfg = self.config
        m = hand.model
        self.model = m
        #: Robot fingers driven here, in hand-config order, and their OpenXR joints.
        self.finger_names: tuple[str, ...] = tuple(f for f in hand.finger_names
                                                   if f in mapping.fingers)
        self._tip_idx = np.array([JOINT_INDEX[mapping.fingers[f]] for f in self.finger_names])
        self._site_ids = np.array([m.site(hand.config.finger(f).site_name).id
                                   for f in self.finger_names])
        #: Robot bodies whose origins follow operator phalanx joints (none at phalanx_cost 0).
        self.phalanx_bodies: tuple[str, ...] = (tuple(mapping.phalanges)
                                                if cfg.phalanx_cost > 0.0 else ())
        self._phal_idx = np.array([JOINT_INDEX[mapping.phalanges[b]] for b in self.phalanx_bodies],
                                  dtype=int)
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
        nf, nb = len(self.finger_names), len(self.phalanx_bodies)
        costs = np.concatenate([np.full(nf, cfg.fingertip_cost), np.full(nb, cfg.phalanx_cost)])
        self._points = PointsTask(m, [int(s) for s in self._site_ids],
                                  [m.body(b).id for b in self.phalanx_bodies], costs,
                                  lm_damping=cfg.task_lm_damping)
        self._posture = mink.PostureTask(m, cost=cfg.posture_cost)
        self._posture.set_target(self.q_rest)
        self._all_tasks: list[mink.Task] = [self._points, self._posture]
        self._limits = [mink.ConfigurationLimit(m, gain=cfg.limit_gain)]
        self._constraints: list[mink.Task] = []
        if frozen:
            self._constraints.append(mink.DofFreezingTask(
                m, dof_indices=[int(m.jnt_dofadr[j]) for j in frozen]))
        if pairs:
            self._constraints.append(CouplingConstraint(m, pairs))
        self._out_data = mujoco.MjData(m)
        self._filter = JointFilter(hand, cfg)
        self._input = HandInputFilter(cfg.input_filter)
        self._pinch_task: PinchTask | None = None
        if self._thumb_row is not None and cfg.pinch_release_gap_m > 0.0 and len(self._other_rows):
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
        self._scale_chain = operator_chain(mapping.fingers[mapping.scale_finger])
        self._chain_idx = np.array([JOINT_INDEX[j] for j in self._scale_chain])
        self.operator_length_m = cfg.operator_hand_length_m
        self._set_scale()
        #: Collecting frames for a scale calibration (None: not calibrating).
        self.calibration: ScaleCalibration | None = None
        if cfg.calibration_s > 0.0:
            self.recalibrate()
        self.surface: ObjectSurface | None = None
        #: Metres (per finger, or one) snapped targets go into the object (the grasp assist's).
        self.press_m: Array | float = 0.0
        self.reset()

    # ------------------------------------------------------------------------------ state

    def reset(self) -> None:
        """Forget the past: IK back to the rest posture, filter empty, hold counts zeroed
        (the calibrated scale, a calibration under way and the object are kept)."""
        self.configuration.update(self.q_rest.copy())
        self._filter.reset()
        self._input.reset()
        self.held_counts: dict[str, int] = dict.fromkeys(HOLD_REASONS, 0)
        self.frames_seen = 0
        nf = len(self.finger_names)
        nan3 = np.full((nf, 3), np.nan)
        # before any hand was seen: rest posture, base at the world origin
        self._last = RetargetResult(
            q=self.q_rest.copy(), base_pos_m=np.zeros(3), base_quat_wxyz=np.array([1.0, 0, 0, 0]),
            palm_pos_m=self._p_bp.copy(), palm_quat_wxyz=self._q_bp.copy(), tip_targets_m=nan3,
            tip_positions_m=nan3.copy(), tip_errors_m=np.full(nf, np.nan), held=True,
            snap_moved_m=np.zeros(nf))

    def set_object(self, surface: ObjectSurface | None) -> None:
        """Snap pad targets onto ``surface`` from the next frame on (None: no object, no
        snapping). Keep its pose current with :meth:`ObjectSurface.set_pose` (the
        retargeter's world: the frame of ``base_pos_m``)."""
        self.surface = surface

    def _set_scale(self) -> None:
        self.scale = self.robot_length_m / self.operator_length_m * self.config.scale
        self._m_wb = self.scale * self._r_bw.T       # rel_wrist @ M → base-frame offset

    @property
    def held_frames(self) -> int:
        """Frames held so far (all reasons)."""
        return sum(self.held_counts.values())

    # ------------------------------------------------------------------------- calibration

    def calibrate_scale(self, frames: Iterable[HandFrame | HandState]) -> float:
        """Set the fingertip scale for this operator from tracked frames and return it (a
        calibration under way is dropped).

        The operator length is the median over usable frames of the bone-chain length wrist →
        ``scale_finger``'s OpenXR tip (:mod:`teleop.retarget.calibration`); frames missing
        the hand or any chain joint are skipped. Raises :class:`RetargetError` when none is
        usable.
        """
        lengths = []
        for item in frames:
            hs = item.hand(self.mapping.side) if isinstance(item, HandFrame) else item
            length = chain_length_m(hs, self._chain_idx)
            if length is not None:
                lengths.append(length)
        if not lengths:
            raise RetargetError(f"cannot calibrate the scale: no frame has a tracked "
                                f"{self.mapping.side} hand with valid joints "
                                f"{list(self._scale_chain)}")
        self.calibration = None
        self._set_operator_length(float(np.median(lengths)), len(lengths))
        return self.scale

    def recalibrate(self, duration_s: float | None = None) -> None:
        """Measure the operator again over the next ``duration_s`` (default ``calibration_s``)
        of tracking; the current scale stays in use until then (the bridge's control)."""
        duration = self.config.calibration_s if duration_s is None else float(duration_s)
        self.calibration = ScaleCalibration(self._chain_idx, duration, self.config.dt_s)
        logger.info("scale calibration: measuring the next %.2f s of tracking", duration)

    def _set_operator_length(self, length_m: float, frames: int) -> None:
        self.operator_length_m = length_m
        self._set_scale()
        logger.info("scale calibrated from %d frames: operator %s length %.4f m, robot %.4f m, "
                    "scale %.4f", frames, self._scale_chain[-1], self.operator_length_m,
                    self.robot_length_m, self.scale)

    # ----------------------------------------------------------------------------- per frame

    def step_frame(self, frame: HandFrame, sim_base: Pose | None = None) -> RetargetResult:
        """:meth:`step` with this hand's side of a :class:`HandFrame` and its device time."""
        return self.step(frame.hand(self.mapping.side), frame.device_time_s, sim_base)

    def step(self, hand: HandState | None, time_s: float | None = None,
             sim_base: Pose | None = None) -> RetargetResult:
        """Retarget one tracking sample (None: the hand is absent from this frame);
        ``sim_base``: where the simulated hand's base is (position, quaternion wxyz; the frame
        of ``base_pos_m``), for the snapped targets (module docstring)."""
        self.frames_seen += 1
        if self.calibration is not None and (length := self.calibration.feed(hand, time_s)):
            self._set_operator_length(length, len(self.calibration.lengths))
            self.calibration = None
        if hand is None:
            return self._hold("no_hand", time_s)
        if not hand.tracked:
            return self._hold("untracked", time_s)
        pos = hand.positions
        need = self._needed
        q_w = hand.orientations_wxyz[WRIST]
        if not (hand.valid[need].all() and np.isfinite(pos[need]).all()
                and np.isfinite(q_w).all() and np.isfinite(hand.orientations_wxyz[need]).all()):
            return self._hold("invalid_joints", time_s)
        norm = math.sqrt(float(q_w @ q_w))
        if norm < 0.5:
            return self._hold("invalid_joints", time_s)
        hand = self._input(hand, time_s)     # One-Euro smoothed (teleop.retarget.input_filter)
        pos, q_w = hand.positions, hand.orientations_wxyz[WRIST]
        q_w = q_w / math.sqrt(float(q_w @ q_w))
        r_w, p_w = quat_to_mat1(q_w), pos[WRIST]
        tips = self._tip_idx
        radii = hand.radii[tips]
        centres = (pos[tips] - p_w) @ r_w             # fingertips in the operator wrist frame
        pads = pad_points(pos[tips], hand.orientations_wxyz[tips], radii)
        rel = (pads - p_w) @ r_w if self.config.pad_targets else centres
        pinch = None
        if self._pinch_task is not None and self._thumb_row is not None:
            rel, pinch = pinch_adjust(rel, centres, radii, self._thumb_row, self._other_rows,
                                      self.config.pinch_release_gap_m)
        targets = self._p_bw + rel @ self._m_wb       # base frame, scaled about the wrist
        wrist_world = self.config.world_offset_m + self.config.wrist_position_scale * p_w
        base_p, base_q = pose_mul1(wrist_world, r_w, q_w, self._p_wb, self._q_wb)
        cfg, moved = self.config, np.zeros(len(targets))
        if self.surface is not None and cfg.snap_distance_m > 0.0:
            targets, moved = snap_pad_targets(
                self.surface, targets, (base_p, base_q), cfg.snap_distance_m, self.press_m,
                sim_base if cfg.snap_in_sim_frame else None,
                operator_pads_m=cfg.world_offset_m + cfg.wrist_position_scale * pads,
                operator_snap_m=cfg.operator_snap_distance_m,
                operator_depth_m=cfg.operator_touch_depth_m)
        phal = self._phalanx_targets(hand, p_w, r_w)
        q_ik = self._solve(targets, phal, pinch)
        if q_ik is None:
            return self._hold("solver_failed", time_s)

        q_out = self._filter(q_ik, time_s)
        data = self._out_data
        data.qpos[:] = q_out
        mujoco.mj_kinematics(self.model, data)
        tip_pos = data.site_xpos[self._site_ids].copy()
        palm_p, palm_q = pose_mul1(wrist_world, r_w, q_w, self._p_wp, self._q_wp)
        errors = np.linalg.norm(tip_pos - targets, axis=1)
        for arr in (q_out, base_p, base_q, palm_p, palm_q, targets, tip_pos, errors, moved):
            arr.setflags(write=False)  # shared by held frames: read-only
        self._last = RetargetResult(
            q=q_out, base_pos_m=base_p, base_quat_wxyz=base_q, palm_pos_m=palm_p,
            palm_quat_wxyz=palm_q, tip_targets_m=targets, tip_positions_m=tip_pos,
            tip_errors_m=errors, held=False, reason=None, time_s=time_s, snap_moved_m=moved)
        return self._last

    def _phalanx_targets(self, hand: HandState, p_w: Array, r_w: Array) -> Array | None:
        """Phalanx keypoint targets (base frame) of this frame; their costs are zeroed where
        the operator joint is invalid (None: no phalanx tasks)."""
        if not len(self._phal_idx):
            return None
        pts = hand.positions[self._phal_idx]
        ok = hand.valid[self._phal_idx] & np.isfinite(pts).all(axis=1)
        nf = len(self.finger_names)
        self._points.cost[3 * nf:] = np.repeat(np.where(ok, self.config.phalanx_cost, 0.0), 3)
        rel = (np.where(ok[:, None], pts, p_w) - p_w) @ r_w
        return self._p_bw + rel @ self._m_wb

    def _solve(self, targets: Array, phal: Array | None, pinch: Array | None) -> Array | None:
        """A few mink IK iterations toward the pulp ``targets`` and phalanx targets ``phal``
        (base frame), warm-started, with the thumb–finger task weighted by the pinch weights
        ``pinch`` when given; the new joint vector, or None when the QP fails (the IK state is
        then restored)."""
        cfg = self.config
        conf = self.configuration
        data = conf.data
        q_before = data.qpos.copy()
        nf = len(targets)
        self._points.target_m[:nf] = targets
        if phal is not None:
            self._points.target_m[nf:] = phal
        tasks = self._all_tasks
        if pinch is not None and self._pinch_task is not None:
            diff = targets[self._other_rows] - targets[self._thumb_row]
            self._pinch_task.target_m[:] = np.sqrt(np.einsum("ij,ij->i", diff, diff))
            self._pinch_task.set_weights(cfg.pinch_cost * pinch)
            tasks = [*self._all_tasks, self._pinch_task]
        try:
            for _ in range(cfg.iterations):
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

    def _hold(self, reason: str, time_s: float | None) -> RetargetResult:
        """The last output again, marked held for ``reason`` (counted)."""
        self.held_counts[reason] += 1
        logger.debug("frame held (%s)", reason)
        return replace(self._last, held=True, reason=reason, time_s=time_s)
