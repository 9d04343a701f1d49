"""Subcommand ``workspace``: AutoWS fingertip workspace clouds of a hand, optionally centred on a
reference grasp, summarised, saved and rendered."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from dexaug.commands.guards import require_writable
from dexaug.commands.options import hand_arg
from dexaug.commands.registry import command


def _workspace_args(p: argparse.ArgumentParser) -> None:
    hand_arg(p)
    p.add_argument("--demo", metavar="GRASP",
                   help="centre the clouds on a demonstration: the name of a reference grasp in "
                   "configs/hands/<hand>/grasps.toml (its joints, and its fingertip contacts on its "
                   "object found in MuJoCo)")
    p.add_argument("--out", type=Path, help="also save the clouds to this .npz file")
    p.add_argument("--render", type=Path, metavar="PNG", help="render the clouds over the hand")
    p.add_argument("--no-cache", action="store_true", help="ignore and do not write the disk cache")


@command("workspace", _workspace_args)
def workspace(args: argparse.Namespace, console: Console) -> int:
    """Build AutoWS fingertip workspace clouds (paper §3) for a hand.

    Without --demo, joint grids come from the manual ranges of the hand config (the paper's
    Table 1 for the Shadow Hand); with --demo, from the demonstration's angles ± 2 steps of 5°,
    with contact faces centred on its fingertip contacts. Clouds are cached on disk
    (DEXAUG_CACHE_DIR), keyed by the hand model, config, demo and parameters.
    """
    for option, path in (("--out", args.out), ("--render", args.render)):
        if path is not None:
            require_writable(path, option)
    if args.render:
        from sim.world.render import select_gl_backend

        select_gl_backend()
    from augment.autows.build import build_workspace
    from augment.autows.cloud import summarise
    from augment.autows.render import render_workspace_png
    from augment.autows.seed import DemoSeed
    from sim.hand.model import Hand

    hand = Hand.load(args.hand)
    demo = None
    if args.demo:
        from sim.errors import ConfigError
        from sim.hand.reference_grasps import load_reference_grasps
        from sim.validate.validator import Validator
        from sim.world.objects import load_object

        refs = {r.name: r for r in load_reference_grasps(hand)}
        if args.demo not in refs:
            raise ConfigError(f"--demo: no reference grasp {args.demo!r} for hand {hand.name!r}; "
                              f"known: {sorted(refs)}")
        ref = refs[args.demo]
        contacts = Validator(hand, load_object(ref.object)).fingertip_contacts(ref.grasp)
        demo = DemoSeed(joints=ref.grasp.joints, contacts=contacts, id=f"grasp:{ref.name}")
    start = time.perf_counter()
    cloud = build_workspace(hand, demo=demo, cache=not args.no_cache)
    seconds = time.perf_counter() - start
    table = Table(title=f"AutoWS workspace of {hand.name}" + (f" (demo {args.demo})" if demo else ""))
    for col in ("finger", "points", "contact faces"):
        table.add_column(col)
    for finger, n_points, n_faces in summarise(cloud):
        table.add_row(finger, str(n_points), str(n_faces))
    console.print(table)
    source = "cache" if cloud.from_cache else "built"
    console.print(f"{source} in {seconds * 1e3:.1f} ms, {cloud.nbytes / 1e6:.2f} MB")
    if args.out:
        cloud.save(args.out)
        console.print(f"wrote {args.out}")
    if args.render:
        render_workspace_png(hand, cloud, args.render)
        console.print(f"wrote {args.render}")
    return 0
