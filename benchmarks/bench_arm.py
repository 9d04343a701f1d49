"""Hand–arm grasps at a table (paper §5.3): how many demo-augmented grasps survive on an arm.

For each object with a committed demo (``recordings/demos/<object>.json``), the demo is
augmented as ``dexaug augment`` does (``--n`` grasps, lift-drop; its passing grasps are the
input), then every grasp meets the object at ``--placements`` resting placements on the table
for each arm (:func:`sim.arm.evaluate.evaluate_on_arm`). Printed as a Markdown table per arm and
object: (placement, grasp) pairs, the share that clears the table pre-filter, the share that
is reachable (IK at pregrasp, approach, grasp and lift), the share collision-free along the
way, the share that holds in simulation, the failure counts, and seconds per planned grasp
(IK + planning + simulation) and per pair. A second table places the object upright only (as
the demos recorded it), random position and yaw.

    .venv/bin/python benchmarks/bench_arm.py [--objects 005_tomato_soup_can ...] [--n 50]
        [--placements 20] [--arms ur5e kuka_iiwa_14]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections import Counter
from pathlib import Path

from augment import dataset
from dexaug.pipeline.options import AugmentOptions
from dexaug.pipeline.run import augment_demo
from sim.arm.config import load_arm_config
from sim.arm.evaluate import ArmGraspResult, evaluate_on_arm
from sim.arm.scene import ArmScene
from sim.demo import load_demo
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.world.objects import load_object
from sim.world.render import render_scene, save_png
from sim.world.resting import resting_poses

DEMOS = Path(__file__).resolve().parents[1] / "recordings" / "demos"


def pct(k: int, n: int) -> str:
    return f"{100 * k / n:.1f}" if n else "–"


def render_result(scene: ArmScene, result: ArmGraspResult, path: Path) -> None:
    """The scene at the end of ``result``'s simulation (object lifted in the hand)."""
    import mujoco

    d = mujoco.MjData(scene.model)
    d.qpos[:] = result.final_qpos
    mujoco.mj_forward(scene.model, d)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_png(path, render_scene(scene.model, d, lookat=d.qpos[scene.obj_qadr:scene.obj_qadr + 3],
                                distance_m=0.8, azimuth_deg=200.0, elevation_deg=-12.0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--objects", nargs="+",
                        default=["005_tomato_soup_can", "043_phillips_screwdriver", "004_sugar_box"])
    parser.add_argument("--n", type=int, default=50)
    parser.add_argument("--placements", type=int, default=20)
    parser.add_argument("--arms", nargs="+", default=["ur5e", "kuka_iiwa_14"])
    parser.add_argument("--images", type=Path, help="write the first held grasp of each upright "
                        "row as <arm>_<object>.png here (the paper's Fig. 12)")
    args = parser.parse_args()
    print("| arm | object | grasps | pairs | table-clear % | reachable % | collision-free % | "
          "hold % | failures | s / planned grasp | s / pair |\n" + "| --- " * 11 + "|")
    upright_rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.objects:
            demo = load_demo(DEMOS / f"{name}.json")
            s = augment_demo(demo, tmp, AugmentOptions(n=args.n, gallery=0))
            (table,) = dataset.load(s.dataset).values()
            grasps = [Grasp.from_arrays(table["palm_pose"][i][:3], table["palm_pose"][i][3:],
                                        table["hand_pose"][i]) for i in range(len(table))]
            hand, obj = Hand.load(demo.hand), load_object(name)
            upright = resting_poses(obj).upright_index()
            for arm in args.arms:
                t0 = time.perf_counter()
                _, res = evaluate_on_arm(load_arm_config(arm), hand, obj, grasps,
                                         placements=args.placements, seed=0)
                wall = time.perf_counter() - t0
                n = len(res)
                fails = Counter(r.failure for r in res if r.failure)
                clear = n - fails["table"]
                reach = clear - fails["unreachable"]
                free = reach - fails["collision"]
                held = sum(r.passed for r in res)
                planned = [r for r in res if r.times_s is not None]
                per = sum(r.plan_s + r.sim_s for r in planned) / len(planned) if planned else float("nan")
                print(f"| {arm} | {name} | {len(grasps)} | {n} | {pct(clear, n)} | {pct(reach, n)} | "
                      f"{pct(free, n)} | {pct(held, n)} | "
                      f"{', '.join(f'{k} {v}' for k, v in sorted(fails.items()))} | {per:.2f} | "
                      f"{wall / n:.3f} |", flush=True)
                if upright is None:
                    continue
                _, up = evaluate_on_arm(load_arm_config(arm), hand, obj, grasps,
                                        placements=args.placements, seed=0, rest_index=upright)
                if args.images and (held_one := next((r for r in up if r.passed), None)):
                    render_result(ArmScene(load_arm_config(arm), hand, obj), held_one,
                                  args.images / f"{arm}_{name}.png")
                f_up = Counter(r.failure for r in up if r.failure)
                upright_rows.append(
                    f"| {arm} | {name} | {len(up)} | {pct(len(up) - f_up['table'], len(up))} | "
                    f"{pct(sum(r.passed for r in up), len(up))} | "
                    f"{', '.join(f'{k} {v}' for k, v in sorted(f_up.items()))} |")
    print("\nObject upright (as in the demos), random position and yaw:\n"
          "| arm | object | pairs | table-clear % | hold % | failures |\n" + "| --- " * 6 + "|")
    print("\n".join(upright_rows))


if __name__ == "__main__":
    main()
