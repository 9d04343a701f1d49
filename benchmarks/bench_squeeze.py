"""Does the squeeze hold FSG grasps? Pass rates and failure counts of lift-drop and six-dir.

FSG precision grasps load a few fingertips only, so they show whether the validator's squeeze
presses hard enough (docs/validation.md). Workload: FSG grasps
(manual AutoWS workspace, link penetration check on) of each object, validated with both
protocols on all workers. ``--save``/``--load`` keep the grasps in an ``.npz`` so that two
validator versions (or two ``--config`` files) are compared on exactly the same grasps; FSG
under a time budget is not guaranteed to return the same grasps twice. Prints one Markdown table
and writes its rows as a record (:func:`benchmarks.record.write_record`,
``benchmarks/measured/squeeze/``).

    .venv/bin/python benchmarks/bench_squeeze.py [--n 40] [--seed 1] [--save grasps.npz]
    .venv/bin/python benchmarks/bench_squeeze.py --load grasps.npz [--config my_validate.toml]

``--quick``: the first object at n = 8 (a smoke run, not the figures).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.batch import default_workers, validate_many

OBJECTS = ["004_sugar_box", "005_tomato_soup_can", "043_phillips_screwdriver", "062_dice"]


def fsg_grasps(hand: Hand, objects: list[str], n: int, seed: int, budget_s: float,
               workers: int) -> dict[str, list[Grasp]]:
    """FSG grasps per object on the manual (demo-free) workspace."""
    from augment.autows.build import build_workspace
    from augment.object_cloud import object_cloud
    from dexaug.pipeline.run import generate_grasps
    from sim.world.objects import load_object

    workspace = build_workspace(hand)
    out = {}
    for name in objects:
        res = generate_grasps(hand, object_cloud(load_object(name)), workspace, n=n, seed=seed,
                       time_budget_s=budget_s, workers=workers, link_penetration=True)
        out[name] = [g.grasp for g in res.grasps]
    return out


def save(path: Path, grasps: dict[str, list[Grasp]]) -> None:
    arrays = {}
    for name, gs in grasps.items():
        arrays[f"{name}/palm_pos"] = np.array([g.palm_pos for g in gs]).reshape(-1, 3)
        arrays[f"{name}/palm_quat_wxyz"] = np.array([g.palm_quat_wxyz for g in gs]).reshape(-1, 4)
        arrays[f"{name}/joints"] = np.array([g.joints for g in gs])
    np.savez(path, **arrays)


def load(path: Path) -> dict[str, list[Grasp]]:
    data = np.load(path)
    names = sorted({k.rsplit("/", 1)[0] for k in data.files})
    return {name: [Grasp.from_arrays(p, q, j) for p, q, j in zip(
        data[f"{name}/palm_pos"], data[f"{name}/palm_quat_wxyz"], data[f"{name}/joints"],
        strict=True)] for name in names}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hand", default=default_hand_name())
    parser.add_argument("--objects", nargs="+", default=OBJECTS)
    parser.add_argument("--n", type=int, default=40, help="FSG grasps per object")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--budget-s", type=float, default=60.0, help="FSG time budget per object")
    parser.add_argument("--workers", type=int, default=default_workers())
    parser.add_argument("--protocols", nargs="+", default=["lift-drop", "six-dir"])
    parser.add_argument("--config", type=Path, help="validate.toml to use (default: configs/)")
    parser.add_argument("--save", type=Path, help="write the generated grasps here (.npz)")
    parser.add_argument("--load", type=Path, help="validate these grasps instead of running FSG")
    parser.add_argument("--quick", action="store_true", help="one object, n = 8 (smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.objects, args.n = args.objects[:1], min(args.n, 8)
    logging.basicConfig(level=logging.ERROR)
    hand = Hand.load(args.hand)
    if args.load:
        grasps = {k: v for k, v in load(args.load).items() if k in args.objects}
    else:
        grasps = fsg_grasps(hand, args.objects, args.n, args.seed, args.budget_s, args.workers)
        if args.save:
            save(args.save, grasps)
    print("| object | protocol | grasps | pass | pass rate | failures | validations/s/core |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    rows = []
    for name, gs in grasps.items():
        for protocol in args.protocols:
            start = time.perf_counter()
            results = validate_many(hand.name, name, gs, protocol, workers=args.workers,
                                    config_path=args.config)
            seconds = time.perf_counter() - start  # includes the workers' start-up
            passed = sum(r.passed for r in results)
            fails = Counter(str(r.failure) for r in results if not r.passed)
            failures = ", ".join(f"{k} {v}" for k, v in sorted(fails.items())) or "-"
            rate = passed / len(results) if results else float("nan")
            print(f"| {name} | {protocol} | {len(results)} | {passed} | {rate:.0%} | {failures} | "
                  f"{len(results) / seconds / args.workers:.1f} |", flush=True)
            rows.append({"object": name, "protocol": protocol, "grasps": len(results),
                         "passed": passed, "pass_rate": rate, "failures": dict(sorted(fails.items())),
                         "validations_per_s_per_core": len(results) / seconds / args.workers})
    path = write_record("squeeze", rows, config=vars(args), hand=hand.name, objects=list(grasps))
    print(f"record: {path}")


if __name__ == "__main__":
    main()
