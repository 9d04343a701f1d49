"""What the augmentation commands share: rich progress bars, the per-unit summary table,
running units of work (``dexaug batch``, ``augment --ray``) locally or on Ray, what a unit that
fell short says (:func:`report_shortfalls`), and the optional arm stage after each unit
(``--arm``)."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import logging
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeElapsedColumn
from rich.table import Table

from dexaug.commands.argtypes import count
from dexaug.commands.guards import error_hint
from dexaug.commands.options import augment_options, fell_short
from sim.errors import UsageError

if TYPE_CHECKING:
    from dexaug.pipeline.arm_stage import ArmStageOutcome
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.summary import DemoSummary
    from dexaug.scale.units import Unit

__all__ = ["ArmRow", "arm_args", "arm_placements", "arm_table", "fsg_rejections", "no_grasp_why",
           "progress_bars", "put_on_arm", "ray_args", "ray_options", "report_shortfalls",
           "run_units", "stage_ticker", "summary_table"]


def progress_bars(console: Console) -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), console=console, transient=False)


def stage_ticker(bar: Progress) -> Callable[[str, int, int], None]:
    """A pipeline progress callback that keeps one bar per stage (workspace, fsg, …)."""
    tasks: dict[str, TaskID] = {}

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
            console.print(error_hint(f"{o.unit.id}: {o.error}"), style="red", highlight=False)
            continue
        s = o.summary
        rows.append(s)
        state = "skipped (done)" if s.skipped else "done"
        console.print(f"{s.demo_id}: {s.passed}/{s.generated} passed, {state}; report {s.report}")
    return rows, sum(o.summary is None for o in outcomes)


# ------------------------------------------------------------------------------ shortfalls

#: what FSG counts but does not reject for: left out of the reasons a search found nothing
_NOT_REJECTIONS = ("candidates", "accepted", "accepted_open", "relaxed")


class _FsgCounts(logging.Handler):
    """Keeps the rejection counts of FSG's shortfall warning (``augment.fsg.run``: object name
    first, the counts last among its arguments), by object: the one place this process sees
    the counts of a search the pipeline ran (its result keeps only why it stopped)."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.by_object: dict[str, dict[str, int]] = {}

    def emit(self, record: logging.LogRecord) -> None:
        args = record.args if isinstance(record.args, tuple) else ()
        counts = next((a for a in reversed(args) if isinstance(a, dict) and "candidates" in a),
                      None)
        if counts is not None and args and isinstance(args[0], str):
            self.by_object[args[0]] = dict(counts)


@contextlib.contextmanager
def fsg_rejections() -> Iterator[dict[str, dict[str, int]]]:
    """While open, the rejection counts of every FSG search of this process that fell short,
    by object name (empty for searches run elsewhere, e.g. on Ray)."""
    handler = _FsgCounts()
    logger = logging.getLogger("augment.fsg.run")
    logger.addHandler(handler)
    try:
        yield handler.by_object
    finally:
        logger.removeHandler(handler)


def no_grasp_why(s: DemoSummary, counts: dict[str, int] | None, budget_s: float | None) -> str:
    """Why FSG found no grasp for ``s``, in words: where the search stopped and, when known,
    its main rejections (``counts``: FSG's, :func:`fsg_rejections`)."""
    fsg_s = s.timings_s.get("fsg")
    if s.fsg_stopped == "time budget":
        spent = f" after {fsg_s:.2f} s" if fsg_s is not None else ""
        of = f" of --budget {budget_s:g} s" if budget_s is not None else ""
        why = f"the search stopped at its time budget{spent}{of}"
    else:
        why = f"the search stopped: {s.fsg_stopped}"
    if counts is not None:
        sampled = int(counts.get("candidates", 0))
        top = sorted(((v, k) for k, v in counts.items() if v and k not in _NOT_REJECTIONS
                      and not k.startswith(("pairs_", "usable_"))), reverse=True)[:3]
        if not sampled:
            why += "; no candidate grasp was sampled (raise --budget)"
        elif top:
            why += (f"; of {sampled} candidates, rejected for " +
                    ", ".join(f"{k} {v}" for v, k in top))
    return why


def report_shortfalls(console: Console, summaries: Sequence[DemoSummary],
                      counts: dict[str, dict[str, int]], budget_s: float | None) -> int:
    """A yellow line for each unit that fell short of ``--n`` by more than half (one saying
    "FSG found no grasp for this demo: WHY" when it made none); returns how many fell short."""
    short = 0
    for s in summaries:
        if not fell_short(s.requested, s.generated):
            continue
        short += 1
        if s.generated == 0:
            console.print(f"{s.demo_id}: FSG found no grasp for this demo: "
                          f"{no_grasp_why(s, counts.get(s.object), budget_s)}",
                          style="yellow", highlight=False, soft_wrap=True)
        else:
            console.print(f"{s.demo_id}: fell short: {s.generated} of --n {s.requested} "
                          f"grasps, fewer than half (stopped: {s.fsg_stopped})",
                          style="yellow", highlight=False, soft_wrap=True)
    return short


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


