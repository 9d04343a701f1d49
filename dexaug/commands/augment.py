"""Subcommands of the augmentation half: ``augment``, ``rerecord`` (``generate`` has its own
module, :mod:`dexaug.commands.generate`).

Each parses its arguments, calls ``augment`` / ``teleop``, and reports with rich progress bars
and tables; libraries never print.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console

from dexaug.commands.argtypes import count, int_at_least, positive
from dexaug.commands.guards import error_hint, object_name, require_writable
from dexaug.commands.options import (
    SHORT_STATUS,
    budget_arg,
    generation_args,
    warn_if_unreachable,
    workers_arg,
)
from dexaug.commands.registry import command
from dexaug.commands.running import (
    arm_args,
    arm_placements,
    arm_table,
    fsg_rejections,
    progress_bars,
    put_on_arm,
    ray_args,
    ray_options,
    report_shortfalls,
    run_units,
    stage_ticker,
    summary_table,
)
from dexaug.commands.workers import stop_workers
from sim.errors import DexaugError, UsageError

if TYPE_CHECKING:
    from dexaug.pipeline.summary import DemoSummary

log = logging.getLogger(__name__)


def _augment_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("inputs", nargs="*", type=Path, metavar="SESSION",
                   help="recorded sessions (.mcap) or demo files (.json)")
    p.add_argument("--out", type=Path, default=Path("datasets"),
                   help="output folder: one sub-folder per demo (default ./datasets)")
    p.add_argument("--watch", type=Path, metavar="DIR", help="keep watching DIR and augment "
                   "each new session once its recorder has closed it")
    p.add_argument("--poll", type=positive, default=2.0, help="--watch: seconds between scans")
    p.add_argument("--force", action="store_true", help="redo demos that are already finished")
    p.add_argument("--gallery", type=int_at_least(0), default=6,
                   help="grasps rendered in each report (0: no report)")
    generation_args(p)
    ray_args(p)
    arm_args(p)


@command("augment", _augment_args)
def augment_cmd(args: argparse.Namespace, console: Console) -> int:
    """Augment recorded demonstrations: session → demo → AutoWS → FSG → validation → dataset.

    Each grasp demonstration found in a session (stable multi-fingertip contact or a
    grasp_mark) is expanded into --n grasps; every grasp is validated in MuJoCo; per demo the
    output folder gets grasps.h5 (validated grasps, rejected ones in a side table),
    report.html and summary.json. Re-running skips finished demos; --watch DIR augments new
    sessions as they are recorded. A session without a usable grasp, object or hand is
    reported with the reason and the others go on (exit status 1 if any failed; else 3 if a
    demo's FSG made fewer than half of --n grasps, e.g. none: "FSG found no grasp for this
    demo: WHY", its dataset, report and summary still written). --ray runs
    the demos on a Ray cluster instead of the local process pool (see dexaug batch for many
    sessions and objects at once). --arm ARM then puts each demo's passing grasps on that arm
    at a table (as dexaug arm does) into arm_<ARM>.h5 beside them.
    """
    from dexaug.pipeline.run import augment_demo, augment_session
    from dexaug.scale.ray_cluster import ray_cluster
    from dexaug.scale.units import gather_units
    from sim.demo import DemoError, load_demo

    if not args.inputs and not args.watch:
        raise UsageError("give sessions to augment or --watch DIR")
    arm_placements(args)          # --arm-placements without --arm: refused before any work
    require_writable(args.out, "--out", folder=True)
    opts = ray_options(args)
    warn_if_unreachable(console, opts.n, opts.time_budget_s, opts.workers)
    failed = short = 0
    rows, arm_rows = [], []
    with contextlib.ExitStack() as stack, progress_bars(console) as bar:
        counts = stack.enter_context(fsg_rejections())
        if args.ray is not None:
            stack.enter_context(ray_cluster(args.ray, num_cpus=args.ray_cpus))

        def augment(path: Path) -> list[DemoSummary]:
            """``path``'s demos augmented (a line each); a failure is printed and counted."""
            nonlocal failed, short
            if args.ray is not None:
                units, errors = gather_units([path], opts)
                for text in errors:
                    console.print(error_hint(text), style="red", highlight=False)
                done, bad = run_units(units, args, console, bar)
                failed += len(errors) + bad
                short += report_shortfalls(console, done, counts, opts.time_budget_s)
                return done
            tick = stage_ticker(bar)
            try:
                if path.suffix == ".json":
                    summaries = [augment_demo(load_demo(path), args.out, opts, progress=tick,
                                              force=args.force)]
                else:
                    summaries = augment_session(path, args.out, opts, progress=tick,
                                                force=args.force)
            except (DemoError, DexaugError) as exc:
                failed += 1
                text = str(exc) if str(path) in str(exc) else f"{path}: {exc}"
                console.print(error_hint(text), style="red", highlight=False)
                return []
            for s in summaries:
                state = "skipped (done)" if s.skipped else "done"
                console.print(f"{s.demo_id}: {s.passed}/{s.generated} passed, {state}; "
                              f"report {s.report}")
            short += report_shortfalls(console, summaries, counts, opts.time_budget_s)
            return summaries

        def one(path: Path) -> None:
            nonlocal failed
            summaries = augment(path)
            rows.extend(summaries)
            done, bad = put_on_arm(summaries, args, console, bar)
            arm_rows.extend(done)
            failed += bad

        for path in args.inputs:
            one(path)
        if args.watch:
            _watch(args.watch, args.poll, one, console)
    summary_table(console, rows)
    arm_table(console, arm_rows)
    return 1 if failed else SHORT_STATUS if short else 0


def _watch(folder: Path, poll_s: float, handle: Callable[[Path], None],
           console: Console) -> None:
    """Augment each ``*.mcap`` in ``folder`` once its recorder closed it (a file still being
    written reads as truncated), until Ctrl-C."""
    from teleop.record.session import SessionError, open_session

    seen: set[Path] = set()
    incomplete: dict[Path, tuple[int, int]] = {}   # (size, mtime) when last found unfinished
    console.print(f"watching {folder} for finished sessions (Ctrl-C to stop)")
    try:
        while True:
            for path in sorted(folder.glob("*.mcap")):
                if path in seen:
                    continue
                st = path.stat()
                if incomplete.get(path) == (st.st_size, st.st_mtime_ns):
                    continue              # unchanged since it read as unfinished: no re-scan
                try:
                    unfinished = open_session(path).truncated    # still recording
                except SessionError:
                    unfinished = True
                if unfinished:
                    incomplete[path] = (st.st_size, st.st_mtime_ns)
                    continue
                seen.add(path)
                incomplete.pop(path, None)
                handle(path)
            time.sleep(poll_s)
    except KeyboardInterrupt:
        stop_workers()   # an augmentation under way: its FSG workers would run to the budget
        console.print("stopped watching")


def _rerecord_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("src", type=Path, help="a session with raw /hands input (e.g. from synth)")
    p.add_argument("out", type=Path, help="the full session to write")
    p.add_argument("--hand", help="hand config (default: the session's)")
    p.add_argument("--object", type=object_name, help="object (default: the session's)")
    p.add_argument("--object-mode", choices=("demo", "free"),
                   help="demo: the object settles on the table and is held while the hand "
                   "grasps; free: it can be lifted (default: the session's; free for a session "
                   "that records none)")


@command("rerecord", _rerecord_args)
def rerecord_cmd(args: argparse.Namespace, console: Console) -> int:
    """Replay a session's raw hand input through the bridge and record a full session.

    The bridge runs on its own loopback zenoh peer in deterministic mode (every frame, fixed
    physics steps), so a raw-input session (a synthetic operator's, an older recording) gains
    simulated state and contacts; grasp marks are re-issued at the same frames.
    """
    from teleop.bridge.rerecord import rerecord

    require_writable(args.out, "OUT")
    out = rerecord(args.src, args.out, hand=args.hand, object_name=args.object,
                   object_mode=args.object_mode)
    console.print(f"wrote {out}")
    return 0


def _bench_args(p: argparse.ArgumentParser) -> None:
    from dexaug.bench_paper import OBJECTS, VARIANTS

    p.add_argument("suite", choices=("paper",), help="paper: the reference paper's Tables 2, 3")
    p.add_argument("--n", type=count, default=20, help="grasps requested per row")
    budget_arg(p, 30.0, per=" of each row")
    p.add_argument("--objects", nargs="*", default=list(OBJECTS), type=object_name,
                   help=f"objects (default: the paper's {', '.join(OBJECTS)})")
    p.add_argument("--methods", nargs="*", default=list(VARIANTS), choices=list(VARIANTS),
                   help="the paper's method variants (default: all)")
    p.add_argument("--workspaces", nargs="*", default=["manual", "demo"],
                   choices=["manual", "demo"], help="workspace rows (default: both)")
    workers_arg(p)
    p.add_argument("--no-six-dir", action="store_true", help="skip the six-dir validation")
    p.add_argument("--out", type=Path, help="also write the Markdown table to this file")


@command("bench", _bench_args)
def bench_cmd(args: argparse.Namespace, console: Console) -> int:
    """Benchmarks. `dexaug bench paper` measures the rows of the paper's Tables 2 and 3.

    For 004, 005, 024, 043 and 062 with the Shadow Hand, without and with the committed
    demonstrations (recordings/demos/), for FSG, FSG+Aff, FSG+Aff-FinIter and FSG+Aff+LinkPen:
    time per result, GWS ε / volume and valid-ε % from simulated contacts, plus lift-drop,
    DexGraspBench (dgb) and six-dir pass rates, penetration and diversity; prints a Markdown
    table with the paper's figures beside ours.
    """
    from dexaug.bench_paper import markdown, measure, paper_figures
    from sim.io import write_bytes_atomic
    from sim.validate.batch import default_workers

    if args.out:
        require_writable(args.out, "--out")
    rows_total = len(args.objects) * len(args.methods) * len(args.workspaces)
    with progress_bars(console) as bar:
        task = bar.add_task("rows", total=rows_total)
        rows = measure(args.objects, args.methods, args.workspaces, n=args.n,
                       budget_s=args.budget, workers=args.workers or default_workers(),
                       six_dir=not args.no_six_dir,
                       on_row=lambda r: bar.advance(task))
    table = markdown(rows, paper_figures())
    console.print(table, markup=False, highlight=False, soft_wrap=True)
    if args.out:
        write_bytes_atomic(args.out, (table + "\n").encode())
        console.print(f"wrote {args.out}")
    return 0
