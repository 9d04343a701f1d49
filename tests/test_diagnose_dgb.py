"""``dexaug diagnose --protocol dgb``: the benchmark's closing replayed free and held.

The held closing's wrench is checked against MuJoCo's own account of the external forces on the
object (``cfrc_ext``), and a bowl grasp whose verdict turns on its tendon-shared fingers (it
passes with the benchmark's pregrasp settled, fails without: ``tests/test_free_modes.py``) is
diagnosed both ways: the failing run's middle finger reconfigures, the passing run's does not.
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from sim.transforms import quat_to_mat
from sim.validate.config import ValidateConfig
from sim.validate.dgb import DGB_DIRECTIONS
from sim.validate.diagnose_dgb import diagnose_dgb, held_closing, replay_push, summarise_dgb
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb, without_drift_correction, without_settled_modes
from tests.test_free_modes import BOWL_GRASP

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]


@pytest.fixture(scope="module")
def bowl_validators(shadow) -> dict[bool, Validator]:
    # the splits' motion as measured before the drift correction, which moves the fore and
    # middle fingers' squeeze targets too (the grasp passes either way)
    cfg = without_drift_correction(ValidateConfig.load())
    bowl = load_object("024_bowl")
    return {True: Validator(shadow, bowl, cfg),
            False: Validator(shadow, bowl, without_settled_modes(cfg))}


def test_the_held_closings_wrench_is_mujocos_and_the_object_stays(bowl_validators) -> None:
    v = bowl_validators[True]
    p, scene = v.config.dgb, v.scene("dgb")
    stages = v.stages(BOWL_GRASP, sized_for="dgb")
    scene.reset_with_grasp(*v.palm_world(BOWL_GRASP), stages.pregrasp)
    pos0, quat0 = scene.object_pose()
    held = held_closing(scene, (p.stage_increments, p.steps_per_increment),
                        v.palm_world(BOWL_GRASP), stages)
    pos, quat = scene.object_pose()
    assert np.allclose(pos, pos0) and np.allclose(quat, quat0)      # held exactly still
    mujoco.mj_rnePostConstraint(scene.model, scene.data)
    external = scene.data.cfrc_ext[scene.obj_body]   # [torque about the COM, force]: all contacts
    assert np.linalg.norm(held.force_n) > 0.1        # a closing that presses, not an empty one
    assert np.allclose(held.force_n, external[3:], atol=1e-9)
    assert np.allclose(held.torque_nm, external[:3], atol=1e-9)
    assert len(held.imbalance_n) == 2 * p.stage_increments and (held.imbalance_n >= 0).all()


def test_a_grasp_that_fails_with_a_reconfiguring_finger_is_diagnosed_so(bowl_validators) -> None:
    found = {settle: diagnose_dgb(v, BOWL_GRASP) for settle, v in bowl_validators.items()}
    for settle, diagnosis in found.items():    # the replay is the validator's: same verdict
        assert diagnosis.passed == bowl_validators[settle].validate(BOWL_GRASP, "dgb").passed
    good, bad = found[True], found[False]
    assert good.passed and not bad.passed
    assert bad.findings["verdict"] == "slipped" and bad.findings["failing_push"] == "-x"
    assert good.findings["failing_push"] is None
    # measured: the middle finger's split moves 0.45 rad unsettled, 0.02 settled
    assert "rh_MFJ2/rh_MFJ1" in bad.findings["pairs_reconfigured"]
    assert good.findings["pairs_reconfigured"] == []
    assert bad.findings["drift_after_squeeze_m_rad"][1] > 2 * good.findings[
        "drift_after_squeeze_m_rad"][1]
    summary = summarise_dgb([good, bad])
    assert summary["failing"]["grasps"] == summary["passing"]["grasps"] == 1
    assert summary["verdicts"] == {"slipped": 1} and summary["failing_push"] == {"-x": 1}
    json.dumps({"summary": summary, "grasp": bad.findings})     # the CLI writes these as JSON


def test_the_replayed_push_is_the_benchmarks_own(bowl_validators) -> None:
    """replay_push runs the validator's push: it ends where the benchmark's phase ended (same
    drift, bit for bit), on the failing push outside the limits and on a passing one inside;
    its direction is the world push seen from frame_palm; the grip is read from the closing."""
    for settle, v in bowl_validators.items():
        result = v.validate(BOWL_GRASP, "dgb")
        stages = v.stages(BOWL_GRASP, sized_for="dgb")
        p, scene, palm = v.config.dgb, v.scene("dgb"), v.palm_world(BOWL_GRASP)
        for name, phase in result.phases.items():
            push = replay_push(scene, p, palm, stages, name)
            assert push.drift_m_rad == (phase.displacement_m, phase.rotation_rad)
            inside = (push.drift_m_rad[0] < p.max_displacement_m
                      and push.drift_m_rad[1] < p.max_rotation_rad)
            assert inside == phase.passed
            world = quat_to_mat(palm[1]) @ push.direction_palm
            assert np.allclose(world, DGB_DIRECTIONS[name])
            assert push.grip_start_n > 0.1 and push.grip_end_n >= 0.0
        hardest = diagnose_dgb(v, BOWL_GRASP).findings["hardest_push"]
        assert hardest["direction"] == ("-x" if not settle else max(
            result.phases, key=lambda k: result.phases[k].rotation_rad))
