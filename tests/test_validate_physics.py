"""What validate.toml says is simulated is what MuJoCo simulates, for every protocol.

Read back from the compiled scenes (every hand and object collision geom, every hand servo, the
object's mass) and from the contacts MuJoCo actually solves while a grasp is closed: MuJoCo
mixes two geoms' values (the larger friction, the mean solref/solimp), so only values set on
both sides reach the contacts unchanged."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sim.errors import ConfigError
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.validate.config import PROTOCOLS, ValidateConfig
from sim.validate.dgb import run_dgb
from sim.validate.result import ValidationResult
from sim.validate.validator import Validator
from sim.world.object_spec import ContactParams
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [needs_menagerie, needs_ycb]
OBJECT = "005_tomato_soup_can"


@pytest.fixture(scope="module")
def validator(shadow: Hand) -> Validator:
    return Validator(shadow, load_object(OBJECT))


def _configured(config: ValidateConfig, protocol: str) -> ContactParams:
    return config.dgb.contact if protocol == "dgb" else config.common.contact


def _closed_contacts(v: Validator, protocol: str) -> mujoco.MjData:
    """The scene's data with the reference grasp of the object closed under ``protocol``."""
    grasp = next(r.grasp for r in load_reference_grasps(v.hand) if r.object == OBJECT)
    scene = v.scene(protocol)
    if protocol == "dgb":
        result = ValidationResult("dgb", False, None, 0.0)
        seen: list[mujoco.MjData] = []
        run_dgb(scene, v.config.dgb, v.palm_world(grasp), v.stages(grasp, "dexaug"), result,
                after_first_close=lambda: seen.append(mujoco.MjData.__copy__(scene.data)))
        return seen[0]
    q = grasp.joints
    v._place(scene, grasp, q)
    v._close(scene, v.derive_targets(scene, q))
    return scene.data


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_every_collision_geom_has_the_configured_contact(validator: Validator, protocol: str) -> None:
    scene = validator.scene(protocol)
    m, want = scene.model, _configured(validator.config, protocol)
    colliding = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
    for mask in (scene.hand_geom_mask & colliding, scene.obj_geom_mask & colliding):
        assert mask.any()
        np.testing.assert_allclose(m.geom_friction[mask], np.tile(want.friction, (mask.sum(), 1)))
        np.testing.assert_allclose(m.geom_solref[mask], np.tile(want.solref, (mask.sum(), 1)))
        np.testing.assert_allclose(m.geom_solimp[mask, :3], np.tile(want.solimp, (mask.sum(), 1)))
        assert (m.geom_condim[mask] == want.condim).all()


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_simulated_contacts_run_at_the_configured_values(validator: Validator, protocol: str) -> None:
    scene = validator.scene(protocol)
    d = _closed_contacts(validator, protocol)
    want = _configured(validator.config, protocol)
    geom = d.contact.geom[:d.ncon]
    hand_obj = (scene.hand_geom_mask[geom[:, 0]] & scene.obj_geom_mask[geom[:, 1]]) | (
        scene.obj_geom_mask[geom[:, 0]] & scene.hand_geom_mask[geom[:, 1]])
    assert hand_obj.sum() >= 3, "the closed grasp touches the object"
    con = d.contact
    # MuJoCo's contact friction is 5 numbers: sliding ×2, torsional, rolling ×2
    expected = np.array([want.friction[0], want.friction[0], want.friction[1], want.friction[2],
                         want.friction[2]])
    np.testing.assert_allclose(con.friction[:d.ncon][hand_obj], np.tile(expected, (hand_obj.sum(), 1)))
    np.testing.assert_allclose(con.solref[:d.ncon][hand_obj], np.tile(want.solref, (hand_obj.sum(), 1)))
    np.testing.assert_allclose(con.solimp[:d.ncon][hand_obj, :3], np.tile(want.solimp, (hand_obj.sum(), 1)))
    assert (con.dim[:d.ncon][hand_obj] == want.condim).all()


