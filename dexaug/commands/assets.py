"""Subcommand ``assets``: which hands and objects dexaug can find, and what is broken and why."""

from __future__ import annotations

import argparse

from rich.console import Console
from rich.table import Table
from rich.text import Text

from dexaug.commands.registry import command


def _assets_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--broken", action="store_true", help="list only objects that fail to load")


@command("assets", _assets_args)
def assets(args: argparse.Namespace, console: Console) -> int:
    """List the hands and objects dexaug can find, and what is broken and why.

    Hands come from configs/hands/*/hand.toml resolved through mujoco_menagerie (MENAGERIE_ROOT);
    objects are the procedural primitives plus every YCB object under DEXAUG_YCB_ROOT.
    """
    from sim.errors import DexaugError
    from sim.hand.config import hand_names
    from sim.hand.model import Hand
    from sim.paths import MENAGERIE_ENV, YCB_ENV, ensure_menagerie_root, ycb_root
    from sim.world.catalog import list_objects

    console.print(f"{MENAGERIE_ENV} = {ensure_menagerie_root()}")
    console.print(f"{YCB_ENV} = {ycb_root(required=False)}")
    hands = Table(title="hands")
    for col in ("hand", "joints", "actuators", "fingers", "status"):
        hands.add_column(col)
    for name in hand_names():
        try:
            hand = Hand.load(name)
            hands.add_row(name, str(hand.nq), str(hand.model.nu), ", ".join(hand.finger_names),
                          Text("ok", style="green"))
        except DexaugError as exc:
            hands.add_row(name, "", "", "", Text(str(exc), style="red"))
    console.print(hands)
    objects = Table(title="objects")
    for col in ("object", "source", "mass (kg)", "status"):
        objects.add_column(col)
    statuses = list_objects()
    for s in statuses:
        if args.broken and s.ok:
            continue
        state = Text("ok", style="green") if s.ok else Text(f"broken: {s.problem}", style="red")
        if s.ok and s.warnings:
            state = Text(f"ok ({'; '.join(s.warnings)})", style="yellow")
        objects.add_row(s.name, s.source, f"{s.mass_kg:.3f}" if s.mass_kg else "", state)
    console.print(objects)
    broken = sum(not s.ok for s in statuses)
    console.print(f"{len(statuses) - broken} objects load, {broken} broken")
    return 0
