"""Hand–arm grasps at a table (paper §5.3): how many demo-augmented grasps survive on an arm.

For each object with a committed demo (``recordings/demos/<object>.json``), the demo is
augmented as ``dexaug augment`` does (``--n`` grasps, lift-drop; its passing grasps are the
input), then grasps meet the object at ``--placements`` resting placements on the table for
each arm (:func:`sim.arm.evaluate.evaluate_on_arm`), in each of two ways
(:mod:`dexaug.pipeline.arm_run`): ``carried`` (the paper's: the dataset's grasps carried to
every placement) and ``as-it-lies`` (:class:`dexaug.pipeline.rest_grasps.RestGrasps`: ``--n``
grasps made per resting pose with the demo's workspace, FSG with that pose's table, lift-drop
hanging as it hangs; made once per object, shared by the arms). Printed as a Markdown table
per mode, arm and object: the grasps per placement, (placement, grasp) pairs, the share that
clears the table pre-filter, is reachable (IK at pregrasp, approach, grasp and lift),
collision-free along the way and holds in simulation; the placements where at least one grasp
holds; the failure counts; seconds per planned grasp (IK + planning + simulation) and per pair,
and, as it lies, seconds making the grasps. ``--upright`` adds the carried grasps with the
object upright only (as the demos recorded it). The rows go to a record as well
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/arm/``).

    .venv/bin/python benchmarks/bench_arm.py [--objects 005_tomato_soup_can ...] [--n 50]
        [--placements 20] [--arms ur5e kuka_iiwa_14] [--modes carried as-it-lies] [--upright]
        [--images DIR] [--seed 0] [--quick]

``--seed`` draws the placements and seeds the grasps made as it lies (their FSG seed is
``seed`` + the resting pose's index): another seed is a held-out repeat of the same run.

``--quick``: the soup can, n = 8, 4 placements, the UR5e, carried only (a smoke run).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from benchmarks.record import write_record
from dexaug.pipeline.arm_report import render_arm_result
from dexaug.pipeline.options import AugmentOptions
from dexaug.pipeline.rest_grasps import RestGrasps
from dexaug.pipeline.run import augment_demo
from sim.arm.config import load_arm_config
from sim.arm.evaluate import ArmGraspResult, GraspSource, evaluate_on_arm
from sim.arm.scene import ArmScene
from sim.demo import load_demo
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.batch import default_workers
from sim.world.objects import load_object
from sim.world.resting import resting_poses

DEMOS = Path(__file__).resolve().parents[1] / "recordings" / "demos"
HEADER = ("| mode | arm | object | grasps / placement | pairs | table-clear % | reachable % | "
          "collision-free % | hold % | placements held | failures | s / planned grasp | "
          "s / pair | s making grasps |\n" + "| --- " * 14 + "|")


def pct(k: int, n: int) -> str:
    return f"{100 * k / n:.1f}" if n else "–"


def stats(mode: str, arm: str, name: str, res: Sequence[ArmGraspResult], placements: int,
          wall_s: float, making_s: float) -> dict[str, Any]:
    """One row of the module docstring's table, as data (counts; seconds)."""
    n = len(res)
    fails = Counter(r.failure for r in res if r.failure)
    clear = n - fails["table"]
    reach = clear - fails["unreachable"]
    free = reach - fails["collision"]
    planned = [r for r in res if r.times_s is not None]
    per = sum(r.plan_s + r.sim_s for r in planned) / len(planned) if planned else float("nan")
    return {"mode": mode, "arm": arm, "object": name, "placements": placements, "pairs": n,
            "table_clear": clear, "reachable": reach, "collision_free": free,
            "held": sum(r.passed for r in res),
            "placements_held": len({r.placement for r in res if r.passed}),
            "failures": dict(sorted(fails.items())), "s_per_planned_grasp": per,
            "s_per_pair": (wall_s - making_s) / max(n, 1), "s_making_grasps": making_s}


