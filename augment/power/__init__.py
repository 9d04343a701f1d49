"""Power grasps: the palm and the inner phalanges on the object (the paper's future work).

FSG (:mod:`augment.fsg`) places fingertips; an object that fingertips cannot lift (a 1.1 kg
bleach bottle, a 0.7 kg wood block) needs the whole hand around it. This mode builds such
grasps the way a person does: bring the open hand, palm first, to the object, close every
finger until it stops on the surface, keep the grasps whose contacts can hold the load with
the hand's actuators. The data flow:

1. :mod:`augment.power.placement`: palm frames over sampled object surface points (palm
   normal against the surface normal, a sampled roll about it), each moved along the normal
   until the open hand (its approach posture) is ``standoff_m`` from the surface; placements
   whose palm then stays farther than ``max_palm_gap_m`` (it overhangs an edge) are dropped.
2. :mod:`augment.power.generate`: close the hand from the approach posture toward the hand's
   ``close_pose`` with the object held still (:func:`sim.world.closing.close_on_object`, in
   the validator's own scene, so contacts are the simulator's), then let the object go while
   the fingers relax (``settle_free``; gravity off) so it settles where the hand holds it, as
   it does in a real hand and in the validator's free closing; read back the grasp relative
   to where the object came to rest and its contacts (the palm moved back out if a link was
   left inside the object), score it with the
   actuator effort the validation's loads need (:class:`sim.validate.batch.SceneEffort`) and
   keep those that touch with the thumb and at least one other finger and need at most
   ``max_effort`` of the force limits.

The validator treats these grasps like any other (its contact-derived pregrasp and squeeze,
:mod:`sim.validate.targets`): giving them their own closing (from the grasp toward the closing
posture) changed the pass rate by object, up and down, not overall (README).

A power demo (a whole-hand wrap a person made, :data:`sim.demo.POWER`) seeds the generator:
the fingers close toward the person's posture and part of the palm placements are the
person's, varied (:mod:`augment.power.demo_seed`).

The output is an :class:`augment.fsg.result.FsgGrasp` list in an :class:`FsgResult`, so the
dataset, validation and report work unchanged.
"""

from augment.power.demo_seed import PowerSeed
from augment.power.generate import generate_power
from augment.power.params import PowerParams, load_power_params

__all__ = ["PowerParams", "PowerSeed", "generate_power", "load_power_params"]
