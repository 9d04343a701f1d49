"""The benchmark's closing is simulated once per stages and copied back (sim.validate.dgb.closed).

DexGraspBench resets and closes the same stages before each of its six pushes, and the
rehearsal has closed the kept stages already: copying the kept ``MjData`` back must give the
same bits as simulating the closing again, so that the verdicts are the benchmark's own.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sim.validate.dgb import DGB_DIRECTIONS, close, closed, dgb_drift, run_dgb
from sim.validate.result import ValidationResult
from sim.validate.validator import Validator
from sim.world.objects import load_object
from sim.world.scene import Scene
from tests.conftest import needs_ycb
from tests.test_rehearsal import SUGAR_BOX_GRASP


def _snapshot(scene: Scene) -> dict[str, np.ndarray]:
    d = scene.data
    return {"time": np.array([d.time]), "qpos": d.qpos.copy(), "qvel": d.qvel.copy(),
            "qacc_warmstart": d.qacc_warmstart.copy(), "ctrl": d.ctrl.copy(),
            "contact_pos": d.contact.pos[:d.ncon].copy(), "contact_dist": d.contact.dist[:d.ncon].copy(),
            "efc_force": d.efc_force[:d.nefc].copy()}


@pytest.fixture(scope="module")
def sugar_box(shadow):
    v = Validator(shadow, load_object("004_sugar_box"))
    return v, v.stages(SUGAR_BOX_GRASP, "dexaug", sized_for="dgb")   # the rehearsal closed it


@needs_ycb
def test_a_kept_closing_is_the_closing_simulated_again(sugar_box) -> None:
    v, stages = sugar_box
    scene, p, palm = v.scene("dgb"), v.config.dgb, v.palm_world(SUGAR_BOX_GRASP)
    scene.data.qpos[:] += 0.01                      # whatever came before is overwritten
    closed(scene, p, palm, stages)
    copied = _snapshot(scene)
    scene.reset_with_grasp(*palm, stages.pregrasp)
    close(scene, p, stages)
    simulated = _snapshot(scene)
    assert copied["time"][0] > 0 and len(copied["contact_pos"]) > 0
    for name, value in simulated.items():
        np.testing.assert_array_equal(copied[name], value, err_msg=name)


@needs_ycb
def test_run_dgb_measures_what_closing_before_every_push_measures(sugar_box) -> None:
    v, stages = sugar_box
    scene, p, palm = v.scene("dgb"), v.config.dgb, v.palm_world(SUGAR_BOX_GRASP)
    result = ValidationResult("dgb", False, None, 0.0)
    run_dgb(scene, p, palm, stages, result)
    assert result.passed and list(result.phases) == list(DGB_DIRECTIONS)
    # the benchmark's own order: reset, close, push, for every direction
    m, d = scene.model, scene.data
    scene.reset_with_grasp(*palm, stages.pregrasp)
    pos0, quat0 = scene.object_pose()
    checks = round(p.push_time_s / m.opt.timestep) // p.check_every_steps
    for name, direction in DGB_DIRECTIONS.items():
        scene.reset_with_grasp(*palm, stages.pregrasp)
        close(scene, p, stages)
        d.xfrc_applied[scene.obj_body, :3] = p.force_per_kg * scene.obj_mass_kg * np.asarray(direction)
        mujoco.mj_step(m, d, nstep=checks * p.check_every_steps)
        moved_m, turned_rad = dgb_drift(pos0, quat0, *scene.object_pose())
        assert (result.phases[name].displacement_m, result.phases[name].rotation_rad) == (moved_m, turned_rad)
    d.xfrc_applied[scene.obj_body] = 0.0
