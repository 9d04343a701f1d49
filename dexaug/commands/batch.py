"""``dexaug batch``: augment many sessions, demo files and objects in one run, locally or on Ray."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from rich.console import Console

from dexaug.commands.argtypes import int_at_least
from dexaug.commands.guards import error_hint, object_name, require_writable
from dexaug.commands.options import SHORT_STATUS, generation_args, hand_arg, warn_if_unreachable
from dexaug.commands.registry import command
from dexaug.commands.running import (
    fsg_rejections,
    progress_bars,
    ray_args,
    ray_options,
    report_shortfalls,
    run_units,
    summary_table,
)
from sim.errors import UsageError


def _batch_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("inputs", nargs="*", type=Path, metavar="SESSION",
                   help="recorded sessions (.mcap: every demo in them) or demo files (.json)")
    p.add_argument("--objects", nargs="+", default=[], metavar="OBJ", type=object_name,
                   help="also generate for these objects without a demo, on the hand's manual "
                   "workspace (paper Table 1), one folder <out>/<OBJ>@manual each, no report")
    hand_arg(p, "hand config of --objects (a demo uses its own hand)")
    p.add_argument("--out", type=Path, default=Path("datasets"),
                   help="output folder: one sub-folder per demo / object (default ./datasets)")
    p.add_argument("--force", action="store_true", help="redo units that are already finished")
    p.add_argument("--gallery", type=int_at_least(0), default=6,
                   help="grasps rendered in each demo's report (0: no report)")
    generation_args(p)
    ray_args(p)


@command("batch", _batch_args)
def batch_cmd(args: argparse.Namespace, console: Console) -> int:
    """Augment many demos and objects: every demo of the SESSIONs and demo files, and each --objects.

    Each unit (a demo, or an object on the manual workspace) gets its folder under --out with
    grasps.h5 (validated grasps, rejected ones in a side table), summary.json and, for a demo,
    report.html, written atomically by this process; re-running skips finished units. Without
    --ray the units run one after another on the local process pool (as dexaug augment); with
    --ray they run as Ray tasks (FSG per unit, validation in chunks over the cluster), a task
    whose worker dies is retried, and the datasets are the same as the local path's for the
    same --seed and --workers (FSG's output depends on its worker count). An input or unit
    that fails is reported with the reason and the others go on (exit status 1 if any failed;
    else 3 if a unit made fewer than half of --n grasps, its results still written).
    """
    from dexaug.scale.ray_cluster import ray_cluster
    from dexaug.scale.units import gather_units

    if not args.inputs and not args.objects:
        raise UsageError("give sessions or demo files to augment, or --objects OBJ ...")
    require_writable(args.out, "--out", folder=True)
    opts = ray_options(args)
    warn_if_unreachable(console, opts.n, opts.time_budget_s, opts.workers)
    units, errors = gather_units(args.inputs, opts, args.objects, args.hand, args.finger_iteration)
    for text in errors:
        console.print(error_hint(text), style="red", highlight=False)
    with contextlib.ExitStack() as stack:
        counts = stack.enter_context(fsg_rejections())
        if args.ray is not None:
            stack.enter_context(ray_cluster(args.ray, num_cpus=args.ray_cpus))
        with progress_bars(console) as bar:
            rows, failed = run_units(units, args, console, bar)
        short = report_shortfalls(console, rows, counts, opts.time_budget_s)
    summary_table(console, rows)
    return 1 if failed or errors else SHORT_STATUS if short else 0
