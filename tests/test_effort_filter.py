"""FSG rejects grasps whose actuators cannot hold the validation's loads (``[fsg]
max_actuator_effort``), and stops at once on an object no grasp of the hand can hold.

Above an effort of 1 the hand's servos cannot hold the loads at the grasp's contacts however
they squeeze (:mod:`sim.validate.effort`); none of 117 such grasps over seven objects passed
``dgb`` (``benchmarks/bench_grip_predictor.py``). Measured with the filter on (docs/validation.md,
"Grasps that hold"): the authors' bowl demo 27 → 39 of 200 ``dgb`` passes at the same throughput.
The default limit is 0.25, below 1: grasps above it seldom hold in simulation (calibrated on
objects outside every acceptance set, ``bench_grip_predictor.py --bins``).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import pytest

from augment.fsg.params import load_fsg_params
from augment.fsg.run import TOO_WEAK, TOO_WEAK_AFTER, generate
from sim.validate.batch import SceneEffort
from sim.validate.loads import hold_loads
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def bowl_setup(shadow):
    from augment.autows.build import build_workspace
    from augment.object_cloud import object_cloud
    from sim.world.objects import load_object

    obj = load_object("024_bowl")
    return obj, object_cloud(obj), build_workspace(shadow)


@needs_menagerie
@needs_ycb
def test_grasps_the_actuators_cannot_hold_are_rejected(shadow, bowl_setup) -> None:
    obj, cloud, ws = bowl_setup
    effort = SceneEffort(shadow.name, obj.name, "dgb")
    params = load_fsg_params(shadow.config)
    assert params.max_actuator_effort == 0.25   # on by default (configs/augment.toml)

    def run(limit: float):
        return generate(shadow, cloud, ws, n=8, seed=0, time_budget_s=60, effort=effort,
                        hold=hold_loads(obj, "dgb"),
                        params=dataclasses.replace(params, max_actuator_effort=limit))

    on = run(1.0)   # the bowl's rim grasps: some cannot hold a 1 N push at all
    assert len(on.grasps) == 8 and on.stats["effort"] > 0
    assert all(g.actuator_effort <= 1.0 for g in on.grasps)
    off = run(math.inf)   # no scoring, nothing rejected for its effort
    assert off.stats["effort"] == 0 and all(np.isnan(g.actuator_effort) for g in off.grasps)
    # a lower limit shows the output is filtered, not merely ranked: grasps the plain search
    # keeps are replaced by others within the limit
    plain = [effort(g.grasp) for g in off.grasps]
    limit = float(np.median(plain))
    low = run(limit)
    assert max(plain) > limit and all(g.actuator_effort <= limit for g in low.grasps)
    assert len(low.grasps) == 8


@needs_menagerie
@needs_ycb
def test_an_object_no_grasp_can_hold_stops_fsg_at_once_with_one_line(shadow, bowl_setup,
                                                                      monkeypatch, caplog) -> None:
    import dexaug.pipeline.run as pipeline

    _, cloud, ws = bowl_setup

    class Heavier(SceneEffort):   # as if the bowl were a hundred times heavier: the LP is linear
        def __call__(self, grasp):  # type: ignore[no-untyped-def]
            return 100.0 * super().__call__(grasp)

    monkeypatch.setattr(pipeline, "SceneEffort", Heavier)
    with caplog.at_level(logging.WARNING, logger="dexaug.pipeline.run"):
        res = pipeline.generate_grasps(shadow, cloud, ws, n=20, seed=0, time_budget_s=120,
                                       hold_protocol="dgb")
    assert res.stopped == TOO_WEAK and not res.grasps
    assert res.stats["effort"] >= TOO_WEAK_AFTER
    # TOO_WEAK, not the 120 s budget, ended it: asserted by ``stopped`` above, not the clock
    (rec,) = [r for r in caplog.records if r.name == "dexaug.pipeline.run"]
    msg = rec.getMessage()
    assert "024_bowl (0.15 kg, dgb)" in msg and "force limits" in msg and "\n" not in msg
    assert np.isfinite(res.elapsed_s)
