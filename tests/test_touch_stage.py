"""The benchmark closes through the touching grasp (sim.validate.stages, ``through_touch``).

FSG leaves a grasp's fingertips up to its 5 mm contact plane off the surface. Closed pregrasp →
grasp → squeeze as they were, the fingers already touching pressed the free object while the
others still travelled, and ``dgb`` counts that motion as drift. Under the ``dexaug``
convention the benchmark's grasp stage is now the grasp with those contacts moved onto the
surface, with the pregrasp and squeeze derived there; lift-drop has no middle stage and is
unchanged. Measured on five demos (docs/validation.md, "Grasps that hold").
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.grasp import Grasp
from sim.validate.config import ValidateConfig
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_ycb, without_drift_correction, without_settled_modes

#: a grasp of the committed screwdriver demo's augmentation (frame_palm in the object frame,
#: metres, wxyz; 24 joints): holds the benchmark closed through its touching grasp (1.7°),
#: turns 18.6° closed through its own joints
SCREWDRIVER_GRASP = Grasp(
    np.array([0.0834944067324825, 0.13511328834760578, 0.02598160757065014]),
    np.array([0.05654638343908435, 0.7541095909707812, 0.24467641352731265, -0.606839916278794]),
    np.array([0.0, 0.0, -0.34823430653300835, 0.7883901232000341, 0.0, 0.006962684781683048,
              0.022354912893752216, 0.6714474125591858, 0.3797292973061938, 0.3806119767531137,
              0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.4435789466599188, 1.0038112839729445,
              0.16538002269467403, 0.44419389545682947, -0.1742411958271408]))


@pytest.fixture(scope="module")
def validator(shadow) -> Validator:
    # measured with the grasp's own split of the fingers' free modes (``[dgb]
    # settle_free_modes``, added after: tests/test_free_modes.py), and before the squeeze's drift
    # correction (``rehearsal_drift_corrections``), which holds this grasp either way (5.6°)
    return Validator(shadow, load_object("043_phillips_screwdriver"),
                     without_drift_correction(without_settled_modes(ValidateConfig.load())))


def _gaps_m(v: Validator, q: np.ndarray) -> dict[int, float]:
    """Per hand body within the benchmark's contact set at joints ``q``: its gap (metres)."""
    scene = v.scene("lift-drop")
    v._place(scene, SCREWDRIVER_GRASP, q)
    near = v.near_contacts(scene, v.config.dgb.contact_search_m)
    return {int(b): float(near.dist[near.body_a == b].min()) for b in np.unique(near.body_a)}


@needs_ycb
def test_the_benchmarks_grasp_stage_touches_and_lift_drop_has_none(validator) -> None:
    q = SCREWDRIVER_GRASP.joints
    before = _gaps_m(validator, q)
    assert max(before.values()) > 0.002                  # FSG left a fingertip off the surface
    stages = validator.stages(SCREWDRIVER_GRASP, "dexaug", sized_for="dgb")
    after = _gaps_m(validator, stages.grasp)
    assert set(before) <= set(after)
    assert all(abs(after[b]) < abs(before[b]) for b in before)   # each nearer the surface
    assert max(after[b] for b in before) < 0.0005        # and none left off it (2.8 → 0.24 mm)
    # the pregrasp and the squeeze are the touching grasp's own targets
    touching = dataclasses.replace(SCREWDRIVER_GRASP, joints=stages.grasp)
    again = validator.stages(touching, "bodex", sized_for="dgb")
    np.testing.assert_allclose(stages.pregrasp, again.pregrasp, atol=1e-12)
    # lift-drop closes pregrasp → squeeze; its stages keep the grasp's own joints
    np.testing.assert_array_equal(validator.stages(SCREWDRIVER_GRASP, "dexaug").grasp, q)
    # a grasp that carries its stages is run as given
    given = dataclasses.replace(SCREWDRIVER_GRASP, pregrasp=stages.pregrasp, squeeze=stages.squeeze)
    np.testing.assert_array_equal(validator.stages(given, "dexaug", sized_for="dgb").grasp, q)


@needs_ycb
def test_a_screwdriver_grasp_holds_the_benchmark_closed_through_its_touch(validator) -> None:
    """The grasp closes pregrasp → touch → squeeze and holds. Until 2026-12-07 its closing
    without the touch (the grasp's own joints in the middle) failed, which showed the touch
    stage at work; with the benchmark's own collision settings (``[dgb] ccd_iterations``,
    ``multiccd``) it holds either way, so this grasp no longer tells the two apart (a closing
    note of that day says so; a grasp that does is still to be found)."""
    result = validator.validate(SCREWDRIVER_GRASP, "dgb")
    assert result.passed, np.degrees(result.rotation_rad)
    assert result.touch is not None and not np.array_equal(result.touch, SCREWDRIVER_GRASP.joints)
