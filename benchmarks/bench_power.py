"""Fingertip (FSG) against power grasps (``augment.power``) on the same objects, no demo.

For each object: ``dexaug generate``'s two modes on the hand's manual workspace with the same
n, seed, workers and protocol, validated in MuJoCo; reports the pass rate, validated (passing)
grasps per minute of generation + validation, the finger-count distribution of the passing
grasps and, for the power mode, how many candidates were tried and where they were dropped.

    .venv/bin/python benchmarks/bench_power.py [--objects A B ...] [--n 40] [--workers 2] [--quick]

``--quick``: the first two objects at n = 8 (a smoke run, not the figures).

Prints one Markdown table and writes its rows as a record (:func:`benchmarks.record.write_record`,
``benchmarks/measured/power/``). Single runs: timings vary by about ±15 % on a shared machine.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment.autows.build import build_workspace
from augment.object_cloud import object_cloud
from augment.power import generate_power
from benchmarks.record import write_record
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
         protocol: str) -> dict[str, Any]:
    """One object and mode, generated and validated: the table's row as data."""
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
    return {"object": name, "mass_kg": load_object(name).mass_kg, "mode": mode,
            "grasps": len(results), "passed": len(passed), "pass_rate": rate,
            "validated_per_min": 60 * len(passed) / wall, "wall_s": wall,
            "passing_by_fingers": dict(sorted(fingers.items())),
            "failures": dict(Counter(str(r.failure) for r in results if not r.passed)),
            "power_stats": dict(sorted(res.stats.items())) if mode == "power" else None}


def _line(r: dict[str, Any]) -> str:
    """The Markdown row of :func:`_row`'s dict."""
    stats = r["power_stats"]
    tried = (f"{stats.get('candidates', 0)} tried, "
             + ", ".join(f"{k} {v}" for k, v in stats.items()
                         if k not in ("candidates", "accepted"))) if stats is not None else ""
    return (f"| {r['object']} ({r['mass_kg']:.2f} kg) | {r['mode']} | {r['grasps']} | "
            f"{100 * r['pass_rate']:.0f} % | {r['validated_per_min']:.0f} | "
            f"{r['passing_by_fingers']} | {r['failures']} | {tried} |")


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
    ap.add_argument("--quick", action="store_true", help="two objects, n = 8 (smoke run)")
    args = ap.parse_args()
    if args.quick:
        args.objects, args.n = args.objects[:2], min(args.n, 8)
    logging.basicConfig(level=logging.WARNING)
    hand = Hand.load(args.hand)
    print("| object | mode | grasps | lift-drop | validated/min | passing by finger count "
          "| failures | power candidates |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for name in args.objects:
        for mode in args.modes:
            rows.append(_row(hand, name, mode, args.n, args.workers, args.seed, args.protocol))
            print(_line(rows[-1]), flush=True)
    path = write_record("power", rows, config=vars(args), hand=hand.name, objects=args.objects)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
