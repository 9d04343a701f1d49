"""Is the benchmark's Shadow Hand the hand the demonstrations were recorded on?

The FSG authors' keyframes (``../shared/assets/handdata/fsg_keyframes/srh.txt``) record where
their fingers stopped on the object with every tendon-shared pair at J1 = J2 (within 4 mrad,
twelve pressing fingers); AutoWS samples the same coupling (``coupled_to`` in the hand config).
The benchmark's Shadow (Menagerie's, as DexGraspBench uses it) drives J1 + J2 through one tendon
and leaves their split free. Three measurements:

``press DEMO.json ...``
    The demonstration's grasp on the benchmark's hand, the object held still: every coupled
    finger's tendon target is set ``--press`` rad past the demonstrated sum (a finger that
    presses), the rest at the demonstrated angles, for one second. Prints each coupled
    finger's J2/J1 as demonstrated and where it ends, and whether it touches the object.
``verdicts DATASET.h5 ...``
    Each stored grasp re-validated under ``dgb`` (dexaug convention) twice: on the benchmark's
    hand, and on the same hand with every coupled pair tied by a joint equality (the split held,
    as the demonstrations' hand evidently held it: an experiment, not the benchmark's model).
``imbalance DATASET.h5 ...``
    The benchmark's closing (pregrasp → grasp → squeeze, its ramp) with the object held still:
    the hand's net force (N) and torque over 2 cm (N) on the object, averaged over the closing
    (:func:`sim.validate.diagnose_dgb.held_closing`).
    A squeeze whose forces do not balance on a held object shoves the free one. Reports how
    well that predicts the stored ``dgb`` verdict (AUC; pass rate of the better half).

Up to ``--n`` grasps per verdict and object (default 200); two processes. Each printed row goes
to a record as well (:func:`benchmarks.record.write_record`,
``benchmarks/measured/dgb_demo_hand/``; ``what``: press, verdicts or imbalance).
Units: metres, newtons, radians (degrees where printed so).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Iterator
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.diagnose_dgb import hand_wrench, held_closing, held_steps
from sim.validate.validator import Validator
from sim.world import scene as scene_module
from sim.world.objects import load_object
from sim.world.scene import HAND_PREFIX, Scene

_validator: Validator | None = None


def tied(compose: Callable[[Scene], mujoco.MjSpec]) -> Callable[[Scene], mujoco.MjSpec]:
    """``Scene._compose`` that also ties each coupled pair of the scene's hand (follower =
    coefficient · leader) with a joint equality: the experiment's hand, not the benchmark's."""

    def composed(self: Scene) -> mujoco.MjSpec:
        spec = compose(self)
        names = {j.name for j in spec.joints}
        for follower, leader, coef in self.hand.couplings:
            a, b = (HAND_PREFIX + self.hand.joint_names[k] for k in (follower, leader))
            if a in names and b in names:
                eq = spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT,
                                       objtype=mujoco.mjtObj.mjOBJ_JOINT, name1=a, name2=b)
                poly = np.zeros(len(eq.data))
                poly[1] = coef
                eq.data = poly
        return spec

    return composed


def press(demo_path: Path, press_rad: float) -> list[dict[str, Any]]:
    """Print and return one row per coupled finger (angles in rad)."""
    doc = json.loads(demo_path.read_text())
    hand = Hand.load(doc["hand"])
    validator = Validator(hand, load_object(doc["object"]))
    q = np.asarray(doc["joints_rad"], dtype=float)
    grasp = Grasp(np.asarray(doc["palm_pos_m"]), np.asarray(doc["palm_quat_wxyz"]), q)
    scene = validator.scene("dgb")
    scene.reset_with_grasp(*validator.palm_world(grasp), q)
    target = q.copy()
    for follower, leader, _ in hand.couplings:
        target[[follower, leader]] += press_rad / 2.0
    scene.data.ctrl[scene.hand_act] = scene.ctrl_for(hand.clip(target))
    held_steps(scene, round(1.0 / scene.model.opt.timestep))
    _, _, touching = hand_wrench(scene)
    m, d, names = scene.model, scene.data, hand.joint_names
    rows = []
    for follower, leader, _ in hand.couplings:
        now = [d.qpos[m.joint(HAND_PREFIX + names[k]).qposadr[0]] for k in (leader, follower)]
        body = m.jnt_bodyid[m.joint(HAND_PREFIX + names[follower]).id]
        print(f"| {demo_path.stem} | {names[leader]}/{names[follower]} | "
              f"{q[leader]:.2f}/{q[follower]:.2f} | {now[0]:.2f}/{now[1]:.2f} | "
              f"{'yes' if body in touching else 'no'} |")
        rows.append({"what": "press", "demo": demo_path.stem, "object": doc["object"],
                     "hand": doc["hand"], "pair": f"{names[leader]}/{names[follower]}",
                     "demonstrated_rad": [q[leader], q[follower]], "after_press_rad": now,
                     "touches": body in touching})
    return rows


def _init(hand: str, name: str, held: bool) -> None:
    global _validator
    if held:   # this worker process only; it ends with the pool
        scene_module.Scene._compose = tied(scene_module.Scene._compose)
    _validator = Validator(Hand.load(hand), load_object(name))


def _verdict(job: tuple[np.ndarray, np.ndarray]) -> bool:
    pose, q = job
    return bool(_validator.validate(Grasp(pose[:3], pose[3:], q), "dgb",
                                    squeeze_convention="dexaug").passed)


def _imbalance(job: tuple[np.ndarray, np.ndarray]) -> float:
    pose, q = job
    v = _validator
    grasp = Grasp(pose[:3], pose[3:], q)
    stages = v.stages(grasp, "dexaug", sized_for="dgb")
    p = v.config.dgb
    held = held_closing(v.scene("dgb"), (p.stage_increments, p.steps_per_increment),
                        v.palm_world(grasp), stages)
    return float(held.imbalance_n.mean())


def jobs_of(path: Path, n: int) -> Iterator[tuple[str, str, np.ndarray, list]]:
    """Per object of a dataset: its name, hand, stored verdicts and (palm pose, joints) jobs."""
    for name, table in dataset.load(path).items():
        labels, jobs = [], []
        for verdict, t in ((True, table), (False, table.rejected)):
            if t is None:
                continue
            for i in range(min(len(t), n)):
                labels.append(verdict)
                jobs.append((t.columns["palm_pose"][i], t.columns["hand_pose"][i]))
        yield name, str(table.attrs["hand"]), np.array(labels), jobs


def run_pool(hand: str, name: str, held: bool, fn, jobs: list) -> list:
    with Pool(2, initializer=_init, initargs=(hand, name, held)) as pool:
        return pool.map(fn, jobs)


def auc(labels: np.ndarray, score: np.ndarray) -> float:
    """Probability that a passing grasp scores lower than a failing one (ties count half)."""
    good, bad = score[labels], score[~labels]
    if not len(good) or not len(bad):
        return float("nan")
    less = (good[:, None] < bad[None, :]).mean()
    return float(less + 0.5 * (good[:, None] == bad[None, :]).mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=("press", "verdicts", "imbalance"))
    ap.add_argument("paths", nargs="+", type=Path)
    ap.add_argument("--n", type=int, default=200, help="grasps per object and verdict (200)")
    ap.add_argument("--press", type=float, default=0.3,
                    help="press: tendon target past the demonstrated J1 + J2, rad (0.3)")
    args = ap.parse_args()
    rows: list[dict[str, Any]] = []
    if args.what == "press":
        print("| demo | pair | J2/J1 demonstrated | J2/J1 after 1 s pressing | touches |")
        print("|---|---|---|---|---|")
        for path in args.paths:
            rows += press(path, args.press)
        _record(rows, args)
        return
    if args.what == "verdicts":
        print("| object | grasps | pass, split free (benchmark) | pass, split held | "
              "pass → fail | fail → pass |")
        print("|---|---|---|---|---|---|")
    else:
        print("| object | grasps | stored passes | AUC (low imbalance = pass) | "
              "median pass / fail (N) | pass rate of the lower half |")
        print("|---|---|---|---|---|---|")
    for path in args.paths:
        for name, hand, labels, jobs in jobs_of(path, args.n):
            if args.what == "verdicts":
                free = np.array(run_pool(hand, name, False, _verdict, jobs))
                held = np.array(run_pool(hand, name, True, _verdict, jobs))
                print(f"| {name} | {len(jobs)} | {free.sum()} | {held.sum()} | "
                      f"{(free & ~held).sum()} | {(~free & held).sum()} |")
                rows.append({"what": "verdicts", "dataset": path, "object": name, "hand": hand,
                             "grasps": len(jobs), "pass_split_free": int(free.sum()),
                             "pass_split_held": int(held.sum()),
                             "pass_to_fail": int((free & ~held).sum()),
                             "fail_to_pass": int((~free & held).sum())})
                continue
            score = np.array(run_pool(hand, name, False, _imbalance, jobs))
            lower = np.argsort(score)[:len(score) // 2]
            print(f"| {name} | {len(jobs)} | {labels.sum()} | {auc(labels, score):.2f} | "
                  f"{np.median(score[labels]):.2f} / {np.median(score[~labels]):.2f} | "
                  f"{100 * labels[lower].mean():.1f} % |")
            rows.append({"what": "imbalance", "dataset": path, "object": name, "hand": hand,
                         "grasps": len(jobs), "stored_passes": int(labels.sum()),
                         "auc": auc(labels, score),
                         "median_pass_n": float(np.median(score[labels])) if labels.any() else None,
                         "median_fail_n": float(np.median(score[~labels])) if (~labels).any() else None,
                         "lower_half_pass_rate": float(labels[lower].mean())})
    _record(rows, args)


def _record(rows: list[dict[str, Any]], args: argparse.Namespace) -> None:
    hands = {str(r["hand"]) for r in rows}
    path = write_record("dgb_demo_hand", rows, config=vars(args),
                        hand=next(iter(hands)) if len(hands) == 1 else None,
                        objects=sorted({str(r["object"]) for r in rows}))
    print(f"record: {path}")


if __name__ == "__main__":
    main()