# ------------------------------------------------------------------------------ the arm stage

def arm_args(p: argparse.ArgumentParser) -> None:
    """``--arm ARM``, ``--arm-placements N``: put each unit's grasps on an arm once written."""
    from dexaug.pipeline.arm_stage import DEFAULT_PLACEMENTS
    from sim.arm.config import arm_names

    p.add_argument("--arm", choices=arm_names(), default=None,
                   help="after each demo's result is written, put its passing grasps on this arm "
                   "at a table as `dexaug arm` does (carried grasps, placement seed 0) into "
                   "<result folder>/arm_<ARM>.h5; a file already made from the same dataset "
                   "is kept (--force redoes it). The augmentation's results and resume are "
                   "unchanged. Default: no arm stage")
    p.add_argument("--arm-placements", type=count, default=None, metavar="N",
                   help=f"--arm: random resting placements of the object on the table; "
                   f"default {DEFAULT_PLACEMENTS}")


def arm_placements(args: argparse.Namespace) -> int | None:
    """The arm stage's placements, None without ``--arm``; ``--arm-placements`` alone is a
    mistake (it would silently do nothing), refused before any work."""
    from dexaug.pipeline.arm_stage import DEFAULT_PLACEMENTS

    if args.arm is None:
        if args.arm_placements is not None:
            raise UsageError("--arm-placements needs --arm ARM")
        return None
    return args.arm_placements or DEFAULT_PLACEMENTS


@dataclasses.dataclass(frozen=True)
class ArmRow:
    """One unit's arm stage, for the final table."""

    unit: str
    outcome: ArmStageOutcome


def _arm_line(unit: str, o: ArmStageOutcome) -> str:
    """``demo: on ur5e, 3 of 12 (placement, grasp) pairs held (25.0 %); failures table 9;
    wrote …/arm_ur5e.h5`` (or the reason it was skipped)."""
    if o.file is None:
        return f"{unit}: on {o.arm}, skipped ({o.skipped})"
    f = o.file
    share = "–" if f.pass_share is None else f"{100 * f.pass_share:.1f} %"
    done = "already made" if o.skipped else f"wrote {o.path}"
    return (f"{unit}: on {o.arm}, {f.passed} of {f.pairs} (placement, grasp) pairs held "
            f"({share}); failures {f.failures_text()}; {done}")


def put_on_arm(summaries: Sequence[DemoSummary], args: argparse.Namespace, console: Console,
               bar: Progress) -> tuple[list[ArmRow], int]:
    """The arm stage of each finished unit (``--arm``; nothing without it), with a progress bar
    and a line per unit; a unit whose stage fails is printed in red and the others go on.
    Returns the rows and the number that failed."""
    from dexaug.pipeline.arm_stage import run_arm_stage
    from sim.errors import DexaugError

    placements = arm_placements(args)
    rows: list[ArmRow] = []
    failed = 0
    if placements is None:
        return rows, failed
    for s in summaries:
        try:
            outcome = run_arm_stage(s.dataset, args.arm, placements=placements,
                                    progress=stage_ticker(bar), force=args.force)
        except DexaugError as exc:
            failed += 1
            console.print(f"{s.demo_id}: arm stage on {args.arm} failed: {exc}", style="red",
                          highlight=False, markup=False)
            continue
        rows.append(ArmRow(s.demo_id, outcome))
        console.print(_arm_line(s.demo_id, outcome), highlight=False, markup=False)
    return rows, failed


def arm_table(console: Console, rows: Sequence[ArmRow]) -> None:
    """One row per unit's arm file: pairs, passed, pass share, failures by reason."""
    if not rows:
        return
    t = Table(title="grasps on an arm")
    for col in ("demo", "arm", "placements", "pairs", "passed", "pass %", "failures", "file"):
        t.add_column(col)
    for r in rows:
        f = r.outcome.file
        if f is None:
            t.add_row(r.unit, r.outcome.arm, "", "", "", "", f"skipped: {r.outcome.skipped}", "")
            continue
        share = "–" if f.pass_share is None else f"{100 * f.pass_share:.1f}"
        t.add_row(r.unit, f.arm, str(f.placements), str(f.pairs), str(f.passed), share,
                  f.failures_text(), str(r.outcome.path))
    console.print(t)
