"""The squeeze's normal forces balance on the object (sim.validate.contact_forces).

A thumb opposing four fingertips: an equal split leaves 3/5 of the grip as a net push on the
object, the balanced split nearly none. In MuJoCo, the paper authors' own five-finger
sugar-box demonstration slips out of an equal-force squeeze (the box is shoved 30 mm toward the
fingers while the hand closes) and holds with the balanced one.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sim.demo import load_demo
from sim.validate.config import ValidateConfig
from sim.validate.contact_forces import balanced_normal_forces, normal_wrench_matrix
from sim.validate.validator import Validator
from sim.world.objects import load_object

HUMAN_SUGAR_BOX = Path(__file__).resolve().parents[1] / "recordings/demos/human/004_sugar_box.json"


def _thumb_against_four() -> tuple[np.ndarray, np.ndarray]:
    """Four fingertips on the +y face of a box 2 cm apart, the thumb on the −y face."""
    fingers = np.array([[x, 0.03, 0.0] for x in (-0.03, -0.01, 0.01, 0.03)])
    points = np.vstack([fingers, [[0.0, -0.03, 0.0]]])
    normals = np.vstack([np.tile([0.0, -1.0, 0.0], (4, 1)), [[0.0, 1.0, 0.0]]])
    return points, normals


def test_balanced_forces_cancel_where_equal_forces_push() -> None:
    points, normals = _thumb_against_four()
    wrench = normal_wrench_matrix(points, normals, np.zeros(3))
    equal = np.full(5, 2.0)
    balanced = balanced_normal_forces(points, normals, np.zeros(3), 10.0)
    assert balanced.sum() == pytest.approx(10.0)
    assert np.all(balanced >= 0.25 * 2.0 - 1e-9)
    assert np.linalg.norm(wrench @ equal) == pytest.approx(6.0)  # 4·2 N against 2 N
    assert np.linalg.norm(wrench @ balanced) < 0.05
    assert balanced[4] == pytest.approx(5.0, abs=0.05)  # the thumb carries half the grip


def test_one_sided_contacts_keep_the_total_and_the_floor() -> None:
    points = np.array([[0.0, 0.03, 0.0], [0.02, 0.03, 0.0]])
    normals = np.tile([0.0, -1.0, 0.0], (2, 1))
    forces = balanced_normal_forces(points, normals, np.zeros(3), 4.0, min_share=0.5)
    assert forces.sum() == pytest.approx(4.0) and np.all(forces >= 1.0 - 1e-9)
    assert balanced_normal_forces(points[:1], normals[:1], np.zeros(3), 4.0) == pytest.approx([4.0])
    assert balanced_normal_forces(points[:0], normals[:0], np.zeros(3), 4.0).shape == (0,)


@pytest.mark.parametrize(("mode", "holds"), [("balanced", True), ("equal", False)])
def test_authors_sugar_box_demo_holds_only_with_a_balanced_squeeze(shadow, mode: str,
                                                                   holds: bool) -> None:
    demo = load_demo(HUMAN_SUGAR_BOX)
    base = ValidateConfig.load()
    assert base.common.squeeze_forces == "balanced"  # the default
    config = replace(base, common=replace(base.common, squeeze_forces=mode))
    result = Validator(shadow, load_object(demo.object), config).validate(demo.grasp)
    assert result.passed is holds, result.failure
