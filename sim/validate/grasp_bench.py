"""The shared services of every validation protocol: the hand and the object on the bench.

:class:`GraspBench` owns one scene per protocol (built lazily by the protocol,
:mod:`sim.validate.protocols`), places a grasp (palm pose in the object frame + joint vector)
with the object at home, reads the hand–object contacts and near misses, derives the grasp's
pregrasp and squeeze targets sized for a protocol's loads (:mod:`sim.validate.targets`), makes
its stages (:mod:`sim.validate.stages`), closes the fingers (:mod:`sim.validate.closing`) and
measures the contacts. It is what a protocol's :class:`~sim.validate.protocols.base.Bench` is;
:class:`sim.validate.validator.Validator` adds the entry points.

lift-drop and six-dir multiply each hand servo's own kp by ``servo_kp_scale`` (5 by default,
or the hand's own ``[validate] servo_kp_scale``; force limits stay the model's): kp is the
controller's gain, and at the Menagerie models' ≈ 1 N·m/rad a grasp that holds the object
still turns it past the 15° limit under its own weight. Every scene's contact values are set
on hand and object geoms alike, so they are what every contact simulates.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.metrics.holding import HoldLoads
from sim.transforms import pose_mul
from sim.validate.closing import close, hand_object_contacts, measure_contacts
from sim.validate.config import ValidateConfig
from sim.validate.dgb import dgb_penetration_m
from sim.validate.effort import actuator_effort
from sim.validate.protocols.registry import get
from sim.validate.result import ValidationResult
from sim.validate.stages import GraspStages, grasp_stages
from sim.validate.targets import GraspTargets, finger_joint_mask, holds_every_load, targets_from_contacts
from sim.world.contacts import Contacts
from sim.world.hand_spec import ServoSettings
from sim.world.objects import ObjectAsset
from sim.world.scene import HAND_PREFIX, OBJECT_HOME, Scene

__all__ = ["PLACING_SCENE", "GraspBench"]

#: the protocol scene grasps are placed in to read their contacts and derive their stages
PLACING_SCENE = "lift-drop"


class GraspBench:
    """One hand and one object, with the placing, contact and closing services protocols use."""

    def __init__(self, hand: Hand, obj: ObjectAsset, config: ValidateConfig | None = None) -> None:
        self.hand = hand
        self.obj = obj
        self.config = config or ValidateConfig.load()
        self._scenes: dict[str, Scene] = {}
        self._finger_mask = finger_joint_mask(hand)

    def scene(self, protocol: str) -> Scene:
        """The scene of registered protocol ``protocol``, built the first time."""
        built = get(protocol)   # an unknown name raises, listing the registered ones
        if protocol not in self._scenes:
            self._scenes[protocol] = built.build_scene(self)
        return self._scenes[protocol]

    @property
    def servos(self) -> ServoSettings:
        """Lift-drop's and six-dir's servos: ``[common] servo_kp_scale`` or hand.toml's own."""
        scale = self.hand.config.validate_kp_scale
        return self.config.common.servos if scale is None else ServoSettings(kp_scale=scale)

    def place(self, scene: Scene, grasp: Grasp, q: np.ndarray) -> None:
        """Reset the scene with the object at home and the hand at the grasp's palm pose."""
        scene.reset_with_grasp(*self.palm_world(grasp), q)

    _place = place

    @staticmethod
    def palm_world(grasp: Grasp) -> tuple[np.ndarray, np.ndarray]:
        """frame_palm of ``grasp`` in the world (metres, wxyz), the object being at home."""
        return pose_mul(OBJECT_HOME, np.array([1.0, 0.0, 0.0, 0.0]), grasp.palm_pos, grasp.palm_quat_wxyz)

    @staticmethod
    def _hand_object_contacts(scene: Scene, with_force: bool = False) -> Contacts:
        return hand_object_contacts(scene, with_force)

    def near_contacts(self, scene: Scene, search_m: float | None = None) -> Contacts:
        """Hand–object contacts and near misses within ``search_m`` (default ``[common]
        contact_search_m``): object geoms get that margin for one collision pass, then no more."""
        m, d = scene.model, scene.data
        search_m = self.config.common.contact_search_m if search_m is None else search_m
        saved = m.geom_margin.copy()
        m.geom_margin[scene.obj_geom_mask] = search_m
        mujoco.mj_collision(m, d)
        m.geom_margin[:] = saved
        near = hand_object_contacts(scene)
        keep = near.dist <= search_m
        return Contacts(near.pos[keep], near.normal[keep], near.dist[keep], near.body_a[keep],
                        near.force_n[keep])

    def holds_every_load(self, near: Contacts, loads: HoldLoads) -> bool:
        """:func:`sim.validate.targets.holds_every_load` (whether ``near`` can hold ``loads``)."""
        return holds_every_load(near, loads)

    def derive_targets(self, scene: Scene, q: np.ndarray, down: np.ndarray | None = None, *,
                       sized_for: str = "lift-drop", own_pregrasp: bool = True) -> GraspTargets:
        """Pregrasp and squeeze joint vectors from the contacts near the placed grasp
        (:func:`sim.validate.targets.targets_from_contacts`), the grip sized for protocol
        ``sized_for``'s loads (``down``: the way gravity pulls, where it lifts; None: −z), its
        contacts and servo options (:class:`sim.validate.protocols.base.Protocol`'s
        ``world_loads``, ``target_contacts``, ``target_options``); ``own_pregrasp``: the
        closing makes its own pregrasp (the ``dexaug`` convention; ``bodex`` makes its squeeze
        from the grasp's)."""
        protocol = get(sized_for)
        loads = protocol.world_loads(self, scene, down)
        near = protocol.target_contacts(self, scene, loads)
        options = protocol.target_options(self, scene, own_pregrasp)
        return targets_from_contacts(scene, self.hand, q, near, self.config.common, self._finger_mask,
                                     loads, **options)

    def stages(self, grasp: Grasp, convention: str | None = None, *,
               sized_for: str = "lift-drop") -> GraspStages:
        """Pregrasp, grasp and squeeze of ``grasp``: its own when it carries them, else made by
        ``convention`` (default: ``[dgb] squeeze_convention``; :mod:`sim.validate.stages`),
        whose ``dexaug`` targets come from the placing scene's contacts with the grip sized for
        ``sized_for`` (:meth:`derive_targets`; arm lift: ``lift-drop``), then as that protocol
        runs them (``refine_stages``: ``dgb`` rehearses them)."""
        self.hand.check_q(grasp.joints, "grasp joints")
        convention = convention or self.config.dgb.squeeze_convention
        protocol = get(sized_for)

        def derive(q: np.ndarray) -> GraspTargets:
            scene = self.scene(PLACING_SCENE)
            self.place(scene, grasp, q)
            return self.derive_targets(scene, q, sized_for=sized_for, own_pregrasp=convention == "dexaug")

        stages = grasp_stages(grasp, convention, derive, through_touch=protocol.closes_through_touch)
        return protocol.refine_stages(self, grasp, stages)

    def _close(self, scene: Scene, targets: GraspTargets) -> None:
        """Close the fingers of the grasp placed in ``scene`` onto ``targets``, here."""
        close(scene, self.config.common, targets)

    def measure_contacts(self, scene: Scene, result: ValidationResult) -> None:
        """Contact count and grasp wrench space of the simulated contacts (object frame)."""
        measure_contacts(scene, self.obj, self.config.common, result)

    def actuator_effort(self, grasp: Grasp, hold: HoldLoads, protocol: str = "lift-drop") -> float:
        """Least worst actuator effort (fraction of the force limits of ``protocol``'s scene)
        with which the hand could hold ``hold``'s loads at the grasp's contacts
        (:mod:`sim.validate.effort`); > 1: these actuators cannot hold them however the grasp
        squeezes. One collision pass and a linear programme, no simulation."""
        scene = self.scene(protocol)
        self.place(scene, grasp, self.hand.check_q(grasp.joints, "grasp joints"))
        return actuator_effort(scene, self.near_contacts(scene), self._finger_mask, hold)

    def penetration_m(self, grasp: Grasp, protocol: str = "lift-drop") -> float:
        """Deepest penetration (metres, 0 when none) of the hand into the object or into itself
        (links inside each other: a pose no hand can take), the grasp placed as a protocol
        places it: the check made before simulating, public so a sampler can drop what would
        fail it (one collision pass, no simulation)."""
        q = self.hand.check_q(grasp.joints, "grasp joints")
        if q.ndim != 1:
            raise ValueError("one grasp at a time; use sim.validate.batch for many")
        self.place(scene := self.scene(protocol), grasp, q)
        return max(dgb_penetration_m(scene))   # (hand–object, hand–hand) of the placed grasp

    def fingertip_contacts(self, grasp: Grasp) -> dict[str, np.ndarray | None]:
        """Per finger, the centroid (metres, fingertip body frame) of the hand–object contacts
        of its tip body at the placed grasp (within ``contact_search_m``), or None. This is what
        AutoWS needs from a demonstration."""
        q = self.hand.check_q(grasp.joints, "grasp joints")
        scene = self.scene(PLACING_SCENE)
        self.place(scene, grasp, q)
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
        """RGB image of the grasp after closing in the placing scene, framed by
        :func:`sim.validate.grasp_image.framed_image`."""
        from sim.validate.grasp_image import framed_image

        q = self.hand.check_q(grasp.joints, "grasp joints")
        scene = self.scene(PLACING_SCENE)
        self.place(scene, grasp, q)
        targets = self.derive_targets(scene, q)
        if targets.n_bodies_near:
            self._close(scene, targets)
        return framed_image(scene, width, height, geom_ids=geom_ids)
