"""Fingertip (FSG) against power grasps (``augment.power``) on the same objects, no demo.

For each object: ``dexaug generate``'s two modes on the hand's manual workspace with the same
n, seed, workers and protocol, validated in MuJoCo; reports the pass rate, validated (passing)
grasps per minute of generation + validation, the finger-count distribution of the passing
grasps and, for the power mode, how many candidates were tried and where they were dropped.

    .venv/bin/python benchmarks/bench_power.py [--objects A B ...] [--n 40] [--workers 2]

Prints one Markdown table. Single runs: timings vary by about ±15 % on a shared machine.
"""

from __future__ import annotations

import argparse
import logging
import time
from collections import Counter

from augment.autows.build import build_workspace
from augment.object_cloud import object_cloud
from augment.power import generate_power
from dexaug.pipeline.run import generate_grasps
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.world.objects import load_object

#: the heaviest shared YCB objects first (object_weights.yaml), then lighter everyday ones
OBJECTS = ("071_nine_hole_peg_test", "021_bleach_cleanser", "036_wood_block",
           "072_a_toy_airplane", "004_sugar_box", "003_cracker_box", "006_mustard_bottle",
           "002_master_chef_can", "042_adjustable_wrench", "038_padlock")


def _row(hand: Hand, name: str, mode: str, n: int, workers: int, seed: int,
         protocol: str) -> str:
    t0 = time.perf_counter()
    if mode == "power":
        res = generate_power(hand, name, n=n, seed=seed, workers=workers, protocol=protocol,
                             time_budget_s=600)
    else:
        res = generate_grasps(hand, object_cloud(load_object(name)), build_workspace(hand),
                              n=n, seed=seed, workers=workers, hold_protocol=protocol,
                              time_budget_s=600)
    results = validate_many(hand.name, name, [g.grasp for g in res.grasps], protocol,
                            workers=workers) if res.grasps else []
    wall = time.perf_counter() - t0
    passed = [g for g, r in zip(res.grasps, results, strict=True) if r.passed]
    rate = len(passed) / len(results) if results else 0.0
    fingers = Counter(len(g.fingers) for g in passed)
    tried = (f"{res.stats.get('candidates', 0)} tried, "
             + ", ".join(f"{k} {v}" for k, v in sorted(res.stats.items())
                         if k not in ("candidates", "accepted"))) if mode == "power" else ""
    failures = Counter(str(r.failure) for r in results if not r.passed)
    return (f"| {name} ({load_object(name).mass_kg:.2f} kg) | {mode} | {len(results)} | "
            f"{100 * rate:.0f} % | {60 * len(passed) / wall:.0f} | "
            f"{dict(sorted(fingers.items()))} | {dict(failures)} | {tried} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", nargs="*", default=list(OBJECTS))
    ap.add_argument("--modes", nargs="*", default=["fingertip", "power"],
                    choices=["fingertip", "power"])
    ap.add_argument("--hand", default=default_hand_name())
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--protocol", default="lift-drop")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    hand = Hand.load(args.hand)
    print("| object | mode | grasps | lift-drop | validated/min | passing by finger count "
          "| failures | power candidates |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.objects:
        for mode in args.modes:
            print(_row(hand, name, mode, args.n, args.workers, args.seed, args.protocol),
                  flush=True)


if __name__ == "__main__":
    main()
