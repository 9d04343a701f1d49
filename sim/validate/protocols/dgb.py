"""The ``dgb`` protocol: DexGraspBench's evaluation, with its own scene, closing and rehearsal.

Its scene is the benchmark's (floating palm, kp 5 / ±3 N·m servos, 0.1 kg object unless
"real", μ 0.6 / 0.02; ``[dgb]``). Its squeeze is sized for six pushes of ``force_per_kg`` × that
mass with its own friction and servos, pressing only the bodies within ``[dgb]
contact_search_m`` unless those cannot hold every push; for the ``dexaug`` convention's own
pregrasp it settles the fingers' free modes (:mod:`sim.validate.free_modes`) and keeps the
pregrasp out of itself (:mod:`sim.validate.self_clearance`). Its stages close through the
grasp's touch and are rehearsed (:mod:`sim.validate.rehearsal`); :func:`sim.validate.dgb.run_dgb`
then closes stage by stage and pushes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from sim.metrics.holding import HoldLoads
from sim.validate.dgb import run_dgb
from sim.validate.protocols.base import Bench, Options, Protocol, TargetOptions, six_pushes
from sim.validate.protocols.registry import register
from sim.validate.rehearsal import rehearsed
from sim.validate.result import ValidationResult
from sim.validate.targets import servo_limits_from, servo_stiffness_from
from sim.world.scene import PhysicsOptions, Scene

if TYPE_CHECKING:
    from sim.grasp import Grasp
    from sim.validate.config import ValidateConfig
    from sim.validate.stages import GraspStages
    from sim.world.contacts import Contacts
    from sim.world.objects import ObjectAsset

__all__ = ["Dgb"]


@register
class Dgb(Protocol):
    name = "dgb"
    section = "dgb"
    closes_through_touch = True
    drift_reference = "start"
    diagnosis = ("sim.validate.diagnose_dgb", "diagnose_dgb", "summarise_dgb")
    fsg_hold_oversample = "dgb_hold_oversample"   # the benchmark's loads are light ones

    def build_scene(self, bench: Bench) -> Scene:
        p = bench.config.dgb
        physics = PhysicsOptions(timestep_s=p.timestep_s, impratio=p.impratio,
                                 noslip_iterations=p.noslip_iterations,
                                 solver_iterations=p.solver_iterations,
                                 weld_solref=p.weld_solref, sparse_jacobian=None,
                                 ccd_iterations=p.ccd_iterations, multiccd=p.multiccd,
                                 islands=p.islands)
        return Scene(bench.hand, bench.obj, contact=p.contact, physics=physics, servos=p.servos,
                     floating_palm=True, object_mass_kg=p.object_mass_kg, contact_on_hand=True)

    def hold_loads(self, obj: ObjectAsset, config: ValidateConfig) -> HoldLoads:
        """Six pushes of ``force_per_kg`` × the benchmark's mass, with its own friction."""
        p = config.dgb
        mass_kg = obj.mass_kg if p.object_mass_kg is None else p.object_mass_kg
        return HoldLoads(six_pushes(p.force_per_kg * mass_kg), np.asarray(obj.com_m, dtype=float),
                         p.contact.friction[0], p.contact.friction[1], self.name)

    def target_contacts(self, bench: Bench, scene: Scene, loads: HoldLoads) -> Contacts:
        """The bodies within ``[dgb] contact_search_m``, or within ``[common]``'s wider one when
        those cannot hold every push (:func:`sim.validate.targets.holds_every_load`)."""
        bench.scene(self.name)   # compiled before the contacts are read, as it always was
        near = bench.near_contacts(scene, bench.config.dgb.contact_search_m)
        return near if bench.holds_every_load(near, loads) else bench.near_contacts(scene)

    def target_options(self, bench: Bench, scene: Scene, own_pregrasp: bool) -> TargetOptions:
        """Its servos' stiffness and limits; free modes settled and the pregrasp kept out of
        itself for the convention's ``own_pregrasp``."""
        dgb = bench.scene(self.name)
        return {"act_stiffness": servo_stiffness_from(dgb, scene),
                "act_limits": servo_limits_from(dgb, scene),
                "settle_modes": own_pregrasp and bench.config.dgb.settle_free_modes,
                "self_clear": own_pregrasp}

    def refine_stages(self, bench: Bench, grasp: Grasp, stages: GraspStages) -> GraspStages:
        """Rehearsed (:func:`sim.validate.rehearsal.rehearsed`)."""
        return rehearsed(bench.scene(self.name), bench.config.dgb, bench.palm_world(grasp), stages)

    def validate(self, bench: Bench, grasp: Grasp, options: Options) -> ValidationResult:
        """The benchmark on the grasp's stages (``options.squeeze_convention`` overrides
        ``[dgb] squeeze_convention``)."""
        stages = bench.stages(grasp, options.squeeze_convention, sized_for=self.name)
        scene = bench.scene(self.name)
        result = ValidationResult(self.name, False, None, 0.0, closing="free", touch=stages.grasp,
                                  squeeze_convention=stages.made_by,
                                  pregrasp=stages.pregrasp, squeeze=stages.squeeze)
        run_dgb(scene, bench.config.dgb, bench.palm_world(grasp), stages, result,
                after_first_close=lambda: bench.measure_contacts(scene, result))
        return result
