"""A planned arm grasp simulated in MuJoCo: settle the object, follow the plan, close, lift, hold.

The paper's hand–arm check (§5.3): "the IK solutions with grasp poses are simulated in MuJoCo …
validity is assessed based on changes in the object pose after grasping". The arm's position
servos follow the plan's joint targets, linearly interpolated between its keyframes (home →
pregrasp → the approach waypoints → the grasp; closing; the lift), while the hand's servos hold
the plan's pregrasp and then ramp to the squeeze (the pregrasp/squeeze the hand-only validator
makes, :meth:`~sim.validate.validator.Validator.stages`, with the wrist and the pregrasp's
opening as the plan set them near the table: :func:`sim.arm.plan.hand_for_approach`).
Verdict, with the lift-drop limits of ``configs/validate.toml``: ``pushed`` when the object
moved more than the displacement limit before the fingers closed, ``dropped`` when it rose less
than half the lift, ``slipped`` when its pose in frame_palm changed by more than the limits
between the end of closing and the end of the hold; else it holds. Units: metres, radians, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from sim.arm.plan import ArmPlan
from sim.arm.scene import ARM_PREFIX, ArmScene
from sim.errors import ConfigError
from sim.transforms import pose_inv, pose_mul, quat_angle
from sim.world.scene import HAND_PREFIX

__all__ = ["ArmOutcome", "ArmTiming", "arm_servo_ids", "settle_object", "simulate_plan"]


@dataclass(frozen=True)
class ArmTiming:
    """Seconds of each phase: to the pregrasp, the approach, closing (pregrasp → squeeze),
    settling closed, the lift, the hold at the top."""

    to_pregrasp_s: float = 1.5
    approach_s: float = 1.0
    close_s: float = 0.3
    settle_s: float = 0.2
    lift_s: float = 1.0
    hold_s: float = 1.0


@dataclass(frozen=True)
class ArmOutcome:
    """What the simulation gave: ``passed``, ``failure`` (None, ``pushed``, ``dropped``,
    ``slipped``), the object's pose change in frame_palm over the lift and hold
    (``displacement_m``, ``rotation_rad``), how far it rose (``lifted_m``), and the commanded
    arm trajectory (``times_s`` (K,), ``arm_q_rad`` (K, n_arm), piecewise linear) and the
    scene's whole qpos when the simulation ended (``final_qpos``)."""

    passed: bool
    failure: str | None
    displacement_m: float
    rotation_rad: float
    lifted_m: float
    times_s: np.ndarray
    arm_q_rad: np.ndarray
    final_qpos: np.ndarray


def arm_servo_ids(scene: ArmScene) -> np.ndarray:
    """The actuator of each arm joint (config order); each must be a position servo whose
    control is the joint angle (gain = −bias₁), as the Menagerie arms' are."""
    m = scene.model
    by_joint = {int(m.actuator_trnid[a, 0]): a for a in range(m.nu)
                if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT}
    out = []
    for name in scene.arm.joints:
        j = m.joint(ARM_PREFIX + name).id
        a = by_joint.get(j)
        if a is None or not np.isclose(m.actuator_gainprm[a, 0], -m.actuator_biasprm[a, 1]):
            raise ConfigError(f"{scene.arm.file}: joints: {m.joint(j).name} has no position servo "
                              "(an actuator whose control is the joint angle)")
        out.append(a)
    return np.array(out)


def _hand_servo_ids(scene: ArmScene) -> np.ndarray:
    names = [scene.hand.model.actuator(a).name for a in range(scene.hand.model.nu)]
    return np.array([scene.model.actuator(HAND_PREFIX + n).id for n in names])


