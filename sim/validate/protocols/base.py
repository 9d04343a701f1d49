"""What a validation protocol is (issue #51): one class, registered by name.

A protocol declares its ``name`` (what callers pass: ``Validator.validate(g, "six-dir")``), its
``ValidateConfig`` ``section``, the scene it simulates in (:meth:`Protocol.build_scene`), the
loads it asks a grasp to hold (:meth:`Protocol.hold_loads`, which also size the squeeze: FSG
ranks and the targets press for the test that is run), how the contacts and servos that size
the targets are chosen, how a grasp's stages are made for it, and its program
(:meth:`Protocol.validate`). It reaches the hand, the object, the config and the shared
placing, contact and closing services through a :class:`Bench` (the validator is one).

:class:`ClosingProtocol` is the shape lift-drop and six-dir share: place the grasp, reject it
when it penetrates or no hand body is near the object, close the fingers onto the squeeze
target (:mod:`sim.validate.closing`), measure the contacts, then run its own
:meth:`~ClosingProtocol.phases`. Being one program (:mod:`sim.validate.program`), it also runs
batched (``mujoco.batch``, MuJoCo Warp). Units: metres, seconds, newtons, radians.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, TypedDict
from typing import Protocol as Interface

import numpy as np

from sim.validate.closing import closing, start_closing
from sim.validate.lift_drop import unit_down
from sim.validate.program import Program, run_here
from sim.validate.result import Failure, ValidationResult
from sim.validate.targets import loads_in_world
from sim.world.scene import PhysicsOptions, Scene

if TYPE_CHECKING:
    from sim.grasp import Grasp
    from sim.hand.model import Hand
    from sim.metrics.holding import HoldLoads
    from sim.validate.config import ValidateConfig
    from sim.validate.stages import GraspStages
    from sim.validate.targets import GraspTargets
    from sim.world.contacts import Contacts
    from sim.world.hand_spec import ServoSettings
    from sim.world.objects import ObjectAsset

__all__ = ["Bench", "ClosingProtocol", "Options", "Protocol", "TargetOptions", "six_pushes"]


class TargetOptions(TypedDict, total=False):
    """What a protocol adds to :func:`sim.validate.targets.targets_from_contacts`' keywords
    (:meth:`Protocol.target_options`): typed so a protocol cannot pass a keyword
    the target builder does not take, or one of the wrong kind."""

    act_stiffness: np.ndarray | None   # per actuator, N·m/rad (the protocol's servos)
    act_limits: np.ndarray | None      # per actuator force limit, N·m
    settle_modes: bool                 # settle the hand's free modes first
    self_clear: bool                   # keep the pregrasp out of the hand itself


@dataclass(frozen=True)
class Options:
    """What one validation asks beyond the grasp; each protocol reads the options it takes."""

    #: how the stages are made when the grasp does not carry them (dgb; sim.validate.stages)
    squeeze_convention: str | None = None
    #: called with the phase name as the program runs (lift-drop; sim.validate.diagnose)
    observe: Callable[[str], None] | None = None
    #: the way gravity pulls during the lift (lift-drop; object frame, None: −z)
    gravity_dir: np.ndarray | None = None


class Bench(Interface):
    """The hand and object a protocol validates on, with the shared services
    (:class:`sim.validate.grasp_bench.GraspBench` implements them)."""

    hand: Hand
    obj: ObjectAsset
    config: ValidateConfig

    @property
    def servos(self) -> ServoSettings: ...
    def scene(self, protocol: str) -> Scene: ...
    def palm_world(self, grasp: Grasp) -> tuple[np.ndarray, np.ndarray]: ...
    def near_contacts(self, scene: Scene, search_m: float | None = None) -> Contacts: ...
    def holds_every_load(self, near: Contacts, loads: HoldLoads) -> bool: ...
    def derive_targets(self, scene: Scene, q: np.ndarray, down: np.ndarray | None = None, *,
                       sized_for: str = ..., own_pregrasp: bool = True) -> GraspTargets: ...
    def stages(self, grasp: Grasp, convention: str | None = None, *,
               sized_for: str = ...) -> GraspStages: ...
    def penetration_m(self, grasp: Grasp, protocol: str = ...) -> float: ...
    def measure_contacts(self, scene: Scene, result: ValidationResult) -> None: ...


def six_pushes(force_n: float) -> np.ndarray:
    """Forces of ``force_n`` along ±x, ±y, ±z (six rows of force, torque)."""
    axes = np.vstack([np.eye(3), -np.eye(3)]) * force_n
    return np.hstack([axes, np.zeros((6, 3))])


class Protocol(ABC):
    """One validation protocol; subclass, give it a ``name`` and :func:`register` it."""

    name: ClassVar[str]
    #: the ``ValidateConfig`` section it reads (None: ``[common]`` only)
    section: ClassVar[str | None] = None
    #: whether its stages close through the grasp's touching stage (sim.validate.stages)
    closes_through_touch: ClassVar[bool] = False
    #: what a verdict's displacement and rotation are measured against: "palm" (relative to
    #: the hand) or "start" (the object's initial world pose, as DexGraspBench measures)
    drift_reference: ClassVar[str] = "palm"
    #: (module, diagnose function, summarise function) that replay a grasp under it and
    #: explain its verdict (``dexaug diagnose``); None: it is not offered there
    diagnosis: ClassVar[tuple[str, str, str] | None] = None
    #: the ``augment.fsg.params.FsgParams`` field saying how many grasps FSG finds per grasp
    #: wanted before ranking them by the effort its loads need
    fsg_hold_oversample: ClassVar[str] = "hold_oversample"

    def params(self, config: ValidateConfig) -> Any:
        """Its section of ``config`` (None when it has none)."""
        return None if self.section is None else getattr(config, self.section)

    @abstractmethod
    def build_scene(self, bench: Bench) -> Scene:
        """The scene it simulates in, with the physics, contacts and servos its config states."""

    @abstractmethod
    def hold_loads(self, obj: ObjectAsset, config: ValidateConfig) -> HoldLoads:
        """The loads it puts on ``obj`` (object frame) with the friction it simulates."""

    def world_loads(self, bench: Bench, scene: Scene, down: np.ndarray | None) -> HoldLoads:
        """The loads the squeeze is sized for, in the world of ``scene`` (the grasp placed)."""
        return loads_in_world(self.hold_loads(bench.obj, bench.config), scene)

    def target_contacts(self, bench: Bench, scene: Scene, loads: HoldLoads) -> Contacts:
        """The contacts the squeeze presses: every one within ``[common] contact_search_m``."""
        return bench.near_contacts(scene)

    def target_options(self, bench: Bench, scene: Scene, own_pregrasp: bool) -> TargetOptions:
        """Keyword options of :func:`sim.validate.targets.targets_from_contacts` (servos…)."""
        return {}

    def refine_stages(self, bench: Bench, grasp: Grasp, stages: GraspStages) -> GraspStages:
        """The stages it runs for ``stages`` as a convention made them (default: those)."""
        return stages

    @abstractmethod
    def validate(self, bench: Bench, grasp: Grasp, options: Options) -> ValidationResult:
        """Validate one grasp, here."""


class ClosingProtocol(Protocol):
    """Place, close onto the squeeze target, measure the contacts, then :meth:`phases`."""

    #: whether it takes ``Options.gravity_dir`` (others push along fixed axes)
    takes_gravity_dir: ClassVar[bool] = False

    @abstractmethod
    def physics(self, config: ValidateConfig) -> PhysicsOptions:
        """The solver settings of its scene."""

    @abstractmethod
    def phases(self, bench: Bench, scene: Scene, targets: GraspTargets, result: ValidationResult,
               options: Options) -> Program:
        """Its own phases on the closed grasp (a program); fill ``result``'s verdict."""

    def build_scene(self, bench: Bench) -> Scene:
        return Scene(bench.hand, bench.obj, contact=bench.config.common.contact,
                     physics=self.physics(bench.config), servos=bench.servos, contact_on_hand=True)

    def validate(self, bench: Bench, grasp: Grasp, options: Options) -> ValidationResult:
        result, program = self.start(bench, grasp, options=options)
        if program is not None:
            run_here(bench.scene(self.name), program)
        return result

    def start(self, bench: Bench, grasp: Grasp, *, scene: Scene | None = None,
              options: Options | None = None) -> tuple[ValidationResult, Program | None]:
        """Place ``grasp`` in its scene and decide what can be decided without simulating
        (penetration, no hand body near the object): the result so far and, when simulation
        must follow, the program that finishes it, from the scene's state as this call leaves
        it. ``scene`` (default: its scene) is what the program reads: a batch runner's view of
        its own simulation, whose state it loads from the protocol's scene."""
        options = options or Options()
        if options.gravity_dir is not None and not self.takes_gravity_dir:
            raise ValueError(f"gravity_dir is lift-drop's; {self.name!r} pushes along fixed axes")
        down = None if options.gravity_dir is None else unit_down(options.gravity_dir)
        penetration = bench.penetration_m(grasp, self.name)
        q = bench.hand.check_q(grasp.joints, "grasp joints")
        here = bench.scene(self.name)
        common = bench.config.common
        result = ValidationResult(protocol=self.name, passed=False, failure=None,
                                  penetration_m=penetration,
                                  closing="pinned" if common.pin_while_closing else "free")
        if penetration > common.max_penetration_m:
            result.failure = Failure.PENETRATION
            return result, None
        targets = bench.derive_targets(here, q, down, sized_for=self.name)
        result.pregrasp, result.squeeze = targets.pregrasp, targets.squeeze
        result.squeeze_convention = "dexaug"
        if targets.n_bodies_near == 0:
            result.failure = Failure.NO_CONTACT
            return result, None
        start_closing(here, targets)
        return result, self._program(bench, scene or here, targets, result,
                                     dataclasses.replace(options, gravity_dir=down))

    def _program(self, bench: Bench, scene: Scene, targets: GraspTargets,
                 result: ValidationResult, options: Options) -> Program:
        """Closing, contact measurement and :meth:`phases`, as one program."""
        yield from closing(scene, bench.config.common, targets)
        bench.measure_contacts(scene, result)
        if result.n_contacts == 0:
            result.failure = Failure.LOST_CONTACT
            return
        yield from self.phases(bench, scene, targets, result, options)
