"""Physical grasp validation in MuJoCo: the ``lift-drop``, ``six-dir`` and ``dgb`` protocols
(DESIGN §5).

:class:`Validator` places a grasp (palm pose in the object frame + joint vector) in a scene of
the hand and the object, rejects it when the hand penetrates the object or itself, derives its
pregrasp and squeeze targets (:mod:`sim.validate.targets`), closes the fingers onto the object,
measures the contacts and runs one protocol (:mod:`sim.validate.lift_drop`, ``six_dir``).
``dgb`` is DexGraspBench's evaluation with its own scene (floating palm, kp 5 / ±3 N·m servos,
0.1 kg object, μ 0.6) and closing (:mod:`sim.validate.dgb`, ``stages``, ``rehearsal``).

lift-drop and six-dir multiply each hand servo's own kp by ``servo_kp_scale`` (5 by default,
or the hand's own ``[validate] servo_kp_scale``; force limits stay the model's): kp is the
controller's gain, and at the Menagerie models' ≈ 1 N·m/rad a grasp that holds the object
still turns it past the 15° limit under its own weight. Every scene's contact values are set
on hand and object geoms alike, so they are what every contact simulates. Simulation is
deterministic: the same grasp gives the same result on any worker.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mujoco
import numpy as np

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.metrics.gws import gws_metrics
from sim.metrics.holding import HoldLoads
from sim.transforms import pose_inv, pose_mul, rotate
from sim.validate.batched import BatchRunner, ProgramRunner, validate_batched
from sim.validate.config import PROTOCOLS, ValidateConfig
from sim.validate.dgb import dgb_penetration_m, run_dgb
from sim.validate.effort import actuator_effort
from sim.validate.lift_drop import Observer, lift_drop, unit_down
from sim.validate.loads import hold_loads
from sim.validate.program import Advance, Program, run_here
from sim.validate.rehearsal import rehearsed
from sim.validate.result import Failure, ValidationResult
from sim.validate.six_dir import six_dir
from sim.validate.stages import GraspStages, grasp_stages
from sim.validate.targets import (
    GraspTargets,
    finger_joint_mask,
    holds_every_load,
    loads_in_world,
    servo_limits_from,
    servo_stiffness_from,
    targets_from_contacts,
    weight_loads,
)
from sim.world.contacts import Contacts, contacts_between, merge_nearby
from sim.world.hand_spec import ServoSettings
from sim.world.objects import ObjectAsset
from sim.world.scene import HAND_PREFIX, OBJECT_HOME, PhysicsOptions, Scene

__all__ = ["BACKENDS", "BATCH_SIMS", "Validator"]

#: engines lift-drop and six-dir can step on: MuJoCo (C, mujoco.batch threads), MuJoCo Warp
BACKENDS = ("mujoco", "warp")

#: grasps a validator keeps in flight at once on mujoco.batch (lift-drop, six-dir)
BATCH_SIMS = 16


class Validator:
    """Validates grasps of one hand on one object; owns one scene per protocol (built lazily)."""

    def __init__(self, hand: Hand, obj: ObjectAsset, config: ValidateConfig | None = None) -> None:
        self.hand = hand
        self.obj = obj
        self.config = config or ValidateConfig.load()
        self._scenes: dict[str, Scene] = {}
        self._finger_mask = finger_joint_mask(hand)
        self._runners: dict[tuple[object, ...], ProgramRunner] = {}

    def scene(self, protocol: str) -> Scene:
        if protocol not in PROTOCOLS:
            raise ValueError(f"unknown protocol {protocol!r}; expected one of {PROTOCOLS}")
        if protocol not in self._scenes:
            self._scenes[protocol] = self._build_scene(protocol)
        return self._scenes[protocol]

    def _build_scene(self, protocol: str) -> Scene:
        """The scene of a protocol, with the physics, contacts and servos its config states."""
        common = self.config.common
        if protocol == "dgb":
            p = self.config.dgb
            physics = PhysicsOptions(timestep_s=p.timestep_s, impratio=p.impratio,
                                     noslip_iterations=p.noslip_iterations,
                                     solver_iterations=p.solver_iterations,
                                     weld_solref=p.weld_solref, sparse_jacobian=None)
            return Scene(self.hand, self.obj, contact=p.contact, physics=physics, servos=p.servos,
                         floating_palm=True, object_mass_kg=p.object_mass_kg, contact_on_hand=True)
        if protocol == "six-dir":
            six = self.config.six_dir
            physics = PhysicsOptions(timestep_s=six.timestep_s, impratio=six.impratio,
                                     noslip_iterations=six.noslip_iterations)
        else:
            lift = self.config.lift_drop
            physics = PhysicsOptions(timestep_s=lift.timestep_s, impratio=lift.impratio)
        return Scene(self.hand, self.obj, contact=common.contact, physics=physics,
                     servos=self.servos, contact_on_hand=True)

    @property
    def servos(self) -> ServoSettings:
        """Lift-drop's and six-dir's servos: ``[common] servo_kp_scale`` or hand.toml's own."""
        scale = self.hand.config.validate_kp_scale
        return self.config.common.servos if scale is None else ServoSettings(kp_scale=scale)

    def _place(self, scene: Scene, grasp: Grasp, q: np.ndarray) -> None:
        """Reset the scene with the object at home and the hand at the grasp's palm pose."""
        scene.reset_with_grasp(*self.palm_world(grasp), q)

    @staticmethod
    def palm_world(grasp: Grasp) -> tuple[np.ndarray, np.ndarray]:
        """frame_palm of ``grasp`` in the world (metres, wxyz), the object being at home."""
        return pose_mul(OBJECT_HOME, np.array([1.0, 0.0, 0.0, 0.0]), grasp.palm_pos, grasp.palm_quat_wxyz)

    def _hand_object_contacts(self, scene: Scene, with_force: bool = False) -> Contacts:
        return contacts_between(scene.model, scene.data, scene.hand_geom_mask, scene.obj_geom_mask,
                                with_force=with_force)

    def near_contacts(self, scene: Scene, search_m: float | None = None) -> Contacts:
        """Hand–object contacts and near misses within ``search_m`` (default ``[common]
        contact_search_m``): object geoms get that margin for one collision pass, then no more."""
        m, d = scene.model, scene.data
        search_m = self.config.common.contact_search_m if search_m is None else search_m
        saved = m.geom_margin.copy()
        m.geom_margin[scene.obj_geom_mask] = search_m
        mujoco.mj_collision(m, d)
        m.geom_margin[:] = saved
        near = self._hand_object_contacts(scene)
        keep = near.dist <= search_m
        return Contacts(near.pos[keep], near.normal[keep], near.dist[keep], near.body_a[keep],
                        near.force_n[keep])

    def derive_targets(self, scene: Scene, q: np.ndarray, down: np.ndarray | None = None, *,
                       sized_for: str = "lift-drop", own_pregrasp: bool = True) -> GraspTargets:
        """Pregrasp and squeeze joint vectors from the contacts near the placed grasp
        (:func:`sim.validate.targets.targets_from_contacts`), the grip sized for protocol
        ``sized_for``: ``lift-drop`` — the weight along ``down`` (None: −z); ``six-dir`` and
        ``dgb`` — their six pushes (:func:`sim.validate.loads.hold_loads`). ``dgb`` takes its
        servos from its compiled scene, presses only the bodies within ``[dgb] contact_search_m``
        unless those cannot hold every push (:func:`sim.validate.targets.holds_every_load`),
        and for the closing's ``own_pregrasp`` (``dexaug``; ``bodex`` makes its squeeze from the
        pregrasp) settles the fingers' free modes (:mod:`sim.validate.free_modes`) and keeps the
        pregrasp out of itself (:mod:`sim.validate.self_clearance`); lift-drop keeps both."""
        if sized_for == "lift-drop":
            loads = weight_loads(scene.obj_mass_kg, scene.data.xipos[scene.obj_body],
                                 self.config.common, down)
        else:   # hold_loads refuses an unknown protocol
            loads = loads_in_world(hold_loads(self.obj, sized_for, self.config), scene)
        dgb = self.scene("dgb") if sized_for == "dgb" else None
        near = self.near_contacts(scene, None if dgb is None else self.config.dgb.contact_search_m)
        if dgb is not None and not holds_every_load(near, loads):
            near = self.near_contacts(scene)
        servos = {} if dgb is None else {
            "act_stiffness": servo_stiffness_from(dgb, scene), "act_limits": servo_limits_from(dgb, scene),
            "settle_modes": own_pregrasp and self.config.dgb.settle_free_modes, "self_clear": own_pregrasp}
        return targets_from_contacts(scene, self.hand, q, near, self.config.common, self._finger_mask,
                                     loads, **servos)

    def stages(self, grasp: Grasp, convention: str | None = None, *,
               sized_for: str = "lift-drop") -> GraspStages:
        """Pregrasp, grasp and squeeze of ``grasp``: its own when it carries them, else made by
        ``convention`` (default: ``[dgb] squeeze_convention``; :mod:`sim.validate.stages`),
        whose ``dexaug`` targets come from the lift-drop scene's contacts with the grip sized for
        ``sized_for`` (:meth:`derive_targets`; arm lift: ``lift-drop``; ``dgb``: rehearsed)."""
        self.hand.check_q(grasp.joints, "grasp joints")
        convention = convention or self.config.dgb.squeeze_convention

        def derive(q: np.ndarray) -> GraspTargets:
            scene = self.scene("lift-drop")
            self._place(scene, grasp, q)
            return self.derive_targets(scene, q, sized_for=sized_for, own_pregrasp=convention == "dexaug")

        stages = grasp_stages(grasp, convention, derive, through_touch=sized_for == "dgb")
        return stages if sized_for != "dgb" else rehearsed(self.scene("dgb"), self.config.dgb,
                                                           self.palm_world(grasp), stages)

    def _close(self, scene: Scene, targets: GraspTargets) -> None:
        """Close the fingers of the grasp placed in ``scene`` onto ``targets``, here."""
        self._start_closing(scene, targets)
        run_here(scene, self._closing(scene, targets))

    @staticmethod
    def _start_closing(scene: Scene, targets: GraspTargets) -> None:
        """Put the placed grasp's fingers at the pregrasp, at rest, their servos holding it."""
        scene.set_hand_joints(targets.pregrasp)
        scene.set_hand_ctrl(targets.pregrasp)
        mujoco.mj_forward(scene.model, scene.data)

    def _closing(self, scene: Scene, targets: GraspTargets) -> Program:
        """From the pregrasp, close the fingers onto the squeeze target with gravity off.

        By default the object is free while the fingers close (DESIGN §5): a grasp whose first
        finger to arrive shoves the object out of the hand fails. ``pin_while_closing`` (a named
        option; results record it) holds the object still until the settle phase instead, as a
        table or another hand would while a grasp is acquired; an unbalanced squeeze still moves
        it during the settle, before the lift measures its pose in the palm."""
        common = self.config.common
        timestep = scene.model.opt.timestep
        pin = scene.object_pose() if common.pin_while_closing else None
        yield Advance(max(round(common.close_time_s / timestep), 0),
                      ctrl_from=scene.ctrl_for(targets.pregrasp),
                      ctrl_to=scene.ctrl_for(targets.squeeze), pin=pin)
        yield Advance(max(round(common.settle_time_s / timestep), 0))

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

    def actuator_effort(self, grasp: Grasp, hold: HoldLoads, protocol: str = "lift-drop") -> float:
        """Least worst actuator effort (fraction of the force limits of ``protocol``'s scene)
        with which the hand could hold ``hold``'s loads at the grasp's contacts
        (:mod:`sim.validate.effort`); > 1: these actuators cannot hold them however the grasp
        squeezes. One collision pass and a linear programme, no simulation."""
        scene = self.scene(protocol)
        self._place(scene, grasp, self.hand.check_q(grasp.joints, "grasp joints"))
        return actuator_effort(scene, self.near_contacts(scene), self._finger_mask, hold)

    def penetration_m(self, grasp: Grasp, protocol: str = "lift-drop") -> float:
        """Deepest penetration (metres, 0 when none) of the hand into the object or into itself
        (links inside each other: a pose no hand can take), the grasp placed as :meth:`validate`
        places it: the check validate() makes before simulating, public so a sampler can drop
        what would fail it (one collision pass, no simulation)."""
        q = self.hand.check_q(grasp.joints, "grasp joints")
        if q.ndim != 1:
            raise ValueError("one grasp at a time; use sim.validate.batch for many")
        self._place(scene := self.scene(protocol), grasp, q)
        return max(dgb_penetration_m(scene))   # (hand–object, hand–hand) of the placed grasp

    def validate(self, grasp: Grasp, protocol: str = "lift-drop", *,
                 squeeze_convention: str | None = None,
                 observe: Observer | None = None,
                 gravity_dir: np.ndarray | None = None) -> ValidationResult:
        """Validate one grasp; see the module docstring and DESIGN §5 for the protocols.
        ``squeeze_convention`` (dgb only) overrides ``[dgb] squeeze_convention``; ``observe``
        (lift-drop only, for :mod:`sim.validate.diagnose`) is called with "closed" once the
        fingers have closed and settled, then through the lift and hold; ``gravity_dir``
        (lift-drop only; object frame, default −z): the way gravity pulls during the lift
        (:func:`sim.validate.lift_drop.lift_drop`)."""
        if protocol == "dgb":
            return self._validate_dgb(grasp, squeeze_convention)
        result, program = self.start(grasp, protocol, observe=observe, gravity_dir=gravity_dir)
        if program is not None:
            run_here(self.scene(protocol), program)
        return result

    def validate_all(self, grasps: Sequence[Grasp], protocol: str = "lift-drop", *,
                     nthread: int = 1, squeeze_convention: str | None = None,
                     progress: Callable[[int], None] | None = None,
                     backend: str = "mujoco", device: str = "cuda",
                     nworld: int = 1024,
                     gravity_dir: np.ndarray | None = None) -> list[ValidationResult]:
        """Validate ``grasps`` in input order, the results exactly :meth:`validate`'s.

        With ``nthread`` > 1, lift-drop and six-dir run up to :data:`BATCH_SIMS` grasps at once
        on ``mujoco.batch`` with that many threads (:mod:`sim.validate.batched`): one process
        using several cores. With one thread they step grasp by grasp from Python, which
        measured 12 % faster than a one-thread batch (``benchmarks/bench_validate_speed.py``:
        MuJoCo's step is 75 % of the time either way, and one MjData stays in cache); the
        results are the same bit for bit. dgb always steps grasp by grasp.
        ``backend="warp"`` steps lift-drop and six-dir as ``nworld`` worlds of MuJoCo Warp on
        ``device`` instead (:mod:`sim.validate.warp_runner`; close to, not bit-identical with,
        the C engine's results). ``progress(n_done)`` is called as grasps finish;
        ``gravity_dir`` as in :meth:`validate`."""
        if backend not in BACKENDS:
            raise ValueError(f"backend {backend!r}: expected one of {BACKENDS}")
        if backend != "mujoco" and protocol not in ("lift-drop", "six-dir"):
            raise ValueError(f"backend {backend!r} runs lift-drop and six-dir, not {protocol!r}")
        if protocol not in ("lift-drop", "six-dir") or (backend == "mujoco" and nthread == 1):
            out = []
            for g in grasps:
                out.append(self.validate(g, protocol, squeeze_convention=squeeze_convention,
                                         gravity_dir=gravity_dir))
                if progress is not None:
                    progress(len(out))
            return out
        key = (protocol, backend, nthread if backend == "mujoco" else (device, nworld))
        if key not in self._runners:
            if backend == "warp":
                from sim.validate.warp_runner import WarpRunner

                self._runners[key] = WarpRunner(self.scene(protocol), nworld, device)
            else:
                self._runners[key] = BatchRunner(self.scene(protocol), BATCH_SIMS, nthread)
        return validate_batched(self._runners[key], grasps,
                                lambda g, view: self.start(g, protocol, scene=view,
                                                           gravity_dir=gravity_dir), progress)

    def start(self, grasp: Grasp, protocol: str, *, scene: Scene | None = None,
              observe: Observer | None = None, gravity_dir: np.ndarray | None = None,
              ) -> tuple[ValidationResult, Program | None]:
        """Place ``grasp`` in the protocol's scene and decide what can be decided without
        simulating (penetration, no hand body near the object); the result so far and, when
        simulation must follow, the program that finishes it (:mod:`sim.validate.program`),
        from the scene's state as this call leaves it. ``scene`` (default: the protocol's
        scene) is what the program reads: a batch runner gives a view of its own simulation
        here, whose state it has loaded from the protocol's scene. lift-drop and six-dir only;
        ``gravity_dir`` as in :meth:`validate`.
        """
        if gravity_dir is not None and protocol != "lift-drop":
            raise ValueError(f"gravity_dir is lift-drop's; {protocol!r} pushes along fixed axes")
        down = None if gravity_dir is None else unit_down(gravity_dir)
        if protocol not in ("lift-drop", "six-dir"):
            raise ValueError(f"protocol {protocol!r} has no program; expected lift-drop or six-dir")
        penetration = self.penetration_m(grasp, protocol)
        q = self.hand.check_q(grasp.joints, "grasp joints")
        here = self.scene(protocol)
        result = ValidationResult(protocol=protocol, passed=False, failure=None,
                                  penetration_m=penetration,
                                  closing="pinned" if self.config.common.pin_while_closing else "free")
        if penetration > self.config.common.max_penetration_m:
            result.failure = Failure.PENETRATION
            return result, None
        targets = self.derive_targets(here, q, down, sized_for=protocol)
        result.pregrasp, result.squeeze = targets.pregrasp, targets.squeeze
        result.squeeze_convention = "dexaug"
        if targets.n_bodies_near == 0:
            result.failure = Failure.NO_CONTACT
            return result, None
        self._start_closing(here, targets)
        return result, self._protocol(scene or here, protocol, targets, result, observe, down)

    def _protocol(self, scene: Scene, protocol: str, targets: GraspTargets,
                  result: ValidationResult, observe: Observer | None,
                  gravity_dir: np.ndarray | None = None) -> Program:
        """Closing, contact measurement and the protocol's own phases, as one program."""
        yield from self._closing(scene, targets)
        self._measure_contacts(scene, result)
        if result.n_contacts == 0:
            result.failure = Failure.LOST_CONTACT
            return
        if protocol == "lift-drop":
            if observe is not None:
                observe("closed")
            yield from lift_drop(scene, self.hand, self.config.lift_drop, targets, result, observe,
                                 gravity_dir)
        else:
            yield from six_dir(scene, self.config.six_dir, result)

    def _validate_dgb(self, grasp: Grasp, convention: str | None) -> ValidationResult:
        """The benchmark's protocol on the grasp's stages (:mod:`sim.validate.dgb`)."""
        stages = self.stages(grasp, convention, sized_for="dgb")
        scene = self.scene("dgb")
        result = ValidationResult("dgb", False, None, 0.0, closing="free", touch=stages.grasp,
                                  squeeze_convention=stages.made_by,
                                  pregrasp=stages.pregrasp, squeeze=stages.squeeze)
        run_dgb(scene, self.config.dgb, self.palm_world(grasp), stages, result,
                after_first_close=lambda: self._measure_contacts(scene, result))
        return result

    def fingertip_contacts(self, grasp: Grasp) -> dict[str, np.ndarray | None]:
        """Per finger, the centroid (metres, fingertip body frame) of the hand–object contacts
        of its tip body at the placed grasp (within ``contact_search_m``), or None. This is what
        AutoWS needs from a demonstration."""
        q = self.hand.check_q(grasp.joints, "grasp joints")
        scene = self.scene("lift-drop")
        self._place(scene, grasp, q)
        m, d = scene.model, scene.data
        near = self.near_contacts(scene)
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

    def render(self, grasp: Grasp, width: int = 640, height: int = 480, *,
               geom_ids: list[np.ndarray] | None = None) -> np.ndarray:
        """RGB image of the grasp after closing in the lift-drop scene, framed by
        :func:`sim.validate.grasp_image.framed_image`."""
        from sim.validate.grasp_image import framed_image

        q = self.hand.check_q(grasp.joints, "grasp joints")
        scene = self.scene("lift-drop")
        self._place(scene, grasp, q)
        targets = self.derive_targets(scene, q)
        if targets.n_bodies_near:
            self._close(scene, targets)
        return framed_image(scene, width, height, geom_ids=geom_ids)
