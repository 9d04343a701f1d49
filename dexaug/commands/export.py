"""Subcommand ``export``: a grasp dataset in a layout other tools read.

The work is :mod:`augment.export`; this module picks the tables, the hand and the masses, and
prints what was written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.text import Text

from augment.export import FORMATS, REFERENCE_OBJECT_POSE
from dexaug.commands.registry import command
from sim.errors import DexaugError

__all__ = ["export"]


def _export_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("dataset", type=Path, help="a grasps.h5 written by augment/generate")
    p.add_argument("--format", choices=FORMATS, required=True,
                   help="dexgraspbench: one JSON line per grasp in the DexGraspBench reference "
                        "layout (palm body pose in the world, joints by name, pregrasp/squeeze); "
                        "npz: every column of every table, for numpy.load")
    p.add_argument("--out", type=Path, required=True, help="file to write (replaced atomically)")
    p.add_argument("--object", help="only this object's table (default: every object)")
    p.add_argument("--rejected", action="store_true",
                   help="also the grasps that failed validation (their verdict says so); "
                        "default: only the main table")
    p.add_argument("--object-pose", type=float, nargs=7, default=list(REFERENCE_OBJECT_POSE),
                   metavar=("X", "Y", "Z", "QW", "QX", "QY", "QZ"),
                   help="dexgraspbench: the object frame in the world (metres, wxyz); default "
                        "%(default)s, the reference file's")


def _tables(path: Path, name: str | None, rejected: bool) -> dict:
    from augment.dataset import load, with_rejected

    tables = load(path)
    if name is not None:
        if name not in tables:
            raise DexaugError(f"{path}: no object {name!r} (has {sorted(tables)})")
        tables = {name: tables[name]}
    return {k: with_rejected(t) for k, t in tables.items()} if rejected else tables


def _mass_kg(name: str) -> float | None:
    from sim.world.objects import load_object

    try:
        return load_object(name).mass_kg
    except DexaugError:   # not installed here: the row says null
        return None


@command("export", _export_args)
def export(args: argparse.Namespace, console: Console) -> int:
    """Export a grasp dataset: DexGraspBench's reference JSONL layout or a flat .npz.

    The dexgraspbench layout is the one of ../shared/reference/dexgraspbench/grasps.jsonl: the
    hand's palm body pose and the object pose in the world, q_grasp / q_pregrasp / q_squeeze by
    joint name, plus dexaug's verdict; reading the shared reference file and writing it back
    gives its poses and angles to 1e-9 (tests/test_export.py).
    """
    from augment.export import write_dexgraspbench, write_npz
    from sim.hand.model import Hand

    tables = _tables(args.dataset, args.object, args.rejected)
    if args.format == "npz":
        n = write_npz(args.out, tables)
    else:
        hands = {str(t.attrs.get("hand", "")) for t in tables.values()}
        if len(hands) != 1 or not next(iter(hands)):
            raise DexaugError(f"{args.dataset}: the tables name no single hand (attrs: {hands})")
        masses = {k: m for k in tables if (m := _mass_kg(k)) is not None}
        n = write_dexgraspbench(args.out, tables, Hand.load(hands.pop()),
                                object_pose_world=args.object_pose, masses_kg=masses)
    console.print(Text(f"wrote {n} grasps of {len(tables)} object(s) to {args.out} ({args.format})"))
    return 0