@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_servos_and_mass_are_the_configured_ones(validator: Validator, shadow: Hand, protocol: str) -> None:
    scene = validator.scene(protocol)
    m, acts, cfg = scene.model, scene.hand_act, validator.config
    own = shadow.model
    if protocol == "dgb":
        servos = cfg.dgb.servos
        assert len(acts) == len(scene.hand_act_kept) and scene.floating_palm
        np.testing.assert_allclose(m.actuator_gainprm[acts, 0], servos.kp)
        np.testing.assert_allclose(-m.actuator_biasprm[acts, 1], servos.kp)
        limit = servos.force_limit
        np.testing.assert_allclose(m.actuator_forcerange[acts], [[-limit, limit]] * len(acts))
        assert not m.actuator_ctrllimited[acts].any()
        assert m.body_mass[scene.obj_body] == pytest.approx(cfg.dgb.object_mass_kg)
        assert m.opt.noslip_iterations == cfg.dgb.noslip_iterations
        # collision as the benchmark's MuJoCo 3.3.2: its CCD iterations, one contact per pair
        assert m.opt.ccd_iterations == cfg.dgb.ccd_iterations == 50
        multiccd_off = bool(m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_MULTICCD)
        assert multiccd_off == (not cfg.dgb.multiccd) == True  # noqa: E712
        # and its solver over the whole scene, as 3.3.2 does unless a model enables islands
        islands_off = bool(m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_ISLAND)
        assert islands_off == (not cfg.dgb.islands) == True  # noqa: E712
    else:
        # the other protocols keep this MuJoCo's own collision defaults
        assert m.opt.ccd_iterations == mujoco.MjOption().ccd_iterations
        assert not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_MULTICCD
        assert not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_ISLAND
        scale = cfg.common.servos.kp_scale
        np.testing.assert_allclose(m.actuator_gainprm[acts, 0], scale * own.actuator_gainprm[:, 0])
        np.testing.assert_allclose(m.actuator_forcerange[acts], own.actuator_forcerange)
        assert m.body_mass[scene.obj_body] == pytest.approx(load_object(OBJECT).mass_kg)


@needs_menagerie
def test_a_hand_names_its_own_validation_servo_gain(tmp_path, shadow: Hand) -> None:
    """hand.toml [validate] servo_kp_scale replaces validate.toml's for that hand in lift-drop
    and six-dir (read back from the compiled model); dgb keeps its own absolute gains."""
    import dataclasses

    from sim.hand.config import load_hand_config

    src = shadow.config.file.read_text() + "\n[validate]\nservo_kp_scale = 1.5\n"
    (tmp_path / "hand.toml").write_text(src)
    cfg = load_hand_config(tmp_path / "hand.toml")
    assert cfg.validate_kp_scale == 1.5
    own = Hand(dataclasses.replace(shadow.config, validate_kp_scale=1.5))
    val = Validator(own, load_object("cylinder"))
    for protocol in ("lift-drop", "six-dir"):
        m = val.scene(protocol).model
        np.testing.assert_allclose(m.actuator_gainprm[val.scene(protocol).hand_act, 0],
                                   1.5 * shadow.model.actuator_gainprm[:, 0])
    m = val.scene("dgb").model
    np.testing.assert_allclose(m.actuator_gainprm[val.scene("dgb").hand_act, 0],
                               val.config.dgb.servos.kp)
    (tmp_path / "hand.toml").write_text(src.replace("servo_kp_scale = 1.5", "servo_kp = 1.5"))
    with pytest.raises(ConfigError, match=r"hand\.toml: validate.*servo_kp"):
        load_hand_config(tmp_path / "hand.toml")


def test_dgb_scene_floats_the_palm(validator: Validator, shadow: Hand) -> None:
    """The benchmark's hand has no wrist: the palm body is the floating root and the wrist
    joints and actuators are absent; the finger joints are all there."""
    scene = validator.scene("dgb")
    m = scene.model
    finger_joints = {j for f in shadow.config.fingers for j in f.joints}
    kept = {shadow.joint_names[i] for i in scene.hand_joint_kept}
    assert kept == finger_joints
    assert m.body_parentid[m.body("hand/" + shadow.config.palm.body).id] == m.body("hand_base").id
