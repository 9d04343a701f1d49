"""``dexaug generate``: grasps of one object (FSG fingertip grasps, power grasps, or both),
validated in MuJoCo, into an HDF5 dataset.

Parses its arguments, calls ``augment`` and ``sim.validate``, and reports with rich progress
bars; libraries never print.
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.markup import escape

from dexaug.commands.argtypes import int_at_least
from dexaug.commands.auto_mode import AutoChoice, ModeRun, run_auto
from dexaug.commands.guards import object_name, require_new_or_dataset, require_writable
from dexaug.commands.options import (
    SHORT_STATUS,
    backend_of,
    fell_short,
    generation_args,
    hand_arg,
    warn_if_unreachable,
)
from dexaug.commands.registry import command
from dexaug.commands.running import (
    progress_bars,
)
from sim.errors import DexaugError, UsageError

if TYPE_CHECKING:
    from rich.progress import Progress

    from augment.fsg.result import FsgResult
    from sim.demo import Demo
    from sim.hand.model import Hand
    from sim.validate.result import ValidationResult
    from sim.world.objects import ObjectAsset

log = logging.getLogger(__name__)


def _generate_args(p: argparse.ArgumentParser) -> None:
    hand_arg(p)
    p.add_argument("--object", required=True, type=object_name,
                   help="object name (YCB id/name or primitive)")
    p.add_argument("--demo", help="centre the workspace on a demonstration: a demo .json, a "
                   "session .mcap, or a reference grasp name")
    p.add_argument("--fingers", type=int_at_least(2),
                   help="use at most this many fingers (priority order; FSG needs 2)")
    p.add_argument("--no-aff", action="store_true", help="sample the whole object cloud, not "
                   "its graspable part (the paper's plain FSG)")
    p.add_argument("--out", type=Path, default=Path("grasps.h5"), help="HDF5 dataset to write; "
                   "an existing one with grasps is refused unless --append; default %(default)s")
    p.add_argument("--append", action="store_true", help="add to an existing --out (rows that "
                   "exactly repeat its grasps are refused); default: off")
    p.add_argument("--mode", choices=("fingertip", "power", "auto"), default=None,
                   help="fingertip: FSG (paper §4); power: palm and whole fingers around the "
                   "object, for objects fingertips cannot lift (augment.power; no --demo, "
                   "--fingers or --table); auto: a validated pilot of [power] auto_pilot grasps "
                   "of each mode, then the rest in the one that passes more often (power must "
                   "beat fingertip by [power] auto_margin; fingertip only with --demo, "
                   "--fingers or --table, which ask for fingertips); default: auto, or "
                   "fingertip with --validate none (auto decides from the validation)")
    generation_args(p)


@command("generate", _generate_args)
def generate_cmd(args: argparse.Namespace, console: Console) -> int:
    """Generate grasps of one object with FSG (paper §4) and write them to an HDF5 dataset.

    The workspace is the hand's manual one (paper Table 1), or centred on --demo (and then only
    the fingers that touched in the demo are used, as in the paper's augmentation). Every grasp
    is validated in MuJoCo (--validate); passing grasps go to the main table, failing ones to
    the side table "rejected" with their reason. A shortfall (fewer grasps than --n within
    --budget, which each run gets) is reported, never a hang. --mode power makes whole-hand
    grasps instead (augment.power: palm on the object, every finger closed onto it in
    simulation); --mode auto, the default unless --validate none (issue #54: a user who names
    only the object gets the best mode), pilots both modes and makes the rest of the grasps in
    the one that holds more often (:mod:`dexaug.commands.auto_mode`; table attributes
    ``modes_run`` and ``auto_pilots``); it says which.
    Exit status 3: the dataset was written with fewer than half of --n grasps; 2: an input or
    --out that cannot be used (checked before any work).
    """
    from augment import dataset
    from dexaug.pipeline.demos import resolve_demo
    from sim.hand.model import Hand
    from sim.validate.batch import default_workers
    from sim.world.objects import load_object

    if args.mode is None:   # the best a user can get unasked: auto needs the validation
        args.mode = "fingertip" if args.validate == "none" else "auto"
    if args.mode == "power" and (args.demo or args.fingers or args.table is not None):
        raise UsageError("--mode power places the whole hand: it takes no --demo, --fingers or "
                         "--table")
    require_writable(args.out, "--out")
    require_new_or_dataset(args.out, "--out")
    workers = args.workers or default_workers()
    warn_if_unreachable(console, args.n, args.budget, workers)
    if not args.append and (held := dataset.existing_rows(args.out)):
        raise DexaugError(f"{args.out} already holds {held} grasps: pass --append to add to it, "
                          f"or choose another --out")
    hand = Hand.load(args.hand)
    obj = load_object(args.object)
    backend = backend_of(args)
    demo = resolve_demo(args.demo, hand.name) if args.demo else None
    if demo is not None and demo.object != obj.name:
        console.print(f"note: demo {demo.id} grasps {demo.object}, generating for {obj.name}",
                      style="yellow")
    if args.mode == "auto" and args.validate == "none":
        raise UsageError("--mode auto decides from the fingertip grasps' validation: it needs "
                         "--validate")
    with progress_bars(console) as bar:
        def run(mode: str, n: int, seed: int) -> ModeRun:
            return (mode, *_generate_and_validate(args, mode, hand, obj, demo, workers, backend,
                                                  bar, n, seed))

        runs, choice = _mode_runs(args, hand, run)
    _report_choice(console, args, choice)
    grasps = [g for _, res, _ in runs for g in res.grasps]
    validated = [r for _, _, r in runs if r is not None]   # every run, or none (--validate)
    results = [x for r in validated for x in r] if len(validated) == len(runs) else None
    table = dataset.from_fsg(grasps, hand.joint_names, hand.finger_names, results,
                             demo_id=demo.id if demo else "",
                             attrs=_generate_provenance(args, hand.name, backend, demo,
                                                        [m for m, _, _ in runs], choice),
                             split_rejected=results is not None)
    dataset.append(args.out, {obj.name: table})
    for mode, res, res_results in runs:
        _report_run(console, args, mode, res, res_results)
    console.print(f"wrote {args.out}")
    if fell_short(args.n, len(grasps)):
        console.print(f"fell short: {len(grasps)} of --n {args.n} grasps, fewer than half "
                      f"(exit status {SHORT_STATUS})", style="yellow")
        return SHORT_STATUS
    return 0


def _generate_and_validate(args: argparse.Namespace, mode: str, hand: Hand, obj: ObjectAsset,
                           demo: Demo | None, workers: int, backend: str, bar: Progress,
                           n: int, seed: int) -> tuple[FsgResult, list[ValidationResult] | None]:
    """``n`` grasps of one mode (``"fingertip"``: FSG; ``"power"``) from ``seed`` and, unless
    --validate none, their validation, each with its progress bar."""
    from sim.validate.batch import validate_many

    task = bar.add_task(escape(f"{'power' if mode == 'power' else 'FSG'} {obj.name}"), total=n)
    res = (_power(args, hand, obj.name, workers, n, seed, lambda k: bar.update(task, completed=k))
           if mode == "power" else _fsg(args, hand, obj, demo, workers, n, seed,
                                        lambda k: bar.update(task, completed=k)))
    bar.update(task, completed=len(res.grasps))
    if args.validate == "none" or not res.grasps:
        return res, None if args.validate == "none" else []
    vt = bar.add_task(f"validate {args.validate}", total=len(res.grasps))
    return res, validate_many(hand.name, obj.name, [g.grasp for g in res.grasps],
                              args.validate, workers=workers,
                              squeeze_convention=args.squeeze_convention,
                              progress=lambda k: bar.update(vt, completed=k), backend=backend)


def _mode_runs(args: argparse.Namespace, hand: Hand,
               run: Callable[[str, int, int], ModeRun]) -> tuple[list[ModeRun], AutoChoice | None]:
    """The runs --mode asks for: --n grasps of power or fingertip; for auto, its pilots and the
    chosen mode's grasps (:func:`dexaug.commands.auto_mode.run_auto`), fingertip alone when
    --demo, --fingers or --table ask for fingertips."""
    from augment.power import load_power_params

    asked = bool(args.demo) or bool(args.fingers) or args.table is not None
    if args.mode == "auto" and not asked:
        params = load_power_params(hand_file=hand.config.file)
        return run_auto(run, args.n, args.seed, params.auto_pilot, params.auto_margin)
    return [run("power" if args.mode == "power" else "fingertip", args.n, args.seed)], None


def _report_choice(console: Console, args: argparse.Namespace, choice: AutoChoice | None) -> None:
    """--mode auto's pilots and choice, and the pilot it does not write."""
    if choice is None:
        if args.mode == "auto":
            console.print("auto: fingertip only (--demo, --fingers or --table ask for fingertips)")
        return
    console.print(choice.summary())
    for mode, (made, _) in choice.pilots.items():
        if mode != choice.mode and made:
            console.print(f"auto: the {mode} pilot's {made} grasps are not written")


