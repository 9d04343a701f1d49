"""Validator throughput: validations per second for lift-drop and six-dir.

Workload: for each object, the hand's reference grasps (configs/hands/<hand>/grasps.toml) plus random
perturbations of them (palm ±5 mm / ±5°, joints ±0.05 rad), so passes and the usual failures
(penetration, slipping, lost contact) are all in the mix. Prints one Markdown table and writes
its rows as a record (:func:`benchmarks.record.write_record`, ``benchmarks/measured/validate/``).

    .venv/bin/python benchmarks/bench_validate.py [--n 40] [--objects 004_sugar_box 024_bowl]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.validate.batch import validate_many
from sim.validate.validator import Validator
from sim.world.objects import load_object


def perturbed(hand: Hand, base: list[Grasp], n: int, seed: int) -> list[Grasp]:
    rng = np.random.default_rng(seed)
    out = list(base)
    while len(out) < n:
        g = base[rng.integers(len(base))]
        rot = Rotation.from_rotvec(rng.normal(0, np.deg2rad(5) / np.sqrt(3), 3))
        quat = (rot * Rotation.from_quat(g.palm_quat_wxyz, scalar_first=True)).as_quat(
            scalar_first=True)
        q = hand.clip(g.joints + rng.uniform(-0.05, 0.05, hand.nq))
        out.append(Grasp.from_arrays(g.palm_pos + rng.uniform(-0.005, 0.005, 3), quat, q))
    return out[:n]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--hand", default=default_hand_name())
    parser.add_argument("--n", type=int, default=40, help="grasps per object")
    parser.add_argument("--objects", nargs="+", default=["004_sugar_box", "024_bowl"])
    parser.add_argument("--workers", type=int, nargs="+", default=[2])
    args = parser.parse_args()
    hand = Hand.load(args.hand)
    refs = load_reference_grasps(hand)
    print("| object | protocol | workers | grasps | pass | validations/s | per core | note |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    rows = []
    for obj in args.objects:
        base = [r.grasp for r in refs if r.object == obj]
        if not base:
            print(f"| {obj} | no reference grasps | | | | | |")
            continue
        grasps = perturbed(hand, base, args.n, seed=0)
        validator = Validator(hand, load_object(obj))
        for protocol in ("lift-drop", "six-dir"):
            validator.validate(grasps[0], protocol)  # build the scene outside the timing
            start = time.perf_counter()
            results = [validator.validate(g, protocol) for g in grasps]
            rate = len(grasps) / (time.perf_counter() - start)
            passed = sum(r.passed for r in results)
            print(f"| {obj} | {protocol} | 1 | {len(grasps)} | {passed} | {rate:.1f} | {rate:.1f} | "
                  "in-process, scene built |", flush=True)
            rows.append({"object": obj, "protocol": protocol, "path": "in-process", "workers": 1,
                         "grasps": len(grasps), "passed": passed, "validations_per_s": rate,
                         "per_core": rate})
            for workers in args.workers:
                start = time.perf_counter()
                stamps: list[float] = []
                results = validate_many(args.hand, obj, grasps, protocol, workers=workers,
                                        progress=lambda _n, s=stamps: s.append(time.perf_counter()))
                total = stamps[-1] - start
                steady = (len(grasps) - 1) / max(stamps[-1] - stamps[0], 1e-9)
                passed = sum(r.passed for r in results)
                print(f"| {obj} | {protocol} | {workers} | {len(grasps)} | {passed} | "
                      f"{steady:.1f} | {steady / workers:.1f} | sim.validate.batch steady state "
                      f"({len(grasps) / total:.1f}/s incl. {stamps[0] - start:.1f} s start-up) |",
                      flush=True)
                rows.append({"object": obj, "protocol": protocol, "path": "validate_many",
                             "workers": workers, "grasps": len(grasps), "passed": passed,
                             "validations_per_s": steady, "per_core": steady / workers,
                             "with_start_up_per_s": len(grasps) / total,
                             "start_up_s": stamps[0] - start})
    path = write_record("validate", rows, config=vars(args), hand=hand.name, objects=args.objects)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
