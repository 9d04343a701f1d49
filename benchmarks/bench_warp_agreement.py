"""MuJoCo Warp against MuJoCo's C engine: verdict agreement and validations/s on a fixed set.

Workload: the first ``--n`` FSG grasps of one object (``--grasps FILE``, as
``benchmarks/bench_validate_speed.py`` makes it). Both backends run the same protocol programs
(sim.validate.program); Warp's collision and solver differ in detail, so the verdicts are
compared grasp by grasp. The C reference runs on ``--workers`` processes (``validate_many``;
1: one thread in this process). Warp runs the n grasps as n worlds; ``--worlds`` adds
throughput rows at other world counts (the grasps repeated to fill them). Every Warp row is
timed after a warm-up call on the same runner (kernels compiled, step graph captured), and
says how its time splits: the device loop (upload, steps, download), the host writing each
advanced world's state back with ``mj_forward`` of it, the host starting grasps
(``Validator.start``: placement, penetration, pregrasp and squeeze targets), and the rest (the
programs between calls). ``--device cpu`` runs Warp's CPU backend (slow; for agreement on a
machine without a GPU). Needs ``pip install mujoco-warp``; results of an H200 are in
``benchmarks/measured/warp_h200/`` (written before benchmark records: no commit or machine). Every
run writes a record (:func:`benchmarks.record.write_record`, ``benchmarks/measured/warp_agreement/``:
the rows below and the C reference); ``--json`` writes the old file as well.

    python benchmarks/bench_warp_agreement.py [--n 64] [--device cuda] [--protocol lift-drop]
        [--workers 1] [--worlds 4096,8192] [--json results.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.validate.batched import validate_batched
from sim.validate.program import Program
from sim.validate.result import ValidationResult
from sim.validate.validator import Validator
from sim.validate.warp_runner import WarpRunner
from sim.world.objects import load_object
from sim.world.scene import Scene


def c_reference(v: Validator, hand: str, obj: str, grasps: list[Grasp], protocol: str,
                workers: int) -> tuple[list[ValidationResult], float]:
    """The C engine's verdicts and its validations/s (process pool started beforehand)."""
    if workers > 1:
        validate_many(hand, obj, grasps[:workers], protocol, workers=workers)
    t0 = time.perf_counter()
    ref = (validate_many(hand, obj, grasps, protocol, workers=workers) if workers > 1
           else v.validate_all(grasps, protocol))
    return ref, len(grasps) / (time.perf_counter() - t0)


