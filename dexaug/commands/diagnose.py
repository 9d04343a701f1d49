"""Subcommand ``diagnose``: why a dataset's grasps failed, from a replay of each under lift-drop.

:func:`diagnose_dataset` is the job (also callable without the CLI parser); the physics is
:mod:`sim.validate.diagnose`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import Progress
from rich.table import Table
from rich.text import Text

from dexaug.commands.argtypes import int_at_least
from dexaug.commands.registry import command
from sim.errors import DexaugError

__all__ = ["diagnose", "diagnose_dataset"]


def _diagnose_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", type=Path, help="a grasps.h5 written by augment/generate")
    p.add_argument("--object", help="only this object's table (default: every object in the file)")
    p.add_argument("--n", type=int_at_least(1), default=20,
                   help="failing grasps replayed per object (from the rejected table); "
                        "default %(default)s")
    p.add_argument("--passing", type=int_at_least(0), default=5,
                   help="passing grasps replayed too, for comparison; default %(default)s")
    p.add_argument("--json", type=Path, help="write every grasp's findings and the summary as JSON")


def _grasps(table: Any, n: int) -> list[Any]:
    from sim.grasp import Grasp

    out = []
    for i in range(min(n, len(table) if table is not None else 0)):
        pose = table["palm_pose"][i]
        out.append(Grasp(pose[:3], pose[3:], table["hand_pose"][i]))
    return out


def _summary_table(name: str, summary: dict[str, Any]) -> Table:
    t = Table(title=f"{name}: {summary['grasps']} grasps replayed", show_header=True)
    t.add_column("finding")
    t.add_column("failing")
    t.add_column("passing")
    f, p = summary["failing"], summary["passing"]

    def num(x: float, fmt: str = ".2f") -> str:
        return "—" if x != x else format(x, fmt)

    t.add_row("verdicts", Text(json.dumps(summary["verdicts"])), "")
    t.add_row("slip mode (palm frame)", Text(json.dumps(summary["slip_modes"])), "")
    t.add_row("slip starts in", Text(json.dumps(summary["slip_onset_phase"])), "")
    t.add_row("friction use ft/(μ·fn), median", num(f["friction_use_median"]),
              num(p["friction_use_median"]))
    t.add_row("largest servo effort / limit, median", num(f["effort_max_median"]),
              num(p["effort_max_median"]))
    t.add_row("grasps with a servo at its limit", str(f["with_actuator_at_limit"]), "")
    t.add_row("grasps with a sliding contact", str(f["with_sliding_contact"]), "")
    t.add_row("total normal force (N), median", num(f["fn_total_median_n"], ".1f"),
              num(p["fn_total_median_n"], ".1f"))
    t.add_row("contact centroid → COM lever (mm), median", num(1e3 * f["lever_arm_median_m"], ".1f"),
              num(1e3 * p["lever_arm_median_m"], ".1f"))
    t.add_row("weight carried per finger, median", Text(json.dumps(f["support_median"])),
              Text(json.dumps(p["support_median"])))
    return t


def diagnose_dataset(path: Path, console: Console, *, object_name: str | None = None,
                     n: int = 20, passing: int = 5, json_path: Path | None = None) -> int:
    """Replay up to ``n`` failing and ``passing`` passing grasps per object of the dataset at
    ``path`` and print the findings; returns the exit code."""
    from augment import dataset
    from sim.hand.model import Hand
    from sim.io import write_bytes_atomic
    from sim.validate.diagnose import diagnose, summarise
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    tables = dataset.load(path)
    if object_name is not None:
        if object_name not in tables:
            raise DexaugError(f"{path}: no object {object_name!r}; it holds {sorted(tables)}")
        tables = {object_name: tables[object_name]}
    report: dict[str, Any] = {}
    for name, table in tables.items():
        hand_name = str(table.attrs.get("hand") or "")
        if not hand_name:
            raise DexaugError(f"{path}: object {name!r} has no 'hand' attribute")
        validator = Validator(Hand.load(hand_name), load_object(name))
        jobs = [("failing", g) for g in _grasps(table.rejected, n)]
        jobs += [("passing", g) for g in _grasps(table, passing)]
        if not jobs:
            console.print(Text(f"{name}: no grasps to replay"))
            continue
        diagnoses = []
        with Progress(console=console, transient=True) as bar:
            task = bar.add_task(f"replaying {name}", total=len(jobs))
            for _, grasp in jobs:
                diagnoses.append(diagnose(validator, grasp))
                bar.advance(task)
        summary = summarise(diagnoses)
        console.print(_summary_table(name, summary))
        report[name] = {"summary": summary,
                        "grasps": [{"set": s, **d.findings} for (s, _), d in zip(jobs, diagnoses,
                                                                                  strict=True)]}
    if json_path is not None:
        write_bytes_atomic(json_path, (json.dumps(report, indent=1, default=float) + "\n").encode())
        console.print(Text(f"wrote {json_path}"))
    return 0


@command("diagnose", _diagnose_args)
def diagnose(args: argparse.Namespace, console: Console) -> int:
    """Why grasps slip: replay a dataset's failing (and some passing) grasps under lift-drop.

    Per grasp and summarised per object: when the object starts to slip and which way
    (translation or rotation, palm-frame axis: +y out of the palm), each contact's friction use
    ft/(μ·fn), each servo's effort against its force limit, the total normal force, which fingers
    carry the object's weight, and the lever arm from the contacts to the centre of mass. The
    replay is the validator's own run, so the verdicts are the dataset's.
    """
    return diagnose_dataset(args.dataset, console, object_name=args.object, n=args.n,
                            passing=args.passing, json_path=args.json)
