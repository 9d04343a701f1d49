"""Cost curves: how the time of FSG + lift-drop validation grows with n, objects and workers.

Each unit of work is one object on the hand's manual (demonstration-free) workspace, as
``dexaug generate --validate lift-drop`` runs it: AutoWS clouds, FSG for n grasps, every grasp
validated (``sim.validate.batch.validate_many``). Three curves, each printed as a Markdown table:

- ``--ns``: one object (005) at n = 200 … 5,000: FSG s, validation s, validated grasps/s;
- ``--objects``: n = 200 on each of the first 1 … 20 YCB objects: cumulative wall time;
- ``--workers``: 005 at n = 1,000 with 1 and 2 worker processes.

The memory peak (max RSS of this process and of its largest worker, MB) closes each table.
Ray's row of the worker curve comes from ``benchmarks/bench_ray.py``.

    .venv/bin/python benchmarks/bench_cost_curves.py [--ns 200 1000 5000] [--max-objects 20]
"""

from __future__ import annotations

import argparse
import resource
import time

from augment.autows.build import build_workspace
from augment.object_cloud import object_cloud
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


def memory_mb() -> str:
    me = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return f"memory peak: this process {me:.0f} MB, largest worker {child:.0f} MB"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--ns", type=int, nargs="*", default=[200, 1000, 5000])
    parser.add_argument("--max-objects", type=int, default=20)
    parser.add_argument("--workers", type=int, nargs="*", default=[1, 2])
    args = parser.parse_args()
    hand = Hand.load(default_hand_name())
    header = "| {} | grasps | passed | FSG s | validation s | total s | validated grasps/s |"
    rule = "| --- | --- | --- | --- | --- | --- | --- |"

    def line(label: object, fsg_s: float, val_s: float, made: int, passed: int) -> str:
        total = fsg_s + val_s
        return (f"| {label} | {made} | {passed} | {fsg_s:.1f} | {val_s:.1f} | {total:.1f} | "
                f"{made / val_s if val_s else float('nan'):.1f} |")

    if args.ns:
        print("\n005_tomato_soup_can, 2 workers\n" + header.format("n") + "\n" + rule)
        for n in args.ns:
            print(line(n, *run_one(hand, "005_tomato_soup_can", n, 2)), flush=True)
        print(memory_mb())
    if args.max_objects:
        objects = [f.name for f in ycb_folders()][:args.max_objects]
        print(f"\nn = 200 per object, 2 workers, cumulative over {len(objects)} objects\n"
              "| objects | last object | cumulative s | grasps | passed |\n| --- | --- | --- | --- | --- |")
        total_s, made_all, passed_all = 0.0, 0, 0
        for k, obj in enumerate(objects, start=1):
            fsg_s, val_s, made, passed = run_one(hand, obj, 200, 2)
            total_s, made_all, passed_all = total_s + fsg_s + val_s, made_all + made, passed_all + passed
            print(f"| {k} | {obj} | {total_s:.0f} | {made_all} | {passed_all} |", flush=True)
        print(memory_mb())
    if args.workers:
        print("\n005_tomato_soup_can, n = 1,000\n" + header.format("workers") + "\n" + rule)
        for w in args.workers:
            print(line(w, *run_one(hand, "005_tomato_soup_can", 1000, w)), flush=True)
        print(memory_mb())


if __name__ == "__main__":
    main()
