"""lift-drop's release is measured along the release direction, out of the palm face.

A parallel gripper (the Robotiq 2F-85) holds a can, opens, and the can must leave it along the
palm normal. The same physical grasp seen through a palm frame whose +y points backwards (the
Robotiq config's old sign) releases toward the gripper's base: that object has not fallen out of
the hand, and the check must fail it — a distance-only check passed it (the can travels 27 mm toward the base
and rests against it)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.grasp import Grasp
from sim.hand.config import hand_names, load_hand_config
from sim.hand.model import Hand
from sim.transforms import mat_to_quat, quat_mul
from sim.validate.result import Failure
from sim.validate.validator import Validator
from sim.world.closing import close_on_object
from sim.world.objects import load_object
from sim.world.scene import Scene
from tests.conftest import needs_menagerie

GRIPPER = "robotiq_2f85"
pytestmark = [needs_menagerie,
              pytest.mark.skipif(GRIPPER not in hand_names(), reason=f"no {GRIPPER} config")]
# frame_palm in the object frame: palm +y along object +x (approach from −x), closing along y
PALM_QUAT = mat_to_quat(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))
TURN_Z = np.array([0.0, 0.0, 0.0, 1.0])   # 180° about palm z: flips palm +y (and x)


@pytest.fixture(scope="module")
def gripper_grasp() -> tuple[Hand, Grasp]:
    hand = Hand.load(GRIPPER)
    drivers = np.array([n.endswith("driver_joint") for n in hand.joint_names])
    closed = hand.fill_coupled(np.where(drivers, hand.upper, 0.0))
    grasp = close_on_object(Scene(hand, load_object("cylinder")), np.array([-0.09, 0.0, 0.0]),
                            PALM_QUAT, hand.open_pose, closed)
    return hand, grasp


def test_the_object_leaves_the_gripper(gripper_grasp) -> None:
    hand, grasp = gripper_grasp
    result = Validator(hand, load_object("cylinder")).validate(grasp, "lift-drop")
    assert result.passed, result.summary()
    assert result.closing == "free"
    assert result.phases["drop"].displacement_m >= 0.02   # metres out along palm +y


def test_an_object_pushed_into_the_palm_is_not_released(gripper_grasp) -> None:
    _, grasp = gripper_grasp
    cfg = load_hand_config(GRIPPER)
    palm = dataclasses.replace(cfg.palm, quat_wxyz=quat_mul(cfg.palm.quat_wxyz, TURN_Z))
    backwards = Hand(dataclasses.replace(cfg, palm=palm), check_conventions=False)
    same_pose = Grasp.from_arrays(grasp.palm_pos, quat_mul(grasp.palm_quat_wxyz, TURN_Z), grasp.joints)
    result = Validator(backwards, load_object("cylinder")).validate(same_pose, "lift-drop")
    assert not result.passed
    assert result.failure == Failure.STUCK
    # it did move 2 cm and more — into the gripper, where a distance-only check passed it
    assert result.phases["drop"].displacement_m >= 0.02
