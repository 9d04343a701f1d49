"""Grasp validator ground truth: hand-built grasps hold under both protocols; an open hand
beside the object, a grasp on air, a deeply interpenetrating grasp and a hand inside itself
fail, each for its reason."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sim.errors import ConfigError, GraspInputError
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.transforms import rotate
from sim.validate.config import ValidateConfig
from sim.validate.result import Failure
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]
OBJECTS = ["005_tomato_soup_can", "004_sugar_box"]


@pytest.fixture(scope="module")
def validators(shadow: Hand) -> dict[str, Validator]:
    return {name: Validator(shadow, load_object(name)) for name in OBJECTS}


@pytest.fixture(scope="module")
def references(shadow: Hand) -> dict[str, Grasp]:
    refs = load_reference_grasps(shadow)
    return {obj: next(r.grasp for r in refs if r.object == obj) for obj in OBJECTS}


def _shifted(grasp: Grasp, along_palm_y_m: float, joints: np.ndarray | None = None) -> Grasp:
    """The grasp with the palm moved along its own normal (+ = toward the object)."""
    normal = rotate(grasp.palm_quat_wxyz, np.array([0.0, 1.0, 0.0]))
    return Grasp.from_arrays(grasp.palm_pos + along_palm_y_m * normal, grasp.palm_quat_wxyz,
                             grasp.joints if joints is None else joints)


@pytest.mark.parametrize("obj", OBJECTS)
@pytest.mark.parametrize("protocol", ["lift-drop", "six-dir"])
def test_hand_built_grasp_holds(validators, references, obj: str, protocol: str) -> None:
    result = validators[obj].validate(references[obj], protocol)
    assert result.passed, result.summary()
    assert result.failure is None
    assert result.n_contacts >= 3
    assert result.penetration_m < 0.005
    assert result.epsilon > 0.0  # the simulated contacts are force-closure
    assert result.volume > 0.0


@pytest.mark.parametrize("obj", OBJECTS)
def test_open_hand_beside_object_slips(validators, references, shadow: Hand, obj: str) -> None:
    # open fingers, palm 5 mm closer than in the grasp so that it touches the object: the hand is
    # near enough to be simulated, but nothing encloses the object
    beside = _shifted(references[obj], 0.005, joints=shadow.open_pose)
    result = validators[obj].validate(beside, "lift-drop")
    assert not result.passed
    assert result.failure in (Failure.SLIPPED, Failure.LOST_CONTACT), result.summary()


@pytest.mark.parametrize("obj", OBJECTS)
def test_grasp_on_air_has_no_contact(validators, references, obj: str) -> None:
    far = Grasp.from_arrays(references[obj].palm_pos + np.array([0.5, 0.0, 0.0]),
                            references[obj].palm_quat_wxyz, references[obj].joints)
    result = validators[obj].validate(far, "lift-drop")
    assert (result.passed, result.failure) == (False, Failure.NO_CONTACT)


@pytest.mark.parametrize("obj", OBJECTS)
def test_deep_interpenetration_is_rejected_before_simulating(validators, references,
                                                             obj: str) -> None:
    inside = _shifted(references[obj], 0.03)
    result = validators[obj].validate(inside, "six-dir")
    assert (result.passed, result.failure) == (False, Failure.PENETRATION)
    assert result.penetration_m > 0.005
    assert result.phases == {}  # nothing was simulated


@pytest.mark.parametrize("protocol", ["lift-drop", "six-dir"])
def test_fingers_inside_each_other_are_rejected_before_simulating(validators, shadow: Hand,
                                                                  protocol: str) -> None:
    """Half a metre from the object, so the hand touches only itself: the middle finger spread
    towards the forefinger by 0.15 rad is ≈ 7 mm inside it, a pose no hand can take (refused
    like a hand 7 mm into the object); by 0.1 rad ≈ 3 mm, within the 5 mm allowed, it is
    simulated (and holds nothing)."""
    q = np.zeros(len(shadow.joint_names))
    verdicts = {}
    for spread_rad in (0.1, 0.15):
        q[list(shadow.joint_names).index("rh_MFJ4")] = spread_rad
        far = Grasp(np.array([0.0, 0.0, 0.5]), np.array([1.0, 0.0, 0.0, 0.0]), q.copy())
        verdicts[spread_rad] = validators["005_tomato_soup_can"].validate(far, protocol)
    assert verdicts[0.1].failure == Failure.NO_CONTACT
    assert 0.001 < verdicts[0.1].penetration_m < 0.005
    assert verdicts[0.15].failure == Failure.PENETRATION
    assert verdicts[0.15].penetration_m > 0.005 and verdicts[0.15].phases == {}


def _key(result) -> str:
    """A comparable form of a result (NaN metrics compare equal as text)."""
    return json.dumps(result.summary(), default=str, sort_keys=True)


def test_validation_is_deterministic(validators, references) -> None:
    a = validators["005_tomato_soup_can"].validate(references["005_tomato_soup_can"])
    b = validators["005_tomato_soup_can"].validate(references["005_tomato_soup_can"])
    assert _key(a) == _key(b)


def test_batch_matches_serial_and_keeps_order(references) -> None:
    from sim.validate.batch import validate_many

    obj = "005_tomato_soup_can"
    grasps = [references[obj], _shifted(references[obj], 0.5), references[obj]]
    serial = validate_many("shadow_right", obj, grasps, workers=1)
    parallel = validate_many("shadow_right", obj, grasps, workers=2)
    assert [_key(r) for r in serial] == [_key(r) for r in parallel]
    assert [r.failure for r in serial] == [None, Failure.NO_CONTACT, None]


def test_wrong_grasp_vector_length_is_one_clear_error(validators, references) -> None:
    g = references["004_sugar_box"]
    with pytest.raises(GraspInputError, match=r"grasp joints: expected 24 joint values"):
        validators["004_sugar_box"].validate(Grasp.from_arrays(g.palm_pos, g.palm_quat_wxyz,
                                                               g.joints[:-2]))
    with pytest.raises(GraspInputError, match="unit quaternion"):
        Grasp.from_arrays(g.palm_pos, [1.0, 1.0, 0.0, 0.0], g.joints)


@pytest.mark.parametrize(("old", "new", "key"), [
    ("hold_time_s = 1.0", "hold_time_s = -1.0", r"lift_drop\.hold_time_s"),
    ("friction = [0.8,", "friction = [0.0,", r"common\.friction"),   # grip force = weight / μ
])
def test_validate_config_errors_name_the_key(tmp_path: Path, old: str, new: str, key: str) -> None:
    from sim.paths import CONFIG_DIR

    text = (CONFIG_DIR / "validate.toml").read_text()
    assert old in text
    bad = tmp_path / "validate.toml"
    bad.write_text(text.replace(old, new))
    with pytest.raises(ConfigError, match=rf"validate\.toml: {key}"):
        ValidateConfig.load(bad)


def _normal_force_after_closing(validator: Validator, grasp: Grasp) -> tuple[float, int]:
    """Total hand–object normal force (newtons) after closing with gravity off, and the number
    of grasping contacts the squeeze target was sized for."""
    scene = validator.scene("lift-drop")
    q = validator.hand.check_q(grasp.joints)
    validator._place(scene, grasp, q)  # gravity off
    targets = validator.derive_targets(scene, q)
    validator._close(scene, targets)
    contacts = validator._hand_object_contacts(scene, with_force=True)
    return float(contacts.force_n.sum()), targets.n_bodies_near


def test_squeeze_presses_with_the_intended_force(shadow: Hand, references) -> None:
    # the force part of the squeeze target alone: raising the per-contact force by Δf must raise
    # the simulated normal force by about n·Δf (servo stiffness from the actuator model, contact
    # Jacobians); a wrong stiffness, sign or missing deflection moves the ratio far from 1. The
    # soup can's reference grasp is used because its near bodies all end up touching (the sugar
    # box's thumb base stays 9 mm off, so its share is pressed through other links: ratio ≈ 0.5)
    obj = "005_tomato_soup_can"
    base = ValidateConfig.load()
    totals = []
    for force_n in (1.0, 3.0):
        common = replace(base.common, grip_safety=0.0, min_grip_force_n=force_n)
        validator = Validator(shadow, load_object(obj), replace(base, common=common))
        total_n, n_contacts = _normal_force_after_closing(validator, references[obj])
        totals.append(total_n)
    ratio = (totals[1] - totals[0]) / (n_contacts * 2.0)
    assert 0.6 < ratio < 1.6, (totals, n_contacts)


def test_grip_force_is_sized_by_weight_and_friction(validators, references) -> None:
    validator = validators["004_sugar_box"]
    scene = validator.scene("lift-drop")
    q = validator.hand.check_q(references["004_sugar_box"].joints)
    validator._place(scene, references["004_sugar_box"], q)
    targets = validator.derive_targets(scene, q)
    common = validator.config.common
    at_least = common.grip_safety * scene.obj_mass_kg * 9.81 / (
        common.contact.friction[0] * targets.n_bodies_near)
    assert targets.grip_force_n >= max(at_least, common.min_grip_force_n)
    assert targets.grip_force_n < 20 * at_least  # the moment term stays bounded
