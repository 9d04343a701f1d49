"""The ``dgb`` protocol against DexGraspBench's own verdicts, grasp by grasp, and its speed.

Runs every grasp of ``../shared/reference/dexgraspbench/grasps.jsonl`` (300 Shadow Hand grasps of
three YCB objects) through our ``dgb`` protocol under each verdict variant of the file (squeeze
convention × object mass) and prints, per variant and object, how many verdicts agree, Cohen's
κ and the pass counts of both; then validations per second of ``dgb`` and ``lift-drop`` on one
core (the same grasps).

Usage: ``.venv/bin/python benchmarks/bench_dgb_agreement.py [--variants ...] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from sim.paths import REPO_ROOT
from sim.validate.batch import default_workers, validate_many
from sim.validate.config import VALIDATE_TOML
from sim.validate.dgb_reference import VARIANTS, cohen_kappa, load_reference, reference_hand

REFERENCE = REPO_ROOT.parent / "shared" / "reference" / "dexgraspbench" / "grasps.jsonl"


def real_mass_config(folder: Path) -> Path:
    """A copy of validate.toml whose dgb object mass is the object's own."""
    original = VALIDATE_TOML.read_text()
    text = original.replace("object_mass_kg = 0.1 ", 'object_mass_kg = "real" ', 1)
    if text == original:
        raise SystemExit(f"{VALIDATE_TOML}: no 'object_mass_kg = 0.1' line to switch to the real mass")
    path = folder / "validate_real_mass.toml"
    path.write_text(text)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS))
    ap.add_argument("--workers", type=int, default=default_workers())
    ap.add_argument("--speed-n", type=int, default=30, help="grasps per protocol for the timing")
    args = ap.parse_args()
    hand = reference_hand(REFERENCE)
    refs = load_reference(REFERENCE, hand)
    by_object = defaultdict(list)
    for r in refs:
        by_object[r.object].append(r)
    print("| Variant | Object | Agree | κ | DGB pass | ours pass |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for variant in args.variants:
            convention, mass = VARIANTS[variant]
            cfg = real_mass_config(Path(tmp)) if mass == "real" else None
            theirs_all, ours_all = [], []
            for obj, rows in by_object.items():
                res = validate_many(hand.name, obj, [r.grasp for r in rows], "dgb",
                                    workers=args.workers, config_path=cfg,
                                    squeeze_convention=convention)
                ours = np.array([x.passed for x in res])
                theirs = np.array([bool(r.verdicts[variant]["success"]) for r in rows])
                ours_all.append(ours)
                theirs_all.append(theirs)
                print(f"| {variant} | {obj} | {int((ours == theirs).sum())}/{len(rows)} | "
                      f"{cohen_kappa(ours, theirs):.2f} | {int(theirs.sum())} | {int(ours.sum())} |")
            ours, theirs = np.concatenate(ours_all), np.concatenate(theirs_all)
            print(f"| {variant} | all | {int((ours == theirs).sum())}/{len(ours)} "
                  f"({100 * np.mean(ours == theirs):.1f} %) | {cohen_kappa(ours, theirs):.2f} | "
                  f"{int(theirs.sum())} | {int(ours.sum())} |")
    print("\n| Protocol | grasps | s | validations / s (1 core) |\n|---|---|---|---|")
    sample = refs[::max(len(refs) // max(args.speed_n, 1), 1)][:args.speed_n]
    for protocol in ("dgb", "lift-drop"):
        t0 = time.perf_counter()
        for r in sample:
            validate_many(hand.name, r.object, [r.grasp], protocol, workers=1)
        dt = time.perf_counter() - t0
        print(f"| {protocol} | {len(sample)} | {dt:.1f} | {len(sample) / dt:.2f} |")


if __name__ == "__main__":
    main()
