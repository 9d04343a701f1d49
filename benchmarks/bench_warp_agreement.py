"""MuJoCo Warp against MuJoCo's C engine: verdict agreement and validations/s on a fixed set.

Workload: every k-th of the FSG grasps of one object (``--grasps FILE``, as
``benchmarks/bench_validate_speed.py`` makes it). Both backends run the same protocol programs
(sim.validate.program); Warp's collision and solver differ in detail, so the verdicts are
compared grasp by grasp. ``--device cpu`` runs Warp's CPU backend (slow; for agreement on a
machine without a GPU); the default is the first CUDA device. Needs ``pip install mujoco-warp``.

    python benchmarks/bench_warp_agreement.py [--n 64] [--device cuda] [--protocol lift-drop]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

from augment import dataset
from sim.grasp import Grasp
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.validator import Validator
from sim.world.objects import load_object


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--object", default="005_tomato_soup_can")
    parser.add_argument("--grasps", type=Path, default=Path("/tmp/dexaug_bench_grasps.h5"))
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--protocol", default="lift-drop", choices=["lift-drop", "six-dir"])
    args = parser.parse_args()
    t = dataset.load(args.grasps)[args.object]
    step = max(len(t) // args.n, 1)
    pose, q = t["palm_pose"], t["hand_pose"]
    grasps = [Grasp.from_arrays(pose[i, :3], pose[i, 3:], q[i]) for i in range(0, len(t), step)]
    grasps = grasps[:args.n]
    v = Validator(Hand.load(default_hand_name()), load_object(args.object))
    t0 = time.perf_counter()
    ref = v.validate_all(grasps, args.protocol)
    c_rate = len(grasps) / (time.perf_counter() - t0)
    v.validate_all(grasps[:1], args.protocol, backend="warp", device=args.device, nworld=len(grasps))
    t0 = time.perf_counter()   # kernels compiled and the model uploaded above
    warp = v.validate_all(grasps, args.protocol, backend="warp", device=args.device,
                          nworld=len(grasps))
    w_rate = len(grasps) / (time.perf_counter() - t0)
    same = sum(a.passed == b.passed for a, b in zip(ref, warp, strict=True))
    same_reason = sum(a.failure == b.failure for a, b in zip(ref, warp, strict=True))
    pairs = Counter((str(a.failure), str(b.failure)) for a, b in zip(ref, warp, strict=True)
                    if a.failure != b.failure)
    print(f"{args.object}, {args.protocol}, {len(grasps)} grasps, Warp on {args.device}")
    print("| engine | passed | validations/s | verdicts = C | failure reason = C |")
    print("| --- | --- | --- | --- | --- |")
    print(f"| MuJoCo C (1 thread) | {sum(r.passed for r in ref)} | {c_rate:.2f} | | |")
    print(f"| MuJoCo Warp ({args.device}, {len(grasps)} worlds) | {sum(r.passed for r in warp)} | "
          f"{w_rate:.2f} | {same}/{len(grasps)} ({100 * same / len(grasps):.0f} %) | "
          f"{same_reason}/{len(grasps)} |")
    if pairs:
        print("disagreements (C → Warp):", dict(pairs))


if __name__ == "__main__":
    main()
