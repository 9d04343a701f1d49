"""Physical grasp validation in MuJoCo: the ``lift-drop`` and ``six-dir`` protocols (DESIGN §5).

The augmenter only checks grasps analytically; a grasp is kept when it also holds in simulation.
From a grasp (palm pose in the object frame + joint vector) the validator derives a pregrasp and
a squeeze target itself: it finds the hand bodies near the object, and moves their closest
points back along the contact normals (pregrasp) or onto the object surface (squeeze) with
damped least squares on the contact Jacobians, so it works for any hand without per-hand closing
rules.

The squeeze is sized by force, not by depth. A position servo presses only as hard as its target
lies beyond where the finger stops, so a fixed depth gives a force that depends on the hand's
gains (the Menagerie Shadow Hand's ≈ 1 N·m/rad servos give ≈ 1 N per fingertip for 8 mm, too
little to lift a sugar box with a fingertip grasp), and a fixed larger depth crushes light objects
out of a pinch. Each grasping contact i (one per hand body near the object) is given a desired
normal force ``f_i = max(grip_safety · m·g·(1 + d/ρ) / (μ · n_contacts), min_grip_force_n)``
(d: centre of mass to the contacts' centroid, ρ: the contacts' spread), so that the friction of
all contacts carries ``grip_safety`` times the object's weight and its moment about the grasp,
and the target is

    q_squeeze = q + J⁺ (gaps + squeeze_depth_m) + K_q⁺ Jᵀ f

where J holds the contact-normal rows of the finger Jacobians and ``K_q = Mᵀ diag(k) M`` is the
joint-space stiffness of the hand's servos, from the actuator moment matrix M and each
actuator's position stiffness k (``−biasprm[1]`` of an affine-bias actuator: the force per unit
of length error at a fixed control). ``K_q⁺`` is a damped pseudo-inverse because coupled tendon
joints (one actuator for two joints) make K_q singular. Actuator force limits saturate in the
simulation, as on a real hand. Both protocols close onto the same targets.

The validation scenes multiply the hand's servo stiffness kp by ``servo_kp_scale`` (5, as
DexGraspBench does for the Menagerie hands): kp is the controller's gain, and at the models'
≈ 1 N·m/rad a grasp that holds the object still turns it past the 15° limit under its own
weight (measured on 60 soup-can grasps: 45 % pass at kp × 1, 77 % at × 5; force limits stay).
Simulation is deterministic: the same grasp gives the same result on any worker.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import StrEnum
from pathlib import Path

import mujoco
import numpy as np

from sim.config import load_toml
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.metrics.gws import gws_metrics
from sim.paths import CONFIG_DIR
from sim.transforms import pose_inv, pose_mul, quat_angle, rotate
from sim.world.contacts import Contacts, contacts_between, merge_nearby
from sim.world.objects import ContactParams, ObjectAsset
from sim.world.scene import HAND_PREFIX, OBJECT_HOME, PhysicsOptions, Scene

PROTOCOLS = ("lift-drop", "six-dir")
VALIDATE_TOML = CONFIG_DIR / "validate.toml"
GRAVITY_MPS2 = 9.81
# relative damping of the pseudo-inverses: the contact Jacobian's (m², as J Jᵀ) and the joint
# stiffness's (times its largest eigenvalue; only makes singular directions harmless)
_JAC_DAMPING_M2 = 1e-4
_STIFFNESS_DAMPING = 1e-3
# smallest lever arm (metres) credited to a grasp's friction torque: about a fingertip pad
_MIN_LEVER_M = 0.005
SIX_DIRECTIONS = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0),
                  "+z": (0, 0, 1), "-z": (0, 0, -1)}


class Failure(StrEnum):
    """Why a grasp failed, checked in this order."""

    PENETRATION = "penetration"        # hand–object penetration above the limit before simulating
    NO_CONTACT = "no_contact"          # no hand body near the object: a grasp on air
    LOST_CONTACT = "lost_contact"      # fingers closed but nothing touches the object
    SLIPPED = "slipped"                # object moved/rotated past the limits while lifted or pushed
    STUCK = "stuck"                    # lift-drop: object stayed in the opened hand (interpenetration)


@dataclass(frozen=True)
class CommonParams:
    max_penetration_m: float
    contact_search_m: float
    pregrasp_backoff_m: float
    squeeze_depth_m: float
    grip_safety: float
    min_grip_force_n: float
    close_time_s: float
    settle_time_s: float
    pin_while_closing: bool
    servo_kp_scale: float
    contact: ContactParams
    gws_mu: float


@dataclass(frozen=True)
class LiftDropParams:
    timestep_s: float
    impratio: float
    lift_height_m: float
    lift_time_s: float
    hold_time_s: float
    drop_time_s: float
    max_displacement_m: float
    max_rotation_rad: float
    drop_min_fall_m: float


@dataclass(frozen=True)
class SixDirParams:
    timestep_s: float
    impratio: float
    noslip_iterations: int
    force_per_kg: float
    push_time_s: float
    max_displacement_m: float
    max_rotation_rad: float


@dataclass(frozen=True)
class ValidateConfig:
    common: CommonParams
    lift_drop: LiftDropParams
    six_dir: SixDirParams

    @classmethod
    def load(cls, path: Path | str = VALIDATE_TOML) -> ValidateConfig:
        root = load_toml(path)
        root.reject_unknown({"common", "lift_drop", "six_dir"})
        c = root.section("common")
        c.reject_unknown({"max_penetration_m", "contact_search_m", "pregrasp_backoff_m",
                          "squeeze_depth_m", "grip_safety", "min_grip_force_n", "close_time_s",
                          "settle_time_s", "pin_while_closing", "servo_kp_scale", "friction",
                          "solref",
                          "gws_mu"})
        pos = {"min": 0.0}
        friction = tuple(c.floats("friction", 3))
        if friction[0] <= 0.0:  # the grip force is weight / friction
            raise c.error("friction", f"sliding friction must be > 0, got {friction[0]}")
        common = CommonParams(
            max_penetration_m=c.float("max_penetration_m", **pos),
            contact_search_m=c.float("contact_search_m", **pos),
            pregrasp_backoff_m=c.float("pregrasp_backoff_m", **pos),
            squeeze_depth_m=c.float("squeeze_depth_m", **pos),
            grip_safety=c.float("grip_safety", **pos),
            min_grip_force_n=c.float("min_grip_force_n", **pos),
            close_time_s=c.float("close_time_s", min=1e-3),
            settle_time_s=c.float("settle_time_s", **pos),
            pin_while_closing=c.bool("pin_while_closing"),
            servo_kp_scale=c.float("servo_kp_scale", min=1e-3),
            contact=ContactParams(friction=friction, solref=tuple(c.floats("solref", 2))),
            gws_mu=c.float("gws_mu", min=0.0))
        ld = root.section("lift_drop")
        ld.reject_unknown({"timestep_s", "impratio", "lift_height_m", "lift_time_s", "hold_time_s",
                           "drop_time_s", "max_displacement_m", "max_rotation_deg",
                           "drop_min_fall_m"})
        lift = LiftDropParams(
            timestep_s=ld.float("timestep_s", min=1e-4, max=0.02),
            impratio=ld.float("impratio", min=1.0),
            lift_height_m=ld.float("lift_height_m", **pos), lift_time_s=ld.float("lift_time_s", min=1e-3),
            hold_time_s=ld.float("hold_time_s", **pos), drop_time_s=ld.float("drop_time_s", **pos),
            max_displacement_m=ld.float("max_displacement_m", **pos),
            max_rotation_rad=np.deg2rad(ld.float("max_rotation_deg", min=0.0, max=180.0)),
            drop_min_fall_m=ld.float("drop_min_fall_m", **pos))
        sd = root.section("six_dir")
        sd.reject_unknown({"timestep_s", "impratio", "noslip_iterations", "force_per_kg", "push_time_s",
                           "max_displacement_m", "max_rotation_deg"})
        six = SixDirParams(
            timestep_s=sd.float("timestep_s", min=1e-4, max=0.02),
            impratio=sd.float("impratio", min=1.0),
            noslip_iterations=sd.int("noslip_iterations", min=0),
            force_per_kg=sd.float("force_per_kg", **pos), push_time_s=sd.float("push_time_s", **pos),
            max_displacement_m=sd.float("max_displacement_m", **pos),
            max_rotation_rad=np.deg2rad(sd.float("max_rotation_deg", min=0.0, max=180.0)))
        return cls(common, lift, six)


@dataclass
class PhaseResult:
    passed: bool
    displacement_m: float
    rotation_rad: float


@dataclass
class ValidationResult:
    """Outcome of one grasp under one protocol. Metrics are NaN where the run stopped before
    they could be measured (e.g. penetration rejects before simulating)."""

    protocol: str
    passed: bool
    failure: str | None
    penetration_m: float
    n_contacts: int = 0
    epsilon: float = float("nan")
    volume: float = float("nan")
    displacement_m: float = float("nan")
    rotation_rad: float = float("nan")
    phases: dict[str, PhaseResult] = field(default_factory=dict)
    contact_pos_obj: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    contact_normal_obj: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def summary(self) -> dict[str, object]:
        """Flat, JSON-friendly view (no arrays) for tables and logs."""
        out = asdict(self)
        out.pop("contact_pos_obj")
        out.pop("contact_normal_obj")
        out["phases"] = {k: asdict(v) for k, v in self.phases.items()}
        return out


@dataclass(frozen=True)
class GraspTargets:
    """Joint targets derived from a grasp: where to start closing and where to squeeze to, how
    many hand bodies were near the object, and the normal force (newtons) the squeeze target
    asks of each of them."""

    pregrasp: np.ndarray
    squeeze: np.ndarray
    n_bodies_near: int
    grip_force_n: float = 0.0


class Validator:
    """Validates grasps of one hand on one object; owns one scene per protocol (built lazily)."""

    def __init__(self, hand: Hand, obj: ObjectAsset, config: ValidateConfig | None = None) -> None:
        self.hand = hand
        self.obj = obj
        self.config = config or ValidateConfig.load()
        self._scenes: dict[str, Scene] = {}
        finger_joints = {j for f in hand.config.fingers for j in f.joints}
        self._finger_mask = np.array([n in finger_joints for n in hand.joint_names])

    def scene(self, protocol: str) -> Scene:
        if protocol not in PROTOCOLS:
            raise ValueError(f"unknown protocol {protocol!r}; expected one of {PROTOCOLS}")
        if protocol not in self._scenes:
            if protocol == "six-dir":
                six = self.config.six_dir
                physics = PhysicsOptions(timestep_s=six.timestep_s, impratio=six.impratio,
                                         noslip_iterations=six.noslip_iterations)
            else:
                lift = self.config.lift_drop
                physics = PhysicsOptions(timestep_s=lift.timestep_s, impratio=lift.impratio)
            scene = Scene(self.hand, self.obj, contact=self.config.common.contact,
                          physics=physics)
            scene.scale_servo_stiffness(self.config.common.servo_kp_scale)
            self._scenes[protocol] = scene
        return self._scenes[protocol]

    # ------------------------------------------------------------------------------- set-up

    def _place(self, scene: Scene, grasp: Grasp, q: np.ndarray) -> None:
        """Reset the scene with the object at home and the hand at the grasp's palm pose."""
        m, d = scene.model, scene.data
        mujoco.mj_resetData(m, d)
        obj_quat = np.array([1.0, 0.0, 0.0, 0.0])
        scene.set_object_pose(OBJECT_HOME, obj_quat)
        palm_pos, palm_quat = pose_mul(OBJECT_HOME, obj_quat, grasp.palm_pos, grasp.palm_quat_wxyz)
        base_pos, base_quat = self.hand.base_pose_for_palm(palm_pos, palm_quat, q)
        scene.set_hand_pose(base_pos, base_quat)
        scene.set_hand_joints(q)
        scene.set_hand_ctrl(q)
        m.opt.gravity[:] = 0.0
        mujoco.mj_forward(m, d)

    def _hand_object_contacts(self, scene: Scene, with_force: bool = False) -> Contacts:
        return contacts_between(scene.model, scene.data, scene.hand_geom_mask, scene.obj_geom_mask,
                                with_force=with_force)

    def _near_contacts(self, scene: Scene) -> Contacts:
        """Hand–object contacts and near misses (distance ≤ ``contact_search_m``) of the current
        placement: object geoms get that margin for one collision pass, then it is restored."""
        m, d = scene.model, scene.data
        search_m = self.config.common.contact_search_m
        saved = m.geom_margin.copy()
        m.geom_margin[scene.obj_geom_mask] = search_m
        mujoco.mj_collision(m, d)
        m.geom_margin[:] = saved
        near = self._hand_object_contacts(scene)
        keep = near.dist <= search_m
        return Contacts(near.pos[keep], near.normal[keep], near.dist[keep], near.body_a[keep],
                        near.force_n[keep])

    def grip_force_n(self, scene: Scene, points: np.ndarray) -> float:
        """Desired normal force (newtons) per grasping contact, for contacts at ``points`` (n, 3).

        Friction must carry the object's weight W and its moment about the grasp: with the
        centre of mass a distance d from the contacts' centroid and the contacts spread ρ (RMS)
        around it, friction forces hold a torque of about μ·Σf·ρ, so Σf ≥ W·(1 + d/ρ)/μ covers
        both (conservatively, as if they added). Scaled by ``grip_safety``, split over the n
        contacts, never less than ``min_grip_force_n``.
        """
        common, d = self.config.common, scene.data
        weight_n = scene.obj_mass_kg * GRAVITY_MPS2
        mu = common.contact.friction[0]
        centroid = points.mean(axis=0)
        spread_m = max(float(np.sqrt(((points - centroid) ** 2).sum(axis=1).mean())), _MIN_LEVER_M)
        offset_m = float(np.linalg.norm(d.xipos[scene.obj_body] - centroid))
        total_n = common.grip_safety * weight_n * (1.0 + offset_m / spread_m) / mu
        return max(total_n / len(points), common.min_grip_force_n)

    def joint_stiffness(self, scene: Scene) -> np.ndarray:
        """Joint-space stiffness (nq × nq over the hand's joints; N·m/rad for hinges) of the
        hand's finger servos at the current state: ``K_q = Mᵀ diag(k) M``.

        M is the actuator moment matrix (∂ actuator length / ∂ q, gear included) of the hand's
        actuators and k each actuator's position stiffness at a fixed control: ``−biasprm[1]``
        for a fixed-gain, affine-bias actuator (a position servo: kp), 0 for anything else (a
        motor holds no position). Rows and columns outside the finger joints are zero, since the
        squeeze moves fingers only. Needs ``mj_forward`` (or ``mj_fwdPosition``) to have run.
        """
        m, d = scene.model, scene.data
        moment = np.zeros((m.nu, m.nv))
        mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr,
                                d.moment_colind)
        acts = scene.hand_act
        k = np.where(scene.position_servos(), np.maximum(-m.actuator_biasprm[acts, 1], 0.0), 0.0)
        arm = moment[np.ix_(acts, scene.hand_dadr)] * self._finger_mask
        return arm.T @ (k[:, None] * arm)

    @staticmethod
    def _stiffness_pinv(stiffness: np.ndarray) -> np.ndarray:
        """Damped pseudo-inverse s / (s² + λ²) per eigenvalue s of a symmetric stiffness: ≈ 1/s
        where the servos are stiff, → 0 (not 1/λ) along directions no actuator resists, such as
        the difference of two tendon-coupled joints."""
        s, v = np.linalg.eigh(stiffness)
        lam = _STIFFNESS_DAMPING * max(float(s.max(initial=0.0)), 1e-12)
        return (v * (s / (s * s + lam * lam))) @ v.T

    def derive_targets(self, scene: Scene, q: np.ndarray) -> GraspTargets:
        """Pregrasp and squeeze joint vectors from the contacts near the placed grasp.

        Object geoms get a temporary margin of ``contact_search_m`` so MuJoCo reports near
        misses with their distance; per hand body the closest point is moved along its normal
        (by distance − backoff for the pregrasp, distance + squeeze depth for the squeeze). The
        squeeze then adds the servo deflection ``K_q⁺ Jᵀ f`` that presses each of those points
        into the object with the grip force f (module docstring).
        """
        m, d, common = scene.model, scene.data, self.config.common
        near = self._near_contacts(scene)
        rows, gaps, closest = [], [], []
        jacp = np.zeros((3, m.nv))
        points = near.points_a
        for body in np.unique(near.body_a):
            sel = np.flatnonzero(near.body_a == body)
            i = sel[np.argmin(near.dist[sel])]
            mujoco.mj_jac(m, d, jacp, None, points[i], int(body))
            rows.append(near.normal[i] @ jacp[:, scene.hand_dadr])
            gaps.append(near.dist[i])
            closest.append(points[i])
        if not rows:
            return GraspTargets(q, q, 0)
        jac = np.array(rows) * self._finger_mask
        gaps = np.array(gaps)
        solve = np.linalg.solve(jac @ jac.T + _JAC_DAMPING_M2 * np.eye(len(rows)),
                                np.eye(len(rows)))
        pinv = jac.T @ solve
        pre = self.hand.clip(q + pinv @ (gaps - common.pregrasp_backoff_m))
        force_n = self.grip_force_n(scene, np.array(closest))
        # joint torques that press every contact with force_n (normals point into the object),
        # and the servo deflection that produces them
        torque = jac.T @ np.full(len(rows), force_n)
        deflection = self._stiffness_pinv(self.joint_stiffness(scene)) @ torque
        squeeze = self.hand.clip(q + pinv @ (gaps + common.squeeze_depth_m) + deflection)
        return GraspTargets(pre, squeeze, len(rows), force_n)

    def _relative_object_pose(self, scene: Scene) -> tuple[np.ndarray, np.ndarray]:
        palm_pos, palm_quat = scene.palm_world_pose()
        obj_pos, obj_quat = scene.object_pose()
        inv_p, inv_q = pose_inv(palm_pos, palm_quat)
        return pose_mul(inv_p, inv_q, obj_pos, obj_quat)

    def _run(self, scene: Scene, seconds: float, ctrl_from: np.ndarray | None = None,
             ctrl_to: np.ndarray | None = None, *,
             pin: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Step ``seconds`` of simulation, ramping hand controls linearly when given; with
        ``pin`` (position, wxyz) the object is held at that pose after every step."""
        m, d = scene.model, scene.data
        steps = max(round(seconds / m.opt.timestep), 0)
        if ctrl_from is None and pin is None:
            if steps:
                mujoco.mj_step(m, d, nstep=steps)
            return
        for k in range(steps):
            if ctrl_from is not None and ctrl_to is not None:
                alpha = (k + 1) / steps
                d.ctrl[scene.hand_act] = (1 - alpha) * ctrl_from + alpha * ctrl_to
            mujoco.mj_step(m, d)
            if pin is not None:
                scene.set_object_pose(*pin)

    def _close(self, scene: Scene, targets: GraspTargets) -> None:
        """From the pregrasp, close the fingers onto the squeeze target with gravity off.

        With ``pin_while_closing`` the object is held still while the fingers close, as the
        table or the other hand holds a real object while a grasp is acquired: fingers reach
        the object at different times, and the first one to arrive would otherwise push a free,
        weightless object out of the hand before the others touch — a failure of the closing
        sequence, not of the grasp. It is released for the settle phase, where an unbalanced
        squeeze still moves it before the lift measures its pose in the palm."""
        scene.set_hand_joints(targets.pregrasp)
        scene.set_hand_ctrl(targets.pregrasp)
        mujoco.mj_forward(scene.model, scene.data)
        common = self.config.common
        ctrl_pre = self.hand.ctrl_for(targets.pregrasp)
        ctrl_sq = self.hand.ctrl_for(targets.squeeze)
        pin = scene.object_pose() if common.pin_while_closing else None
        self._run(scene, common.close_time_s, ctrl_pre, ctrl_sq, pin=pin)
        self._run(scene, common.settle_time_s)

    def _measure_contacts(self, scene: Scene, result: ValidationResult) -> None:
        """Contact count and the grasp wrench space of the simulated contacts (object frame)."""
        con = self._hand_object_contacts(scene)
        touching = con.dist <= 1e-4
        result.n_contacts = int(touching.sum())
        obj_pos, obj_quat = scene.object_pose()
        inv_p, inv_q = pose_inv(obj_pos, obj_quat)
        pts = inv_p + rotate(inv_q, con.pos[touching])
        nrm = rotate(inv_q, con.normal[touching])
        result.contact_pos_obj, result.contact_normal_obj = pts, nrm
        pts, nrm = merge_nearby(pts, nrm, con.body_a[touching])
        metrics = gws_metrics(pts, nrm, mu=self.config.common.gws_mu, centre=self.obj.com_m,
                              torque_scale_m=self.obj.max_radius_m)
        result.epsilon, result.volume = metrics.epsilon, metrics.volume

    # ---------------------------------------------------------------------------- protocols

    def penetration_m(self, grasp: Grasp, protocol: str = "lift-drop") -> float:
        """Deepest hand–object penetration (metres, 0 when none) of the grasp placed as
        :meth:`validate` places it: the check validate() makes before simulating, public so a
        sampler can drop what would fail it (one collision pass, no simulation)."""
        q = self.hand.check_q(grasp.joints, "grasp joints")
        if q.ndim != 1:
            raise ValueError("one grasp at a time; use sim.validate.batch for many")
        scene = self.scene(protocol)
        self._place(scene, grasp, q)
        return self._hand_object_contacts(scene).max_penetration_m

    def validate(self, grasp: Grasp, protocol: str = "lift-drop") -> ValidationResult:
        """Validate one grasp; see the module docstring and DESIGN §5 for the protocols."""
        penetration = self.penetration_m(grasp, protocol)
        q = self.hand.check_q(grasp.joints, "grasp joints")
        scene = self.scene(protocol)
        result = ValidationResult(protocol=protocol, passed=False, failure=None,
                                  penetration_m=penetration)
        if penetration > self.config.common.max_penetration_m:
            result.failure = Failure.PENETRATION
            return result
        targets = self.derive_targets(scene, q)
        if targets.n_bodies_near == 0:
            result.failure = Failure.NO_CONTACT
            return result
        self._close(scene, targets)
        self._measure_contacts(scene, result)
        if result.n_contacts == 0:
            result.failure = Failure.LOST_CONTACT
            return result
        if protocol == "lift-drop":
            self._lift_drop(scene, targets, result)
        else:
            self._six_dir(scene, result)
        return result

    def fingertip_contacts(self, grasp: Grasp) -> dict[str, np.ndarray | None]:
        """Per finger, the centroid (metres, fingertip body frame) of the hand–object contacts
        of its tip body at the placed grasp (within ``contact_search_m``), or None. This is what
        AutoWS needs from a demonstration."""
        q = self.hand.check_q(grasp.joints, "grasp joints")
        scene = self.scene("lift-drop")
        self._place(scene, grasp, q)
        m, d = scene.model, scene.data
        near = self._near_contacts(scene)
        points = near.points_a
        out: dict[str, np.ndarray | None] = {}
        for finger in self.hand.config.fingers:
            body = m.body(HAND_PREFIX + finger.tip_body).id
            sel = near.body_a == body
            if not sel.any():
                out[finger.name] = None
                continue
            local = (points[sel] - d.xpos[body]) @ d.xmat[body].reshape(3, 3)
            out[finger.name] = local.mean(axis=0)
        return out

    def render(self, grasp: Grasp, width: int = 640, height: int = 480) -> np.ndarray:
        """RGB image of the grasp after closing (lift-drop scene), contacts marked."""
        from sim.world.render import render_scene

        q = self.hand.check_q(grasp.joints, "grasp joints")
        scene = self.scene("lift-drop")
        self._place(scene, grasp, q)
        targets = self.derive_targets(scene, q)
        if targets.n_bodies_near:
            self._close(scene, targets)
        obj_pos, _ = scene.object_pose()
        return render_scene(scene.model, scene.data, lookat=obj_pos, width=width, height=height)

    def _drift(self, scene: Scene, ref_pos: np.ndarray, ref_quat: np.ndarray) -> tuple[float, float]:
        pos, quat = self._relative_object_pose(scene)
        return float(np.linalg.norm(pos - ref_pos)), float(quat_angle(quat, ref_quat))

    def _lift_drop(self, scene: Scene, targets: GraspTargets, result: ValidationResult) -> None:
        m, d, p = scene.model, scene.data, self.config.lift_drop
        ref_pos, ref_quat = self._relative_object_pose(scene)
        start = d.mocap_pos[scene.mocap_id].copy()
        m.opt.gravity[:] = (0.0, 0.0, -GRAVITY_MPS2)
        lift_steps = max(round(p.lift_time_s / m.opt.timestep), 1)
        chunk = max(lift_steps // 50, 1)
        ok = True
        for k in range(0, lift_steps, chunk):
            rise = p.lift_height_m * min(k + chunk, lift_steps) / lift_steps
            d.mocap_pos[scene.mocap_id] = start + np.array([0.0, 0.0, rise])
            mujoco.mj_step(m, d, nstep=min(chunk, lift_steps - k))
            disp, rot = self._drift(scene, ref_pos, ref_quat)
            if disp > p.max_displacement_m or rot > p.max_rotation_rad:
                ok = False
                break
        result.phases["lift"] = PhaseResult(ok, disp, rot)
        if ok:
            self._run(scene, p.hold_time_s)
            disp, rot = self._drift(scene, ref_pos, ref_quat)
            ok = bool(disp <= p.max_displacement_m and rot <= p.max_rotation_rad)
            result.phases["hold"] = PhaseResult(ok, disp, rot)
        result.displacement_m, result.rotation_rad = disp, rot
        if not ok:
            result.failure = Failure.SLIPPED
            return
        self._release(scene, targets, ref_pos, ref_quat, result)

    def _release(self, scene: Scene, targets: GraspTargets, ref_pos: np.ndarray,
                 ref_quat: np.ndarray, result: ValidationResult) -> None:
        """Open the hand and pull the object out of the palm: a real grasp lets go.

        Gravity is turned to point out of the palm face (frame_palm +y) while the fingers open
        to the pregrasp and then to the hand's open pose, so a wrap grasp or a palm-up grasp
        releases too; an object that stays put is held by interpenetration (DESIGN §5 drops
        along world −z, which a palm-up grasp never passes; see the closing note).
        """
        m, p = scene.model, self.config.lift_drop
        _, palm_quat = scene.palm_world_pose()
        m.opt.gravity[:] = GRAVITY_MPS2 * rotate(palm_quat, np.array([0.0, 1.0, 0.0]))
        ctrl_sq = self.hand.ctrl_for(targets.squeeze)
        ctrl_open = self.hand.ctrl_for(self.hand.open_pose)
        self._run(scene, 0.5 * p.drop_time_s, ctrl_sq, ctrl_open)
        fall, turn = self._drift(scene, ref_pos, ref_quat)
        steps = round(0.5 * p.drop_time_s / m.opt.timestep)
        chunk = max(steps // 10, 1)
        for k in range(0, steps, chunk):  # stop as soon as the object has left
            if fall >= p.drop_min_fall_m:
                break
            mujoco.mj_step(m, scene.data, nstep=min(chunk, steps - k))
            fall, turn = self._drift(scene, ref_pos, ref_quat)
        dropped = bool(fall >= p.drop_min_fall_m)
        result.phases["drop"] = PhaseResult(dropped, fall, turn)
        result.passed = dropped
        result.failure = None if dropped else Failure.STUCK

    def _six_dir(self, scene: Scene, result: ValidationResult) -> None:
        m, d, p = scene.model, scene.data, self.config.six_dir
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(mujoco.mj_stateSize(m, spec))
        mujoco.mj_getState(m, d, state, spec)
        ref_pos, ref_quat = self._relative_object_pose(scene)
        force = p.force_per_kg * scene.obj_mass_kg
        steps = max(round(p.push_time_s / m.opt.timestep), 1)
        chunk = max(steps // 20, 1)
        worst = (0.0, 0.0)
        all_ok = True
        for name, direction in SIX_DIRECTIONS.items():
            mujoco.mj_setState(m, d, state, spec)
            d.xfrc_applied[scene.obj_body, :3] = force * np.asarray(direction, float)
            ok = True
            for k in range(0, steps, chunk):
                mujoco.mj_step(m, d, nstep=min(chunk, steps - k))
                disp, rot = self._drift(scene, ref_pos, ref_quat)
                if disp > p.max_displacement_m or rot > p.max_rotation_rad:
                    ok = False
                    break
            d.xfrc_applied[scene.obj_body] = 0.0
            result.phases[name] = PhaseResult(ok, disp, rot)
            worst = (max(worst[0], disp), max(worst[1], rot))
            all_ok &= ok
        result.displacement_m, result.rotation_rad = worst
        result.passed = all_ok
        result.failure = None if all_ok else Failure.SLIPPED
