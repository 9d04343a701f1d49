"""Subcommand ``arm``: a dataset's hand-only grasps on an arm at a table (paper §5.3).

The work is :mod:`dexaug.pipeline.arm_run` (placements, IK, approach, simulation:
:mod:`sim.arm`); this module parses, shows progress and prints the per-object summary.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.table import Table

from dexaug.commands.argtypes import count
from dexaug.commands.guards import dataset_file, require_writable
from dexaug.commands.registry import command
from dexaug.commands.running import progress_bars, stage_ticker

__all__ = ["arm_cmd"]


def _arm_args(p: argparse.ArgumentParser) -> None:
    from dexaug.pipeline.arm_run import GRASP_SOURCES
    from sim.arm.config import arm_names
    from sim.validate.batch import default_workers

    p.add_argument("dataset", type=dataset_file, help="a grasps.h5 written by augment/generate "
                   "(its passing grasps are used)")
    p.add_argument("--arm", choices=arm_names(), default="ur5e",
                   help="arm config (configs/arms/<arm>/); default %(default)s")
    p.add_argument("--placements", type=count, default=20,
                   help="random resting placements of each object on the table; default %(default)s")
    p.add_argument("--seed", type=int, default=0, help="placement seed; default %(default)s")
    p.add_argument("--object", help="only this object's table (default: every object)")
    p.add_argument("--max-grasps", type=count, default=None, metavar="N",
                   help="at most the first N grasps of each table; as it lies, N new grasps "
                   "per resting pose (default: all / as many as the table holds)")
    p.add_argument("--grasps", choices=GRASP_SOURCES, default="carried",
                   help="carried: the dataset's grasps carried to each placement (the paper's "
                   "§5.3); as-it-lies: grasps made for each resting pose with the dataset's "
                   "demonstration (FSG with that pose's table, lift-drop hanging as it hangs); "
                   "default %(default)s")
    p.add_argument("--workers", type=count, default=default_workers(),
                   help="processes making and validating grasps as they lie; default %(default)s")
    p.add_argument("--out", type=Path, default=Path("arm_grasps.h5"),
                   help="arm dataset to write (replaced atomically); default %(default)s")
    p.add_argument("--report", type=Path, default=None, metavar="HTML",
                   help="also write an HTML report (summary per object and images of held "
                   "grasps, the paper's Fig. 12) here; default: none")
    p.add_argument("--gallery", type=int, default=4,
                   help="images of held grasps per object in the report; default %(default)s")


@command("arm", _arm_args)
def arm_cmd(args: argparse.Namespace, console: Console) -> int:
    """Put a dataset's grasps on an arm: placements on a table, IK, approach, lift in MuJoCo.

    For each object the hand (on the arm's flange, configs/hands/<hand>/hand.toml [mount]) meets
    the object at --placements resting poses drawn on the table (physically found, weighted by
    how often a drop reaches them), settled in MuJoCo; each grasp is carried to the settled
    pose (or, with --grasps as-it-lies, grasps are made for each resting pose), dropped if the
    hand would be in the table, solved with whole-body IK (mink; arm joints, the grasp's
    finger joints fixed, table collision limits), approached from 10 cm
    behind the palm, checked for collisions along the way, then simulated: the arm follows the
    trajectory, the fingers close, the arm lifts 10 cm and holds. Every (placement, grasp)
    gets a verdict (passed, or table / unreachable / collision / pushed / dropped / slipped)
    with its arm trajectory and whole-body configuration in --out.
    """
    from dexaug.pipeline.arm_run import run_arm

    require_writable(args.out, "--out")
    if args.report is not None:
        require_writable(args.report, "--report")
    with progress_bars(console) as bar:
        tick = stage_ticker(bar)
        summaries = run_arm(args.dataset, args.arm, args.out, placements=args.placements,
                            seed=args.seed, object_name=args.object, max_grasps=args.max_grasps,
                            progress=lambda name, done, total: tick(f"{args.arm} {name}", done, total),
                            grasps_from=args.grasps, workers=args.workers,
                            report=args.report, gallery=args.gallery)
    t = Table(title=f"grasps on {args.arm}")
    for col in ("object", "grasps", "placement × grasp", "passed", "pass %", "failures",
                "s per planned grasp"):
        t.add_column(col)
    for s in summaries:
        failures = ", ".join(f"{k} {v}" for k, v in sorted(s.failures.items()))
        t.add_row(s.object, str(s.grasps), str(s.pairs), str(s.passed),
                  f"{100 * s.passed / s.pairs:.1f}", failures, f"{s.seconds_per_planned:.2f}")
    console.print(t)
    console.print(f"wrote {args.out}" + (f" and {args.report}" if args.report else ""))
    return 0
