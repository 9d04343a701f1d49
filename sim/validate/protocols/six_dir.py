"""The ``six-dir`` protocol: close, then push the held object along ±x, ±y, ±z in turn
(:mod:`sim.validate.six_dir` runs the pushes; DESIGN §5).

Its squeeze is sized for those six pushes of ``force_per_kg`` × the real mass with ``[common]``
contacts; its scene takes ``[six_dir]``'s physics (noslip iterations included).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from sim.metrics.holding import HoldLoads
from sim.validate.protocols.base import Bench, ClosingProtocol, Options, six_pushes
from sim.validate.protocols.registry import register
from sim.validate.six_dir import six_dir
from sim.world.scene import PhysicsOptions

if TYPE_CHECKING:
    from sim.validate.config import ValidateConfig
    from sim.validate.program import Program
    from sim.validate.result import ValidationResult
    from sim.validate.targets import GraspTargets
    from sim.world.objects import ObjectAsset
    from sim.world.scene import Scene

__all__ = ["SixDir"]


@register
class SixDir(ClosingProtocol):
    name = "six-dir"
    section = "six_dir"

    def physics(self, config: ValidateConfig) -> PhysicsOptions:
        six = config.six_dir
        return PhysicsOptions(timestep_s=six.timestep_s, impratio=six.impratio,
                              noslip_iterations=six.noslip_iterations)

    def hold_loads(self, obj: ObjectAsset, config: ValidateConfig) -> HoldLoads:
        """Six pushes of ``force_per_kg`` × the real mass (gravity off, as it runs)."""
        friction = config.common.contact.friction
        return HoldLoads(six_pushes(config.six_dir.force_per_kg * obj.mass_kg),
                         np.asarray(obj.com_m, dtype=float), friction[0], friction[1], self.name)

    def phases(self, bench: Bench, scene: Scene, targets: GraspTargets, result: ValidationResult,
               options: Options) -> Program:
        yield from six_dir(scene, bench.config.six_dir, result)