def _report_run(console: Console, args: argparse.Namespace, mode: str, res: FsgResult,
                results: list[ValidationResult] | None) -> None:
    """What one mode made: grasps, time, shortfall and its reasons, how many passed."""
    per = res.elapsed_s / len(res.grasps) if res.grasps else float("nan")
    label = "power" if mode == "power" else "FSG"
    console.print(f"{label}: {len(res.grasps)}/{args.n} grasps in {res.elapsed_s:.2f} s "
                  f"({per:.3f} s/grasp, stopped: {res.stopped}; finger sets "
                  f"{[len(s) for s in res.finger_sets]})")
    if res.shortfall:
        console.print(f"shortfall: {res.shortfall} grasps ({res.stopped}); rejections "
                      f"{ {k: v for k, v in res.stats.items() if not k.startswith(('pairs', 'usable'))} }",
                      style="yellow")
    if results is not None:
        console.print(f"{args.validate} ({label}): {sum(r.passed for r in results)} of "
                      f"{len(results)} passed")


def _fsg(args: argparse.Namespace, hand: Hand, obj: ObjectAsset, demo: Demo | None,
         workers: int, n: int, seed: int, progress: Callable[[int], None]) -> FsgResult:
    """FSG on the hand's manual workspace, or one centred on ``demo``."""
    from augment.autows.build import build_workspace
    from augment.autows.seed import DemoSeed
    from augment.object_cloud import object_cloud
    from dexaug.pipeline.run import demo_fingers, demo_table, generate_grasps

    ws = build_workspace(hand, demo=DemoSeed.from_demo(demo) if demo else None)
    return generate_grasps(hand, object_cloud(obj), ws, n=n, fingers=args.fingers,
                           finger_names=demo_fingers(demo) if demo else None,
                           table=demo_table(demo, args.table), use_affordance=not args.no_aff,
                           finger_iteration=(args.finger_iteration
                                             if args.finger_iteration is not None
                                             else demo is None),
                           link_penetration=not args.no_linkpen, seed=seed,
                           time_budget_s=args.budget, workers=workers,
                           hold_protocol=_hold_protocol(args), progress=progress)