def row(r: dict[str, Any]) -> str:
    """The Markdown row of :func:`stats`'s dict."""
    n, placements = r["pairs"], r["placements"]
    return (f"| {r['mode']} | {r['arm']} | {r['object']} | {n / placements:.1f} | {n} | "
            f"{pct(r['table_clear'], n)} | {pct(r['reachable'], n)} | "
            f"{pct(r['collision_free'], n)} | {pct(r['held'], n)} | "
            f"{r['placements_held']} / {placements} | "
            f"{', '.join(f'{k} {v}' for k, v in r['failures'].items())} | "
            f"{r['s_per_planned_grasp']:.2f} | {r['s_per_pair']:.3f} | "
            f"{r['s_making_grasps']:.0f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--objects", nargs="+",
                        default=["005_tomato_soup_can", "043_phillips_screwdriver", "004_sugar_box"])
    parser.add_argument("--n", type=int, default=50)
    parser.add_argument("--placements", type=int, default=20)
    parser.add_argument("--arms", nargs="+", default=["ur5e", "kuka_iiwa_14"])
    parser.add_argument("--modes", nargs="+", default=["carried", "as-it-lies"],
                        choices=["carried", "as-it-lies"])
    parser.add_argument("--upright", action="store_true",
                        help="also the carried grasps with the object upright only")
    parser.add_argument("--images", type=Path, help="write the first held grasp of each row as "
                        "<mode>_<arm>_<object>.png here (the paper's Fig. 12)")
    parser.add_argument("--seed", type=int, default=0,
                        help="placements and as-it-lies grasps (default: %(default)s)")
    parser.add_argument("--quick", action="store_true", help="one object and arm, small (smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.objects, args.n, args.placements = args.objects[:1], min(args.n, 8), 4
        args.arms, args.modes = args.arms[:1], ["carried"]
    print(HEADER, flush=True)
    rows: list[dict[str, Any]] = []
    upright_rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.objects:
            demo = load_demo(DEMOS / f"{name}.json")
            s = augment_demo(demo, tmp, AugmentOptions(n=args.n, gallery=0))
            (table,) = dataset.load(s.dataset).values()
            grasps = [Grasp.from_arrays(table["palm_pose"][i][:3], table["palm_pose"][i][3:],
                                        table["hand_pose"][i]) for i in range(len(table))]
            hand, obj = Hand.load(demo.hand), load_object(name)
            sources: dict[str, GraspSource] = {
                "carried": grasps,
                "as-it-lies": RestGrasps(hand, obj, demo, n=args.n, seed=args.seed,
                                         workers=default_workers())}
            for mode in args.modes:
                making_s = 0.0
                for arm in args.arms:
                    source = sources[mode]
                    t0 = time.perf_counter()
                    t_make = time.perf_counter()
                    if isinstance(source, RestGrasps):   # make every pose's set, timed apart
                        for k, pose in enumerate(resting_poses(obj).poses):
                            source(k, pose)
                        making_s = time.perf_counter() - t_make
                    _, res = evaluate_on_arm(load_arm_config(arm), hand, obj, source,
                                             placements=args.placements, seed=args.seed)
                    wall = time.perf_counter() - t0
                    rows.append(stats(mode, arm, name, res, args.placements, wall, making_s))
                    print(row(rows[-1]), flush=True)
                    if args.images and (held_one := next((r for r in res if r.passed), None)):
                        render_arm_result(ArmScene(load_arm_config(arm), hand, obj), held_one,
                                      args.images / f"{mode}_{arm}_{name}.png")
                    making_s = 0.0   # made once per object, shared by the next arm
            upright = resting_poses(obj).upright_index()
            if not args.upright or upright is None:
                continue
            for arm in args.arms:
                t0 = time.perf_counter()
                _, up = evaluate_on_arm(load_arm_config(arm), hand, obj, grasps,
                                        placements=args.placements, seed=args.seed,
                                        rest_index=upright)
                upright_rows.append(stats("carried, upright", arm, name, up, args.placements,
                                          time.perf_counter() - t0, 0.0))
    if upright_rows:
        print("\nObject upright (as in the demos), random position and yaw:\n" + HEADER)
        print("\n".join(row(r) for r in upright_rows))
    hands = {load_demo(DEMOS / f"{name}.json").hand for name in args.objects}
    path = write_record("arm", rows + upright_rows, config=vars(args),
                        hand=next(iter(hands)) if len(hands) == 1 else None, objects=args.objects)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
