"""Extraction's table plane and quality flags, on constructed states (the geometry is checked
exactly; the bridge-driven extraction itself is tests/test_demo_extraction.py)."""

from __future__ import annotations

import numpy as np

from sim.hand.model import Hand
from sim.transforms import axis_angle_to_quat, rotate
from teleop.record.demo_quality import fragment_flag, slip_flag, table_in_object_frame


def test_the_table_goes_into_the_object_frame() -> None:
    # an object lying on its side: turned 90° about world x, its frame 3 cm above the table
    quat = axis_angle_to_quat(np.array([1.0, 0.0, 0.0]), np.pi / 2)
    pos = np.array([0.2, -0.1, 0.03])
    plane = table_in_object_frame({"top_z_m": 0.0, "center_m": [0.0, 0.0]}, pos, quat)
    assert plane is not None
    np.testing.assert_allclose(rotate(quat, plane["normal"]), [0.0, 0.0, 1.0], atol=1e-12)
    # the object frame's origin is 3 cm above the plane along its normal
    assert np.isclose(-plane["point_m"] @ plane["normal"], 0.03)
    assert table_in_object_frame(None, pos, quat) is None


def _state(obj_x: float, turn_rad: float = 0.0) -> dict:
    return {"palm_pos_m": [0.0, 0.0, 0.1], "palm_quat_wxyz": [1.0, 0.0, 0.0, 0.0],
            "object_pos_m": [obj_x, 0.0, 0.1],
            "object_quat_wxyz": axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), turn_rad).tolist()}


def test_an_object_that_moves_in_the_hand_is_flagged() -> None:
    assert slip_flag([_state(0.05), _state(0.051), _state(0.052)]) is None
    assert "slipped" in slip_flag([_state(0.05), _state(0.06), _state(0.08)])
    assert "slipped" in slip_flag([_state(0.05), _state(0.05, np.deg2rad(30))])


def test_a_fragment_of_a_wrap_is_flagged(shadow: Hand) -> None:
    names = shadow.finger_names
    touching = (names[0], names[-1])            # the thumb and the last (little) finger
    wrap = shadow.upper.copy() * 0.8
    wrap = np.where(np.isfinite(wrap), wrap, 0.0)
    assert "fragment" in fragment_flag(shadow, shadow.clip(wrap), touching)
    assert fragment_flag(shadow, shadow.open_pose, touching) is None
