"""Cost curves: how the time of FSG + lift-drop validation grows with n, objects and workers.

Each unit of work is one object on the hand's manual (demonstration-free) workspace, as
``dexaug generate --validate lift-drop`` runs it: AutoWS clouds, FSG for n grasps, every grasp
validated (``sim.validate.batch.validate_many``). Three curves, each printed as a Markdown table:

- ``--ns``: one object (005) at n = 200 … 5,000: FSG s, validation s, validated grasps/s;
- ``--max-objects``: n = 200 (``--objects-n``) on each of the first 1 … 20 YCB objects:
  cumulative wall time;
- ``--workers``: 005 at n = 1,000 (``--workers-n``) with 1 and 2 worker processes.

``--quick`` (a smoke run of a few minutes, not the curves): n = 50; 2 objects at n = 20; 1 and 2
workers at n = 50.

The memory peak (max RSS of this process and of its largest worker, MB) closes each table.
Ray's row of the worker curve comes from ``benchmarks/bench_ray.py``. Every row (``curve``: ns,
objects or workers) and the memory peaks go to a record (:func:`benchmarks.record.write_record`,
``benchmarks/measured/cost_curves/``).

    .venv/bin/python benchmarks/bench_cost_curves.py [--ns 200 1000 5000] [--max-objects 20]
        [--objects-n 200] [--workers 1 2] [--workers-n 1000] [--quick]
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment.autows.build import build_workspace
from augment.object_cloud import object_cloud
from benchmarks.record import write_record
from dexaug.pipeline.run import generate_grasps
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.world.objects import load_object, ycb_folders


def run_one(hand: Hand, obj: str, n: int, workers: int) -> tuple[float, float, int, int]:
    """(FSG seconds, validation seconds, grasps generated, grasps passed) for one object."""
    ws = build_workspace(hand)
    t0 = time.perf_counter()
    res = generate_grasps(hand, object_cloud(load_object(obj)), ws, n=n, seed=0, workers=workers,
                          time_budget_s=1800.0)
    fsg_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    results = validate_many(hand.name, obj, [g.grasp for g in res.grasps], "lift-drop",
                            workers=workers)
    return fsg_s, time.perf_counter() - t0, len(res.grasps), sum(r.passed for r in results)


def memory_peaks_mb() -> dict[str, float]:
    """Max RSS so far (MB) of this process and of its largest (finished) worker."""
    return {"this_process_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "largest_worker_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}


def memory_mb(peaks: dict[str, float]) -> str:
    return (f"memory peak: this process {peaks['this_process_mb']:.0f} MB, largest worker "
            f"{peaks['largest_worker_mb']:.0f} MB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--ns", type=int, nargs="*", default=[200, 1000, 5000])
    parser.add_argument("--max-objects", type=int, default=20)
    parser.add_argument("--workers", type=int, nargs="*", default=[1, 2])
    parser.add_argument("--objects-n", type=int, default=200, help="grasps per object, objects curve")
    parser.add_argument("--workers-n", type=int, default=1000, help="grasps, workers curve")
    parser.add_argument("--quick", action="store_true", help="a smoke run (see above)")
    args = parser.parse_args()
    if args.quick:
        args.ns, args.max_objects, args.objects_n, args.workers_n = [50], 2, 20, 50
    hand = Hand.load(default_hand_name())
    header = "| {} | grasps | passed | FSG s | validation s | total s | validated grasps/s |"
    rule = "| --- | --- | --- | --- | --- | --- | --- |"
    rows: list[dict[str, Any]] = []
    memory: dict[str, dict[str, float]] = {}

    def line(label: object, fsg_s: float, val_s: float, made: int, passed: int) -> str:
        total = fsg_s + val_s
        rows.append({"curve": "ns" if curve == "n" else "workers", curve: label, "grasps": made,
                     "passed": passed, "fsg_s": fsg_s, "validation_s": val_s, "total_s": total,
                     "validated_per_s": made / val_s if val_s else float("nan")})
        return (f"| {label} | {made} | {passed} | {fsg_s:.1f} | {val_s:.1f} | {total:.1f} | "
                f"{made / val_s if val_s else float('nan'):.1f} |")

    curve = "n"
    if args.ns:
        print("\n005_tomato_soup_can, 2 workers\n" + header.format("n") + "\n" + rule)
        for n in args.ns:
            print(line(n, *run_one(hand, "005_tomato_soup_can", n, 2)), flush=True)
        memory["ns"] = memory_peaks_mb()
        print(memory_mb(memory["ns"]))
    if args.max_objects:
        objects = [f.name for f in ycb_folders()][:args.max_objects]
        print(f"\nn = {args.objects_n} per object, 2 workers, cumulative over {len(objects)} objects\n"
              "| objects | last object | cumulative s | grasps | passed |\n| --- | --- | --- | --- | --- |")
        total_s, made_all, passed_all = 0.0, 0, 0
        for k, obj in enumerate(objects, start=1):
            fsg_s, val_s, made, passed = run_one(hand, obj, args.objects_n, 2)
            total_s, made_all, passed_all = total_s + fsg_s + val_s, made_all + made, passed_all + passed
            print(f"| {k} | {obj} | {total_s:.0f} | {made_all} | {passed_all} |", flush=True)
            rows.append({"curve": "objects", "objects": k, "last_object": obj,
                         "cumulative_s": total_s, "grasps": made_all, "passed": passed_all})
        memory["objects"] = memory_peaks_mb()
        print(memory_mb(memory["objects"]))
    curve = "workers"
    if args.workers:
        print(f"\n005_tomato_soup_can, n = {args.workers_n:,}\n" + header.format("workers") + "\n"
              + rule)
        for w in args.workers:
            print(line(w, *run_one(hand, "005_tomato_soup_can", args.workers_n, w)), flush=True)
        memory["workers"] = memory_peaks_mb()
        print(memory_mb(memory["workers"]))
    path = write_record("cost_curves", rows, summary={"memory_peak": memory}, config=vars(args),
                        hand=hand.name, objects=sorted({str(r.get("last_object", "005_tomato_soup_can"))
                                                        for r in rows}))
    print(f"record: {path}")


if __name__ == "__main__":
    main()
