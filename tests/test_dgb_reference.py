"""The ``dgb`` protocol against DexGraspBench's own verdicts on the shared reference grasps.

DexGraspBench's unmodified code judged 300 of our Shadow Hand grasps under three ways of making
pregrasp and squeeze (``../shared/reference/dexgraspbench/README.md``). Our implementation must
give the same verdict grasp by grasp on ≥ 97 % of all 300 under each. The verdicts are not
chaotic: moving the object by 100 nm changes none of them, so the figure is stable from run to
run and machine to machine.

All 300 cost ~50–100 s per convention on two cores, so the test runs a fixed stratified quarter
(:func:`benchmarks.bench_dgb_reference.stratified_subset`: within each object × DGB-verdict
stratum in file order, every 4th grasp from the first; ~77 grasps, both verdict classes of every
object that has them) and holds it to what ≥ 97 % over all 300 implies for that sample: at most 9
of the 300 disagree, so more than :func:`max_disagreements` disagreements in the sample (a
hypergeometric tail ≤ 1 %) means the full set is below 97 %. ``benchmarks/bench_dgb_reference.py``
runs the full-300 comparison and records it; ``benchmarks/bench_dgb_agreement.py`` prints it per
object with Cohen's κ and the speed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.bench_dgb_reference import stratified_subset
from sim.errors import GraspInputError
from sim.grasp import Grasp
from sim.paths import REPO_ROOT
from sim.validate.batch import validate_many
from sim.validate.dgb_reference import VARIANTS, cohen_kappa, load_reference, reference_hand
from sim.validate.result import Failure
from tests.conftest import needs_menagerie, needs_ycb

REFERENCE = REPO_ROOT.parent / "shared" / "reference" / "dexgraspbench" / "grasps.jsonl"
pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb,
              pytest.mark.skipif(not REFERENCE.is_file(), reason=f"no {REFERENCE}")]


#: the full-set requirement: agreement on ≥ 97 % of the reference's 300 grasps
FULL_N, FULL_AGREEMENT = 300, 0.97
#: the chance, were the full set exactly at the requirement, that the sample looks worse: the
#: test's false-alarm rate
ALPHA = 0.01


def max_disagreements(n: int, full_n: int = FULL_N, agreement: float = FULL_AGREEMENT,
                      alpha: float = ALPHA) -> int:
    """The most disagreements a sample of ``n`` of ``full_n`` grasps may show: the largest k
    with P(X ≥ k) > ``alpha`` for X ~ Hypergeometric(full_n, K, n), K = the most disagreements
    ``agreement`` allows over all ``full_n`` (9 of 300)."""
    bad = math.floor(round((1 - agreement) * full_n, 9))
    total = math.comb(full_n, n)

    def tail(k: int) -> float:
        return sum(math.comb(bad, i) * math.comb(full_n - bad, n - i)
                   for i in range(k, min(bad, n) + 1)) / total

    return max(k for k in range(n + 1) if tail(k) > alpha)


def test_the_sample_bound_is_the_hypergeometric_tail() -> None:
    # all 300: the plain 97 % (9 disagreements); ~a quarter: 6 of 77 (92 %)
    assert max_disagreements(300) == 9
    assert max_disagreements(77) == 6 and max_disagreements(78) == 6
    assert max_disagreements(1) == 1   # one grasp cannot show the full set below 97 %


@pytest.fixture(scope="module")
def reference():
    hand = reference_hand(REFERENCE)
    return hand, load_reference(REFERENCE, hand)


@pytest.mark.parametrize("variant", ["dexaug_mass0.1", "bodex_mass0.1", "rule_mass0.1"])
def test_verdicts_agree_with_the_benchmark(reference, variant: str) -> None:
    hand, refs = reference
    convention, _ = VARIANTS[variant]
    sample = stratified_subset(refs, variant)
    ours, theirs = [], []
    for obj in sorted({r.object for r in sample}):
        rows = [r for r in sample if r.object == obj]
        results = validate_many(hand.name, obj, [r.grasp for r in rows], "dgb",
                                squeeze_convention=convention)
        assert all(res.squeeze_convention == ("given" if convention == "dexaug" else convention)
                   for res in results)
        ours += [res.passed for res in results]
        theirs += [bool(r.verdicts[variant]["success"]) for r in rows]
    ours_a, theirs_a = np.array(ours), np.array(theirs)
    disagree = int(np.sum(ours_a != theirs_a))
    kappa = cohen_kappa(ours_a, theirs_a)
    allowed = max_disagreements(len(ours))
    print(f"{variant}: {len(ours) - disagree}/{len(ours)} agree (≤ {allowed} may not), "
          f"κ = {kappa:.2f}")
    assert len(refs) == FULL_N and 70 <= len(ours) <= 80 and theirs_a.any() and not theirs_a.all()
    assert disagree <= allowed, (variant, disagree, len(ours), kappa)


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
