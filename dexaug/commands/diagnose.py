"""Subcommand ``diagnose``: why a dataset's grasps failed, from a replay of each under lift-drop
or the benchmark (``dgb``).

:func:`diagnose_dataset` is the job (also callable without the CLI parser); the physics is
:mod:`sim.validate.diagnose` (lift-drop) and :mod:`sim.validate.diagnose_dgb` (``dgb``).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.progress import Progress
from rich.table import Table
from rich.text import Text

from dexaug.commands.argtypes import int_at_least
from dexaug.commands.guards import dataset_file, did_you_mean, require_writable
from dexaug.commands.registry import command
from dexaug.pipeline.protocol_facts import DEFAULT_PROTOCOL, diagnosable, diagnosis
from sim.errors import DexaugError

if TYPE_CHECKING:
    from augment.grasp_table import ObjectTable

__all__ = ["diagnose", "diagnose_dataset"]


def _diagnose_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", type=dataset_file, help="a grasps.h5 written by augment/generate")
    p.add_argument("--object", help="only this object's table (default: every object in the file)")
    p.add_argument("--n", type=int_at_least(1), default=20,
                   help="failing grasps replayed per object (from the rejected table); "
                        "default %(default)s")
    p.add_argument("--passing", type=int_at_least(0), default=5,
                   help="passing grasps replayed too, for comparison; default %(default)s")
    p.add_argument("--protocol", choices=diagnosable(), default=DEFAULT_PROTOCOL,
                   help="replay under lift-drop (slip, friction, efforts) or the benchmark (closing "
                        "drift, the held closing's imbalance, reconfigured J1/J2 pairs, unloaded "
                        "contacts, the hardest push); default %(default)s")
    p.add_argument("--json", type=Path, help="write every grasp's findings and the summary as JSON")


def _num(x: float, fmt: str = ".2f") -> str:
    """``x`` formatted, or a dash for NaN (no grasp in the group)."""
    return "—" if x != x else format(x, fmt)


def _findings_table(title: str) -> Table:
    t = Table(title=title, show_header=True)
    for column in ("finding", "failing", "passing"):
        t.add_column(column)
    return t


def _summary_table(name: str, summary: dict[str, Any]) -> Table:
    t = _findings_table(f"{name}: {summary['grasps']} grasps replayed")
    f, p = summary["failing"], summary["passing"]
    t.add_row("verdicts", Text(json.dumps(summary["verdicts"])), "")
    t.add_row("slip mode (palm frame)", Text(json.dumps(summary["slip_modes"])), "")
    t.add_row("slip starts in", Text(json.dumps(summary["slip_onset_phase"])), "")
    t.add_row("friction use ft/(μ·fn), median", _num(f["friction_use_median"]),
              _num(p["friction_use_median"]))
    t.add_row("largest servo effort / limit, median", _num(f["effort_max_median"]),
              _num(p["effort_max_median"]))
    t.add_row("grasps with a servo at its limit", str(f["with_actuator_at_limit"]), "")
    t.add_row("grasps with a sliding contact", str(f["with_sliding_contact"]), "")
    t.add_row("total normal force (N), median", _num(f["fn_total_median_n"], ".1f"),
              _num(p["fn_total_median_n"], ".1f"))
    t.add_row("contact centroid → COM lever (mm), median", _num(1e3 * f["lever_arm_median_m"], ".1f"),
              _num(1e3 * p["lever_arm_median_m"], ".1f"))
    t.add_row("weight carried per finger, median", Text(json.dumps(f["support_median"])),
              Text(json.dumps(p["support_median"])))
    return t


def _dgb_summary_table(name: str, summary: dict[str, Any]) -> Table:
    t = _findings_table(f"{name}: {summary['grasps']} grasps replayed under dgb")
    f, p = summary["failing"], summary["passing"]
    t.add_row("grasps", str(f["grasps"]), str(p["grasps"]))
    t.add_row("verdicts", Text(json.dumps(summary["verdicts"])), "")
    t.add_row("first failing push", Text(json.dumps(summary["failing_push"])), "")
    t.add_row("turn after the grasp stage (°), median", _num(f["grasp_drift_deg_median"], ".1f"),
              _num(p["grasp_drift_deg_median"], ".1f"))
    t.add_row("drift after the squeeze (mm, °), median",
              f"{_num(f['squeeze_drift_mm_median'], '.1f')}, {_num(f['squeeze_drift_deg_median'], '.1f')}",
              f"{_num(p['squeeze_drift_mm_median'], '.1f')}, {_num(p['squeeze_drift_deg_median'], '.1f')}")
    t.add_row("held closing: imbalance ‖F‖ + ‖τ‖/2 cm (N), median",
              _num(f["held_imbalance_median_n"], ".2f"), _num(p["held_imbalance_median_n"], ".2f"))
    t.add_row("J1/J2 pairs reconfigured (> 0.1 rad), median",
              _num(f["pairs_reconfigured_median"], ".1f"), _num(p["pairs_reconfigured_median"], ".1f"))
    t.add_row("planned contacts unloaded at the end, median",
              _num(f["planned_unloaded_median"], ".1f"), _num(p["planned_unloaded_median"], ".1f"))
    t.add_row("hardest push: grip left at its end (share), median",
              _num(f["push_grip_kept_median"], ".2f"), _num(p["push_grip_kept_median"], ".2f"))
    t.add_row("hardest push: largest J1/J2 split move (°), median",
              _num(f["push_split_moved_deg_median"], ".1f"), _num(p["push_split_moved_deg_median"], ".1f"))
    t.add_row("hardest push: along palm axis (count)", Text(json.dumps(f["hardest_push_palm_axis"])),
              Text(json.dumps(p["hardest_push_palm_axis"])))
    return t


#: how each diagnosis's summary is shown, by the module that makes it
#: (:class:`dexaug.pipeline.protocol_facts.Diagnosis`)
_SUMMARY_TABLES: dict[str, Callable[[str, dict[str, Any]], Table]] = {
    "sim.validate.diagnose": _summary_table, "sim.validate.diagnose_dgb": _dgb_summary_table}


def diagnose_dataset(path: Path, console: Console, *, object_name: str | None = None,
                     n: int = 20, passing: int = 5, json_path: Path | None = None,
                     protocol: str = DEFAULT_PROTOCOL) -> int:
    """Replay up to ``n`` failing and ``passing`` passing grasps per object of the dataset at
    ``path`` under ``protocol`` and print the findings; returns the exit code."""
    from augment import dataset
    from augment.grasp_table import grasps_of
    from sim.hand.model import Hand
    from sim.io import write_bytes_atomic
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    replay = diagnosis(protocol)
    summary_table = _SUMMARY_TABLES[replay.module]
    tables: dict[str, ObjectTable] = dataset.load(path)
    if object_name is not None:
        if object_name not in tables:
            raise DexaugError(f"{path}: no object {object_name!r}; it holds {sorted(tables)}"
                              f"{did_you_mean(object_name, tables)}")
        tables = {object_name: tables[object_name]}
    report: dict[str, Any] = {}
    for name, table in tables.items():
        hand_name = str(table.attrs.get("hand") or "")
        if not hand_name:
            raise DexaugError(f"{path}: object {name!r} has no 'hand' attribute")
        validator = Validator(Hand.load(hand_name), load_object(name))
        jobs = [("failing", g) for g in grasps_of(table.rejected, n)]
        jobs += [("passing", g) for g in grasps_of(table, passing)]
        if not jobs:
            console.print(Text(f"{name}: no grasps to replay"))
            continue
        diagnoses = []
        with Progress(console=console, transient=True) as bar:
            task = bar.add_task(f"replaying {name}", total=len(jobs))
            for _, grasp in jobs:
                diagnoses.append(replay.diagnose(validator, grasp))
                bar.advance(task)
        summary = replay.summarise(diagnoses)
        console.print(summary_table(name, summary))
        report[name] = {"summary": summary,
                        "grasps": [{"set": s, **d.findings} for (s, _), d in zip(jobs, diagnoses,
                                                                                  strict=True)]}
    if json_path is not None:
        write_bytes_atomic(json_path, (json.dumps(report, indent=1, default=float) + "\n").encode())
        console.print(Text(f"wrote {json_path}"))
    return 0


@command("diagnose", _diagnose_args)
def diagnose(args: argparse.Namespace, console: Console) -> int:
    """Why grasps fail: replay a dataset's failing (and some passing) grasps under lift-drop or dgb.

    Lift-drop, per grasp and summarised per object: when the object starts to slip and which
    way (translation or rotation, palm-frame axis: +y out of the palm), each contact's friction
    use ft/(μ·fn), each servo's effort against its force limit, the total normal force, which
    fingers carry the object's weight, and the lever arm from the contacts to the centre of mass.
    dgb (--protocol dgb): the free object's drift after the closing's grasp and squeeze stages,
    the first failing push, and the same closing on the held object: the hand's net force and
    torque on it, which tendon-shared J1/J2 pairs reconfigure, which planned contacts end up
    unloaded; and the hardest push replayed (the first failing one, else the one that turned the
    object most): its palm-frame axis, the grip left at its end, the J1/J2 splits it moved. The
    replay is the validator's own run, so the verdicts are the dataset's.
    """
    if args.json is not None:
        require_writable(args.json, "--json")
    return diagnose_dataset(args.dataset, console, object_name=args.object, n=args.n,
                            passing=args.passing, json_path=args.json, protocol=args.protocol)
