"""What the augmentation commands share: rich progress bars, the per-unit summary table, and
running units of work (``dexaug batch``, ``augment --ray``) locally or on Ray."""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from dexaug.commands.argtypes import count
from dexaug.commands.options import augment_options

if TYPE_CHECKING:
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.summary import DemoSummary
    from dexaug.scale.units import Unit

__all__ = ["progress_bars", "ray_args", "ray_options", "run_units", "stage_ticker", "summary_table"]


def progress_bars(console: Console) -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), console=console, transient=False)


def stage_ticker(bar: Progress) -> Callable[[str, int, int], None]:
    """A pipeline progress callback that keeps one bar per stage (workspace, fsg, …)."""
    tasks: dict[str, int] = {}

    def tick(stage: str, done: int, total: int) -> None:
        if stage not in tasks:
            tasks[stage] = bar.add_task(stage, total=total)
        bar.update(tasks[stage], completed=done, total=total)

    return tick


def ray_args(p: argparse.ArgumentParser) -> None:
    """``--ray [ADDRESS]``, ``--ray-cpus``, ``--chunk``: where and how units run on Ray."""
    from dexaug.scale.ray_cluster import LOCAL

    p.add_argument("--ray", nargs="?", const=LOCAL, default=None, metavar="ADDRESS",
                   help="run on Ray (pip install 'dexaug[ray]'): alone, start a local cluster "
                   "whose servers listen on loopback (127.0.0.1) only, no dashboard; with ADDRESS "
                   "(host:port of a running cluster's GCS, ray://host:port or auto), connect "
                   "there: your choice, and Ray's own token authentication and network setup "
                   "apply (dexaug must be installed on its nodes). Each demo's FSG is one task "
                   "with --workers processes (default 1 with --ray), its validation spreads "
                   "over the cluster in --chunk tasks, and this process writes every result. "
                   "Same datasets as without --ray for the same --seed and --workers. "
                   "Default: the local process pool")
    p.add_argument("--ray-cpus", type=count, default=None, metavar="N",
                   help="--ray without ADDRESS: worker CPUs of the local cluster (default: all "
                   "cores)")
    p.add_argument("--chunk", type=count, default=32, metavar="N",
                   help="--ray: grasps per validation task (default %(default)s)")


def ray_options(args: argparse.Namespace) -> AugmentOptions:
    """``augment_options`` for this run: with ``--ray``, ``--workers`` is the FSG processes of
    one task (default 1, so a task holds one CPU), not all cores."""
    opts = augment_options(args)
    return dataclasses.replace(opts, workers=args.workers or 1) if args.ray is not None else opts


def run_units(units: Sequence[Unit], args: argparse.Namespace, console: Console, bar: Progress,
              ) -> tuple[list[DemoSummary], int]:
    """Run ``units`` into ``args.out``: one after another on the local pool, or with ``--ray``
    on the (already connected) cluster; a line per unit, failures in red. Returns the summaries
    and the number of units that failed."""
    from dexaug.scale.ray_jobs import Outcome, run_on_ray
    from dexaug.scale.units import run_local
    from sim.errors import DexaugError

    if args.ray is not None:
        outcomes = run_on_ray(units, args.out, chunk=args.chunk, force=args.force,
                              progress=stage_ticker(bar))
    else:
        outcomes = []
        overall = bar.add_task("units", total=len(units))
        for unit in units:
            try:
                summary = run_local(unit, args.out, progress=stage_ticker(bar), force=args.force)
                outcomes.append(Outcome(unit, summary))
            except DexaugError as exc:
                outcomes.append(Outcome(unit, error=str(exc)))
            bar.advance(overall)
    rows = []
    for o in outcomes:
        if o.summary is None:
            console.print(f"{o.unit.id}: {o.error}", style="red", highlight=False)
            continue
        s = o.summary
        rows.append(s)
        state = "skipped (done)" if s.skipped else "done"
        console.print(f"{s.demo_id}: {s.passed}/{s.generated} passed, {state}; report {s.report}")
    return rows, sum(o.summary is None for o in outcomes)


def summary_table(console: Console, rows: list[DemoSummary]) -> None:
    """One row per unit: counts, pass rate, FSG and validation seconds, throughput."""
    if not rows:
        return
    t = Table(title="augmentation")
    for col in ("demo", "object", "generated", "passed", "pass %", "FSG s", "validate s",
                "validated/min", "report"):
        t.add_column(col)
    for s in rows:
        rate = 100.0 * s.passed / s.generated if s.generated else 0.0
        t.add_row(s.demo_id, s.object, str(s.generated), str(s.passed), f"{rate:.0f}",
                  f"{s.timings_s.get('fsg', 0):.1f}", f"{s.timings_s.get('validate', 0):.1f}",
                  f"{s.validated_per_min:.0f}", str(s.report))
    console.print(t)