def _object_pose(scene: ArmScene, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    q = d.qpos[scene.obj_qadr:scene.obj_qadr + 7]
    return q[:3].copy(), q[3:].copy()


def settle_object(scene: ArmScene, pos: np.ndarray, quat_wxyz: np.ndarray, *,
                  time_s: float = 1.0) -> mujoco.MjData:
    """A fresh state with the arm at home, the hand open and the object dropped at
    (``pos``, ``quat_wxyz``) and simulated for ``time_s`` so it lies as it settles."""
    m = scene.model
    d = mujoco.MjData(m)
    d.qpos[:] = scene.qpos()
    d.qpos[scene.obj_qadr:scene.obj_qadr + 3] = pos
    d.qpos[scene.obj_qadr + 3:scene.obj_qadr + 7] = quat_wxyz
    d.ctrl[arm_servo_ids(scene)] = scene.arm.home_rad
    d.ctrl[_hand_servo_ids(scene)] = scene.hand.ctrl_for(scene.hand.open_pose)
    mujoco.mj_forward(m, d)
    for _ in range(round(time_s / m.opt.timestep)):
        mujoco.mj_step(m, d)
    return d


def _schedule(plan: ArmPlan, t: ArmTiming) -> tuple[np.ndarray, np.ndarray]:
    # a successful plan (simulate_plan refuses a failed one) has every waypoint
    assert plan.pregrasp is not None and plan.approach is not None and plan.lift is not None
    keys = [plan.home, plan.pregrasp, *plan.approach[1:]]
    times = [0.0, t.to_pregrasp_s]
    n_way = len(plan.approach) - 1
    times += list(t.to_pregrasp_s + t.approach_s * np.arange(1, n_way + 1) / n_way)
    closed = times[-1] + t.close_s + t.settle_s
    keys += [plan.approach[-1], plan.lift, plan.lift]
    times += [closed, closed + t.lift_s, closed + t.lift_s + t.hold_s]
    return np.array(times), np.array(keys)


def simulate_plan(scene: ArmScene, settled: mujoco.MjData, plan: ArmPlan, squeeze_q: np.ndarray,
                  *, max_displacement_m: float, max_rotation_rad: float,
                  timing: ArmTiming | None = None) -> ArmOutcome:
    """Simulate ``plan`` (successful) from a copy of ``settled`` (module docstring): the
    fingers close from the plan's pregrasp to ``squeeze_q`` (the grasp's squeeze), the wrist
    held where the plan bent it."""
    if plan.failure is not None:
        raise ValueError(f"simulate_plan: the plan failed ({plan.failure}); nothing to simulate")
    # a successful plan has its hand joints
    assert plan.pregrasp_q is not None and plan.grasp_q is not None
    free = scene.hand_ik_free
    pregrasp_q, squeeze_q = plan.pregrasp_q, np.array(squeeze_q, float)
    squeeze_q[free] = plan.grasp_q[free]
    t = timing or ArmTiming()
    m = scene.model
    d = mujoco.MjData(m)
    mujoco.mj_copyData(d, m, settled)
    arm_ids, hand_ids = arm_servo_ids(scene), _hand_servo_ids(scene)
    times, keys = _schedule(plan, t)
    open_ctrl, squeeze_ctrl = scene.hand.ctrl_for(pregrasp_q), scene.hand.ctrl_for(squeeze_q)
    t_contact = t.to_pregrasp_s + t.approach_s
    t_closed = t_contact + t.close_s + t.settle_s
    start_pos, _ = _object_pose(scene, d)
    ref: tuple[np.ndarray, np.ndarray] | None = None
    nstep = round(times[-1] / m.opt.timestep)
    # velocity feed-forward: a servo force kp·(ctrl − q) − kv·q̇ vanishes on the path when
    # ctrl = q_path + (kv/kp)·q̇_path; without it the Menagerie UR5e lags 8° behind a 1.5 s move
    lead_s = -m.actuator_biasprm[arm_ids, 2] / m.actuator_gainprm[arm_ids, 0]
    slopes = np.diff(keys, axis=0) / np.maximum(np.diff(times), 1e-9)[:, None]
    # every step's controls computed once, before stepping
    now_s = np.arange(nstep) * m.opt.timestep
    seg = np.minimum(np.searchsorted(times, now_s, side="right") - 1, len(slopes) - 1)
    arm_ctrl = (np.stack([np.interp(now_s, times, keys[:, j]) for j in range(keys.shape[1])], axis=1)
                + lead_s * slopes[seg])
    closing = np.clip((now_s - t_contact) / t.close_s, 0.0, 1.0)[:, None]
    hand_ctrl = (1.0 - closing) * open_ctrl + closing * squeeze_ctrl
    for k in range(nstep):
        now = now_s[k]
        d.ctrl[arm_ids] = arm_ctrl[k]
        d.ctrl[hand_ids] = hand_ctrl[k]
        mujoco.mj_step(m, d)
        if ref is None and now >= t_closed:
            pos, _ = _object_pose(scene, d)
            if np.linalg.norm(pos - start_pos) > max_displacement_m:
                return ArmOutcome(False, "pushed", float(np.linalg.norm(pos - start_pos)), 0.0, 0.0,
                                  times, keys, d.qpos.copy())
            ref = _in_palm(scene, d)
    # the schedule ends a lift and a hold after t_closed, so the loop took the reference
    assert ref is not None
    pos, _ = _object_pose(scene, d)
    lifted = float(pos[2] - start_pos[2])
    rel_pos, rel_quat = _in_palm(scene, d)
    disp = float(np.linalg.norm(rel_pos - ref[0]))
    rot = float(quat_angle(rel_quat, ref[1]))
    failure = ("dropped" if lifted < 0.5 * _lift_height(scene, plan)
               else "slipped" if disp > max_displacement_m or rot > max_rotation_rad else None)
    return ArmOutcome(failure is None, failure, disp, rot, lifted, times, keys, d.qpos.copy())


def _lift_height(scene: ArmScene, plan: ArmPlan) -> float:
    """How far the plan raises frame_palm (m)."""
    assert plan.lift is not None and plan.approach is not None   # a successful plan
    top, _ = scene.site_pose(scene.qpos(plan.lift))
    grasp, _ = scene.site_pose(scene.qpos(plan.approach[-1]))
    return float(top[2] - grasp[2])


def _in_palm(scene: ArmScene, d: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """The object's pose in frame_palm now."""
    palm_pos = d.site_xpos[scene.palm_site].copy()
    palm_quat = np.empty(4)
    mujoco.mju_mat2Quat(palm_quat, d.site_xmat[scene.palm_site])
    inv_p, inv_q = pose_inv(palm_pos, palm_quat)
    return pose_mul(inv_p, inv_q, *_object_pose(scene, d))
