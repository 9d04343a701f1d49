"""lift-drop's release lets go where the grip was made: the fingers back off to the pregrasp
before they open to the open pose.

The grasp below (an FSG grasp of the committed screwdriver demo: thumb, index and middle on the
shaft) holds through the lift and the hold within 2 mm and 1°. Ramped straight from the squeeze
to the open pose, the opening fingers carried the screwdriver 4 cm the wrong way, into the hand,
where it stayed on the index and middle fingers: ``stuck``, the verdict meant for grasps held by
interpenetration. Backing off first, it falls out of the palm."""

from __future__ import annotations

import numpy as np

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [needs_menagerie, needs_ycb]

PALM_POSE = np.array([0.083759, -0.041881, 0.003058, 0.646059, 0.189983, -0.688403, -0.269474])
JOINTS = np.array([0.0, 0.0, -0.086435, 0.701124, 0.147625, 0.154587, 0.349066, 0.496914,
                   0.641529, 0.642411, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.356312,
                   1.22173, 0.078114, 0.182395, -0.261799])


def test_a_held_screwdriver_is_released_out_of_the_palm() -> None:
    v = Validator(Hand.load("shadow_right"), load_object("043_phillips_screwdriver"))
    result = v.validate(Grasp.from_arrays(PALM_POSE[:3], PALM_POSE[3:], JOINTS), "lift-drop")
    assert result.phases["hold"].passed, result.summary()
    drop = result.phases["drop"]
    assert drop.passed and result.failure is None, result.summary()
    assert drop.displacement_m >= v.config.lift_drop.drop_min_fall_m   # out along palm +y