def _power(args: argparse.Namespace, hand: Hand, obj: str, workers: int, n: int, seed: int,
           progress: Callable[[int], None]) -> FsgResult:
    """Power grasps (:mod:`augment.power`), kept when the actuators can hold the loads of
    --validate's protocol (lift-drop's when validation is off)."""
    from augment.power import generate_power

    return generate_power(hand, obj, n=n, seed=seed, workers=workers,
                          time_budget_s=args.budget, protocol=_hold_protocol(args),
                          use_affordance=not args.no_aff, progress=progress)


def _hold_protocol(args: argparse.Namespace) -> str:
    return args.validate if args.validate != "none" else "lift-drop"


def _generate_provenance(args: argparse.Namespace, hand: str, backend: str,
                         demo: Demo | None, modes: list[str],
                         choice: AutoChoice | None) -> dict[str, object]:
    """What made a ``generate`` table: every option as given (JSON), the hand, protocol,
    seed and backend as their own attributes, and the demonstration itself (so ``dexaug arm
    --grasps as-it-lies`` can rebuild its workspace)."""
    from sim.demo import demo_to_json

    options = {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()
               if k not in ("handler",) and not callable(v)}
    return {"hand": hand, "seed": args.seed, "protocol": args.validate, "backend": backend,
            "mode": args.mode, "modes_run": " ".join(dict.fromkeys(modes)),
            "auto_pilots": choice.attrs() if choice is not None else "",
            "options": json.dumps(options, sort_keys=True, default=str),
            "demo_source": str(demo.source) if demo is not None else "",
            "demo": json.dumps(demo_to_json(demo)) if demo is not None else ""}
