"""The full-size check of ``tests/test_dgb_reference.py``: our ``dgb`` verdicts against
DexGraspBench's own on all 300 reference grasps, one record per run.

``tests/test_dgb_reference.py`` compares a fixed stratified quarter of the grasps (every 4th of
each object × DGB-verdict stratum, :func:`stratified_subset`) so that ``make test`` stays short;
this runs every grasp of ``../shared/reference/dexgraspbench/grasps.jsonl`` under each verdict
variant (default: the three with DGB's 0.1 kg mass), requires nothing, and writes per grasp our
verdict beside DGB's, and per variant the agreement, Cohen's κ, the disagreeing grasps and the
same figures over the test's subset, through :func:`benchmarks.record.write_record`
(``benchmarks/measured/dgb_reference/``). The per-object table with the speed is
``benchmarks/bench_dgb_agreement.py``.

``--quick`` validates every 10th grasp of each object only (30 per variant: the CI-size run of
``benchmarks/headline.py run --quick``; its figures are not the full set's).

Usage: ``.venv/bin/python benchmarks/bench_dgb_reference.py [--variants ...] [--workers 2]
[--quick]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
from sim.paths import REPO_ROOT
from sim.validate.batch import default_workers, validate_many
from sim.validate.dgb_reference import (
    VARIANTS,
    ReferenceGrasp,
    cohen_kappa,
    load_reference,
    reference_hand,
)

REFERENCE = REPO_ROOT.parent / "shared" / "reference" / "dexgraspbench" / "grasps.jsonl"
#: the test's sampling step within each stratum (tests/test_dgb_reference.py: EVERY)
EVERY = 4
#: ``--quick``: every QUICK_EVERY-th grasp of each object
QUICK_EVERY = 10


def stratified_subset(refs: list[ReferenceGrasp], variant: str,
                      every: int = EVERY) -> list[ReferenceGrasp]:
    """The test's grasps: within each (object, DGB verdict) stratum in file order, the 1st,
    (every+1)-th, … one (the same rule as ``tests/test_dgb_reference.py``)."""
    strata: dict[tuple[str, bool], list[ReferenceGrasp]] = {}
    for r in refs:
        strata.setdefault((r.object, bool(r.verdicts[variant]["success"])), []).append(r)
    keep = {id(r) for rows in strata.values() for r in rows[::every]}
    return [r for r in refs if id(r) in keep]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variants", nargs="*",
                    default=[v for v, (_, mass) in VARIANTS.items() if mass == "dgb"])
    ap.add_argument("--workers", type=int, default=default_workers())
    ap.add_argument("--quick", action="store_true",
                    help=f"every {QUICK_EVERY}th grasp of each object only (CI size)")
    args = ap.parse_args()
    hand = reference_hand(REFERENCE)
    refs = load_reference(REFERENCE, hand)
    every = QUICK_EVERY if args.quick else 1
    if every > 1:   # the same grasps in every variant: every k-th of each object, file order
        refs = [r for obj in sorted({r.object for r in refs})
                for r in [x for x in refs if x.object == obj][::every]]
    objects = sorted({r.object for r in refs})
    rows, summary = [], {}
    for variant in args.variants:
        convention, mass = VARIANTS[variant]
        if mass != "dgb":
            raise SystemExit(f"{variant}: only the 0.1 kg variants (bench_dgb_agreement.py has "
                             "the real-mass one)")
        in_subset = {id(r) for r in stratified_subset(refs, variant)}
        t0 = time.perf_counter()
        vrows = []
        for obj in objects:
            mine = [r for r in refs if r.object == obj]
            results = validate_many(hand.name, obj, [r.grasp for r in mine], "dgb",
                                    workers=args.workers, squeeze_convention=convention)
            for r, res in zip(mine, results, strict=True):
                vrows.append({"variant": variant, "object": obj, "index": r.index,
                              "dgb_success": bool(r.verdicts[variant]["success"]),
                              "ours_passed": bool(res.passed),
                              "ours_failure": None if res.failure is None else str(res.failure),
                              "in_test_subset": id(r) in in_subset})
        elapsed = time.perf_counter() - t0
        ours = np.array([r["ours_passed"] for r in vrows])
        theirs = np.array([r["dgb_success"] for r in vrows])
        sub = np.array([r["in_test_subset"] for r in vrows])
        agree = ours == theirs
        summary[variant] = {
            "n": len(vrows), "agree": int(agree.sum()), "agreement": float(agree.mean()),
            "kappa": cohen_kappa(ours, theirs), "dgb_pass": int(theirs.sum()),
            "ours_pass": int(ours.sum()),
            "disagree": [f"{r['object']}#{r['index']}" for r, a in zip(vrows, agree, strict=True)
                         if not a],
            "per_object_agreement": {o: float(agree[[r["object"] == o for r in vrows]].mean())
                                     for o in objects},
            "subset_n": int(sub.sum()), "subset_agree": int(agree[sub].sum()),
            "subset_dgb_pass": int(theirs[sub].sum()), "elapsed_s": round(elapsed, 1)}
        s = summary[variant]
        print(f"{variant}: {s['agree']}/{s['n']} agree ({100 * s['agreement']:.1f} %), "
              f"κ = {s['kappa']:.2f}; test subset {s['subset_agree']}/{s['subset_n']}; "
              f"{elapsed:.0f} s; disagree: {', '.join(s['disagree']) or 'none'}")
        rows += vrows
    path = write_record("dgb_reference", rows, summary=summary,
                        config={"variants": args.variants, "workers": args.workers,
                                "every": every,
                                "test_subset_every": EVERY, "reference": str(REFERENCE)},
                        hand=hand.name, objects=objects)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
