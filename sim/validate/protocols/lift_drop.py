"""The ``lift-drop`` protocol: close, then lift against gravity, hold and let go
(:mod:`sim.validate.lift_drop` runs the phases; DESIGN §5).

Its squeeze is sized for the object's weight along the way gravity pulls (−z unless
``gravity_dir``), with ``[common]`` contacts; its scene takes ``[lift_drop]``'s physics.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from sim.metrics.holding import HoldLoads
from sim.validate.config import GRAVITY_MPS2
from sim.validate.lift_drop import lift_drop
from sim.validate.protocols.base import Bench, ClosingProtocol, Options
from sim.validate.protocols.registry import register
from sim.validate.targets import weight_loads
from sim.world.scene import PhysicsOptions

if TYPE_CHECKING:
    from sim.validate.config import ValidateConfig
    from sim.validate.program import Program
    from sim.validate.result import ValidationResult
    from sim.validate.targets import GraspTargets
    from sim.world.objects import ObjectAsset
    from sim.world.scene import Scene

__all__ = ["LiftDrop"]


@register
class LiftDrop(ClosingProtocol):
    name = "lift-drop"
    section = "lift_drop"
    takes_gravity_dir = True
    diagnosis = ("sim.validate.diagnose", "diagnose", "summarise")

    def physics(self, config: ValidateConfig) -> PhysicsOptions:
        lift = config.lift_drop
        return PhysicsOptions(timestep_s=lift.timestep_s, impratio=lift.impratio)

    def hold_loads(self, obj: ObjectAsset, config: ValidateConfig) -> HoldLoads:
        """The object's weight (real mass) straight down in the object frame: the validator
        lifts with the object at its home orientation; ``[common] friction``."""
        friction = config.common.contact.friction
        loads = np.array([[0.0, 0.0, -obj.mass_kg * GRAVITY_MPS2, 0.0, 0.0, 0.0]])
        return HoldLoads(loads, np.asarray(obj.com_m, dtype=float), friction[0], friction[1],
                         self.name)

    def world_loads(self, bench: Bench, scene: Scene, down: np.ndarray | None) -> HoldLoads:
        """The weight along ``down`` (None: −z) at the placed object's centre of mass."""
        return weight_loads(scene.obj_mass_kg, scene.data.xipos[scene.obj_body], bench.config.common,
                            down)

    def phases(self, bench: Bench, scene: Scene, targets: GraspTargets, result: ValidationResult,
               options: Options) -> Program:
        if options.observe is not None:
            options.observe("closed")
        yield from lift_drop(scene, bench.hand, bench.config.lift_drop, targets, result,
                             options.observe, options.gravity_dir)
