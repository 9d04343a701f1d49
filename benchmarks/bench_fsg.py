"""FSG benchmark in the shape of the paper's Tables 2 and 3 (Shadow Hand, five YCB objects).

Per object, workspace mode and FSG variant: wall time per result (the whole ``generate`` call,
object cloud from cache, workspace cloud built beforehand, divided by the grasps returned), mean
GWS ε and volume of the returned grasps (FSG's own contacts, so all ε > 0 by construction), and
then the MuJoCo lift-and-drop validation of every returned grasp (``sim.batch.validate_many``):
"valid ε %" = share of grasps whose *simulated* contacts after closing are in force closure (the
paper's GraspIt "valid epsilon percentage", measured in MuJoCo instead), and the pass rate.

Variants (paper section 5.1): FSG (whole object cloud), FSG+Aff (graspable part: no affordance
annotations ship with dexaug, so the curvature filter stands in for them), FSG+Aff-FinIter (no
finger iteration), FSG+Aff+LinkPen (link penetration check). Workspace modes: "manual" (the
config's joint ranges, paper Table 1) for every object, "demo" (AutoWS centred on a
demonstration) only where configs/grasps/shadow_right.toml has a reference grasp: 004, 005 and
024. The reference grasps are hand-built power wraps; the demo contacts come from
``Validator.fingertip_contacts``.

Usage: ``.venv/bin/python benchmarks/bench_fsg.py [--n 10] [--budget 20] [--objects ...]``.
Rows that find nothing show "—" (as the paper's NaN rows).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import time

import numpy as np

from augment.fsg import generate
from augment.object_cloud import object_cloud
from augment.workspace import DemoSeed, build_workspace
from sim.batch import validate_many
from sim.hand import Hand
from sim.objects import load_object
from sim.paths import ensure_menagerie_root
from sim.reference_grasps import load_reference_grasps
from sim.validate import Validator

OBJECTS = ("004_sugar_box", "005_tomato_soup_can", "024_bowl", "043_phillips_screwdriver",
           "062_dice")
VARIANTS = {
    "FSG": {"use_affordance": False},
    "FSG+Aff": {},
    "FSG+Aff-FinIter": {"finger_iteration": False},
    "FSG+Aff+LinkPen": {"link_penetration": True},
}


def _fmt(x: float, spec: str) -> str:
    return "—" if not math.isfinite(x) else format(x, spec)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=10, help="grasps requested per run")
    ap.add_argument("--budget", type=float, default=20.0, help="time budget per run, seconds")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--objects", nargs="*", default=list(OBJECTS))
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS))
    ap.add_argument("--modes", nargs="*", default=["manual", "demo"])
    ap.add_argument("--workers", type=int, default=1, help="FSG processes")
    ap.add_argument("--no-validate", action="store_true")
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    ensure_menagerie_root()
    hand = Hand.load("shadow_right")
    refs = {r.object: r for r in load_reference_grasps(hand)}
    manual_ws = build_workspace(hand)
    rows = []
    for name in args.objects:
        obj = load_object(name)
        cloud = object_cloud(obj)
        for mode in args.modes:
            if mode == "demo":
                if name not in refs:
                    continue
                ref = refs[name]
                contacts = Validator(hand, obj).fingertip_contacts(ref.grasp)
                ws = build_workspace(hand, demo=DemoSeed(ref.grasp.joints, contacts, ref.name))
            else:
                ws = manual_ws
            for variant in args.variants:
                t0 = time.perf_counter()
                res = generate(hand, cloud, ws, n=args.n, seed=args.seed,
                               time_budget_s=args.budget, workers=args.workers,
                               **VARIANTS[variant])  # type: ignore[arg-type]
                wall = time.perf_counter() - t0
                k = len(res.grasps)
                eps = float(np.mean([g.epsilon for g in res.grasps])) if k else math.nan
                vol = float(np.mean([g.volume for g in res.grasps])) if k else math.nan
                valid = passed = math.nan
                if k and not args.no_validate:
                    vr = validate_many(hand.name, name, [g.grasp for g in res.grasps],
                                       workers=min(k, len(os.sched_getaffinity(0))))
                    valid = 100.0 * np.mean([r.epsilon > 0 for r in vr])
                    passed = 100.0 * np.mean([r.passed for r in vr])
                rows.append((name, mode, variant, k, wall / k if k else math.nan, eps, vol, valid,
                             passed, res.stopped))
                print(f"# {name} {mode} {variant}: {k}/{args.n} in {wall:.2f} s "
                      f"({res.stopped}); fingers {[len(s) for s in res.finger_sets]}", flush=True)
    print()
    print("| Object | Workspace | Method | Results | Time / result (s) | GWS ε | GWS volume "
          "| Valid ε % (sim) | Lift-drop pass % |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, mode, variant, k, tpr, eps, vol, valid, passed, stopped in rows:
        note = "" if stopped == "done" else " (budget)"
        print(f"| {name} | {mode} | {variant} | {k}/{args.n}{note} | {_fmt(tpr, '.3f')} "
              f"| {_fmt(eps, '.2e')} | {_fmt(vol, '.2e')} | {_fmt(valid, '.1f')} "
              f"| {_fmt(passed, '.1f')} |")


if __name__ == "__main__":
    main()
