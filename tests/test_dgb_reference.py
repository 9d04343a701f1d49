"""The ``dgb`` protocol against DexGraspBench's own verdicts on the shared reference grasps.

DexGraspBench's unmodified code judged 300 of our Shadow Hand grasps under three ways of making
pregrasp and squeeze (``../shared/reference/dexgraspbench/README.md``). Our implementation must
give the same verdict grasp by grasp on ≥ 97 % of all 300 under each (about 50 s per convention
on two cores). The verdicts are not chaotic: moving the object by 100 nm changes none of them,
so the figure is stable from run to run and machine to machine. ``benchmarks/
bench_dgb_agreement.py`` prints the same comparison per object with Cohen's κ and the speed."""

from __future__ import annotations

import numpy as np
import pytest

from sim.errors import GraspInputError
from sim.grasp import Grasp
from sim.paths import REPO_ROOT
from sim.validate.batch import validate_many
from sim.validate.dgb_reference import VARIANTS, cohen_kappa, load_reference, reference_hand
from sim.validate.result import Failure
from tests.conftest import needs_menagerie, needs_ycb

REFERENCE = REPO_ROOT.parent / "shared" / "reference" / "dexgraspbench" / "grasps.jsonl"
pytestmark = [needs_menagerie, needs_ycb,
              pytest.mark.skipif(not REFERENCE.is_file(), reason=f"no {REFERENCE}")]


@pytest.fixture(scope="module")
def reference():
    hand = reference_hand(REFERENCE)
    return hand, load_reference(REFERENCE, hand)


@pytest.mark.parametrize("variant", ["dexaug_mass0.1", "bodex_mass0.1", "rule_mass0.1"])
def test_verdicts_agree_with_the_benchmark(reference, variant: str) -> None:
    hand, refs = reference
    convention, _ = VARIANTS[variant]
    ours, theirs = [], []
    for obj in sorted({r.object for r in refs}):
        rows = [r for r in refs if r.object == obj]
        results = validate_many(hand.name, obj, [r.grasp for r in rows], "dgb",
                                squeeze_convention=convention)
        assert all(res.squeeze_convention == ("given" if convention == "dexaug" else convention)
                   for res in results)
        ours += [res.passed for res in results]
        theirs += [bool(r.verdicts[variant]["success"]) for r in rows]
    ours_a, theirs_a = np.array(ours), np.array(theirs)
    agreement = float(np.mean(ours_a == theirs_a))
    kappa = cohen_kappa(ours_a, theirs_a)
    print(f"{variant}: {agreement:.1%} agree, κ = {kappa:.2f} over {len(ours)} grasps")
    assert agreement >= 0.97, (variant, agreement, kappa)
    assert len(ours) == 300 and theirs_a.any() and not theirs_a.all()


def test_pregrasp_penetration_is_rejected_as_the_benchmark_does(reference) -> None:
    """The benchmark's 1 cm filter at the pregrasp: the two grasps it rejected, we reject."""
    hand, refs = reference
    rejected = [r for r in refs if r.verdicts["dexaug_mass0.1"]["rejected_penetration"]]
    assert rejected
    for r in rejected:
        (res,) = validate_many(hand.name, r.object, [r.grasp], "dgb", workers=1)
        assert res.failure == Failure.PENETRATION


def test_a_grasp_without_stages_gets_them_from_the_convention(reference) -> None:
    hand, refs = reference
    r = refs[0]
    bare = Grasp.from_arrays(r.grasp.palm_pos, r.grasp.palm_quat_wxyz, r.grasp.joints)
    (dexaug,) = validate_many(hand.name, r.object, [bare], "dgb", workers=1)
    (rule,) = validate_many(hand.name, r.object, [bare], "dgb", workers=1,
                            squeeze_convention="dgb-rule")
    assert dexaug.squeeze_convention == "dexaug" and rule.squeeze_convention == "dgb-rule"
    np.testing.assert_allclose(rule.pregrasp, 0.9 * bare.joints)
    np.testing.assert_allclose(rule.squeeze, 1.1 * bare.joints)
    assert not np.allclose(dexaug.squeeze, rule.squeeze)


def test_bad_stage_vectors_and_conventions_are_one_line_errors(reference) -> None:
    hand, refs = reference
    g = refs[0].grasp
    with pytest.raises(GraspInputError, match="squeeze: expected 24"):
        Grasp.from_arrays(g.palm_pos, g.palm_quat_wxyz, g.joints, squeeze=g.joints[:3])
    with pytest.raises(GraspInputError, match="squeeze convention: expected one of"):
        validate_many(hand.name, refs[0].object, [g], "dgb", workers=1, squeeze_convention="magic")


def test_closing_drift_replays_the_benchmarks_own_closing(reference) -> None:
    """``closing_drift`` (benchmarks/bench_dgb_drift.py) must show the drift the benchmark's
    run has when its first push starts: same reset, same two stages, same numbers."""
    from sim.validate.dgb import closing_drift, dgb_drift, run_dgb
    from sim.validate.result import ValidationResult
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    hand, refs = reference
    for r in refs[:3]:
        validator = Validator(hand, load_object(r.object))
        stages = validator.stages(r.grasp, "bodex", sized_for="dgb")
        scene, params = validator.scene("dgb"), validator.config.dgb
        palm = validator.palm_world(r.grasp)
        drift = closing_drift(scene, params, palm, stages)
        scene.reset_with_grasp(*palm, stages.pregrasp)
        start = scene.object_pose()
        seen = []
        result = ValidationResult(protocol="dgb", passed=False, failure=None, penetration_m=0.0)

        def record(seen=seen, start=start, scene=scene) -> None:
            seen.append(dgb_drift(*start, *scene.object_pose()))

        run_dgb(scene, params, palm, stages, result, after_first_close=record)
        assert seen and np.allclose(drift["squeeze"], seen[0], rtol=0, atol=1e-12), (drift, seen)
        assert drift["grasp"] != drift["squeeze"]