def warp_row(v: Validator, grasps: list[Grasp], protocol: str, device: str, nworld: int,
             capture: bool = True) -> tuple[list[ValidationResult], dict[str, float]]:
    """Warp's verdicts on ``grasps`` with ``nworld`` worlds, timed after a warm-up."""
    runner = WarpRunner(v.scene(protocol), nworld, device, capture=capture)

    start_s = 0.0

    def start(g: Grasp, view: Scene) -> tuple[ValidationResult, Program | None]:
        nonlocal start_s
        t = time.perf_counter()
        try:
            return v.start(g, protocol, scene=view)
        finally:
            start_s += time.perf_counter() - t

    t0 = time.perf_counter()
    validate_batched(runner, grasps[:min(nworld, 8)], start)
    warmup_s = time.perf_counter() - t0
    print(f"Warp, {nworld} worlds: warm-up (kernels loaded, graph captured) {warmup_s:.1f} s",
          flush=True)
    runner.world_steps, runner.device_s, runner.refresh_s, start_s = 0, 0.0, 0.0, 0.0
    t0 = time.perf_counter()
    out = validate_batched(runner, grasps, start)
    wall = time.perf_counter() - t0
    return out, {"worlds": nworld, "grasps": len(grasps), "warmup_s": warmup_s, "wall_s": wall,
                 "validations_per_s": len(grasps) / wall, "device_s": runner.device_s,
                 "refresh_s": runner.refresh_s, "start_s": start_s,
                 "world_steps_per_s": runner.world_steps / max(runner.device_s, 1e-9),
                 "graph": runner.graph_captured}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--object", default="005_tomato_soup_can")
    parser.add_argument("--grasps", type=Path, default=Path("/tmp/dexaug_bench_grasps.h5"))
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--protocol", default="lift-drop", choices=["lift-drop", "six-dir"])
    parser.add_argument("--workers", type=int, default=1, help="C reference processes")
    parser.add_argument("--worlds", default="", help="more Warp rows: world counts, comma-separated")
    parser.add_argument("--eager", action="store_true",
                        help="one more row: the n worlds stepped without graph capture")
    parser.add_argument("--json", type=Path, default=None, help="write the rows here too")
    args = parser.parse_args()
    t = dataset.load(args.grasps)[args.object]
    pose, q = t["palm_pose"], t["hand_pose"]
    grasps = [Grasp.from_arrays(pose[i, :3], pose[i, 3:], q[i]) for i in range(min(args.n, len(t)))]
    hand = default_hand_name()
    v = Validator(Hand.load(hand), load_object(args.object))
    ref, c_rate = c_reference(v, hand, args.object, grasps, args.protocol, args.workers)
    n = len(grasps)
    print(f"{args.object}, {args.protocol}, {n} grasps, Warp on {args.device}")
    print("| engine | grasps | passed | validations/s | verdicts = C | failure reason = C |")
    print("| --- | --- | --- | --- | --- | --- |")
    print(f"| MuJoCo C ({args.workers} process{'es' if args.workers > 1 else ''}) | {n} | "
          f"{sum(r.passed for r in ref)} | {c_rate:.1f} | | |", flush=True)
    warp, row = warp_row(v, grasps, args.protocol, args.device, len(grasps))
    same = sum(a.passed == b.passed for a, b in zip(ref, warp, strict=True))
    same_reason = sum(a.failure == b.failure for a, b in zip(ref, warp, strict=True))
    pairs = Counter(f"{a.failure} -> {b.failure}" for a, b in zip(ref, warp, strict=True)
                    if a.failure != b.failure)
    print(f"| MuJoCo Warp ({args.device}, {n} worlds) | {n} | {sum(r.passed for r in warp)} | "
          f"{row['validations_per_s']:.1f} | {same}/{n} ({100 * same / n:.1f} %) | "
          f"{same_reason}/{n} |")
    if pairs:
        print("disagreements (C -> Warp):", dict(pairs))
    print("| worlds | grasps | validations/s | device loop share | host: states back + mj_forward "
          "| host: start (place, targets) | world-steps/s (device loop) | warm-up s | graph |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    rows = [row]
    extra = [(int(w), True) for w in args.worlds.split(",") if w]
    if args.eager:
        extra.append((n, False))
    for i, (k, capture) in enumerate([(n, True), *extra]):
        if i > 0:
            rows.append(warp_row(v, (grasps * (k // n + 1))[:k], args.protocol, args.device, k,
                                 capture)[1])
        r = rows[-1]
        print(f"| {r['worlds']} | {r['grasps']} | {r['validations_per_s']:.1f} | "
              f"{100 * r['device_s'] / r['wall_s']:.0f} % | {100 * r['refresh_s'] / r['wall_s']:.0f} % | "
              f"{100 * r['start_s'] / r['wall_s']:.0f} % | {r['world_steps_per_s']:.0f} | "
              f"{r['warmup_s']:.1f} | {r['graph']} |", flush=True)
        if args.json:
            args.json.write_text(json.dumps({"object": args.object, "protocol": args.protocol,
                                             "device": args.device, "c_validations_per_s": c_rate,
                                             "c_workers": args.workers, "agree": same,
                                             "agree_reason": same_reason, "n": n,
                                             "c_passed": sum(r.passed for r in ref),
                                             "warp_passed": sum(r.passed for r in warp),
                                             "disagreements": dict(pairs), "rows": rows}, indent=1))
    summary = {"c_validations_per_s": c_rate, "c_workers": args.workers, "agree": same,
               "agree_reason": same_reason, "n": n, "c_passed": sum(r.passed for r in ref),
               "warp_passed": sum(r.passed for r in warp), "disagreements": dict(pairs)}
    path = write_record("warp_agreement", rows, summary=summary, config=vars(args), hand=hand,
                        objects=[args.object])
    print(f"record: {path}")


if __name__ == "__main__":
    main()
