"""The ``dgb`` protocol against DexGraspBench's own verdicts, grasp by grasp, and its speed.

Runs every grasp of ``../shared/reference/dexgraspbench/grasps.jsonl`` (300 Shadow Hand grasps of
three YCB objects) through our ``dgb`` protocol under each verdict variant of the file (squeeze
convention × object mass) and prints, per variant and object, how many verdicts agree, Cohen's
κ and the pass counts of both; then validations per second of ``dgb`` and ``lift-drop`` on one
core (the same grasps). Every printed row goes to a record as well
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/dgb_agreement/``; ``table``:
agreement or speed).

``--quick``: every 10th grasp of each object and 4 timed grasps (a smoke run; not the figures).

Usage: ``.venv/bin/python benchmarks/bench_dgb_agreement.py [--variants ...] [--workers 2]
[--quick]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
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
    ap.add_argument("--quick", action="store_true", help="every 10th grasp, 4 timed (smoke run)")
    args = ap.parse_args()
    if args.quick:
        args.speed_n = min(args.speed_n, 4)
    hand = reference_hand(REFERENCE)
    refs = load_reference(REFERENCE, hand)
    by_object = defaultdict(list)
    for r in refs:
        by_object[r.object].append(r)
    if args.quick:
        by_object = defaultdict(list, {o: rows[::10] for o, rows in by_object.items()})
    records: list[dict[str, Any]] = []

    def agreement(variant: str, obj: str, ours: np.ndarray, theirs: np.ndarray) -> None:
        records.append({"table": "agreement", "variant": variant, "object": obj,
                        "n": len(ours), "agree": int((ours == theirs).sum()),
                        "agreement": float(np.mean(ours == theirs)),
                        "kappa": cohen_kappa(ours, theirs), "dgb_pass": int(theirs.sum()),
                        "ours_pass": int(ours.sum())})

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
                agreement(variant, obj, ours, theirs)
                print(f"| {variant} | {obj} | {int((ours == theirs).sum())}/{len(rows)} | "
                      f"{cohen_kappa(ours, theirs):.2f} | {int(theirs.sum())} | {int(ours.sum())} |")
            ours, theirs = np.concatenate(ours_all), np.concatenate(theirs_all)
            agreement(variant, "all", ours, theirs)
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
        records.append({"table": "speed", "protocol": protocol, "grasps": len(sample), "s": dt,
                        "validations_per_s": len(sample) / dt})
    path = write_record("dgb_agreement", records,
                        summary={r["variant"]: r for r in records if r.get("object") == "all"},
                        config={**vars(args), "reference": str(REFERENCE)}, hand=hand.name,
                        objects=sorted(by_object))
    print(f"record: {path}")


if __name__ == "__main__":
    main()
