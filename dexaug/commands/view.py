"""Subcommand ``view``: the interactive 3D viewer page of any grasp dataset.

The page is :mod:`dexaug.viewer` (the pipeline writes the same page beside each report); this
module picks the tables, loads their hand and object, and says where the pages went.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.text import Text

from dexaug.commands.argtypes import int_at_least
from dexaug.commands.guards import dataset_file, did_you_mean, require_writable
from dexaug.commands.registry import command
from sim.errors import DexaugError

__all__ = ["view"]


def _view_args(p: argparse.ArgumentParser) -> None:
    from dexaug.viewer.scene import ViewerLimits

    p.add_argument("dataset", type=dataset_file, help="a grasps.h5 written by augment/generate")
    p.add_argument("--object", help="only this object's table (default: every object)")
    p.add_argument("--out", type=Path, help="the page to write (one object); default: "
                   "viewer_<object>.html beside the dataset")
    p.add_argument("--max-grasps", type=int_at_least(1), default=ViewerLimits.max_grasps,
                   help="grasps the page holds (passed first, then rejected); default "
                        "%(default)s")


@command("view", _view_args)
def view(args: argparse.Namespace, console: Console) -> int:
    """Write an interactive 3D viewer of a dataset's grasps (one HTML file per object).

    The object, the hand at each grasp (forward kinematics of the hand model, its visual
    meshes), contacts and normals, the demonstration's table and palm, and the palm cloud with
    the object frame's axes; filters by verdict, failure reason and fingers. Open the file in
    any browser with WebGL2 (no server needed)."""
    from augment import dataset
    from dexaug.pipeline.arm_run import table_demo
    from dexaug.viewer.page import write_viewer
    from dexaug.viewer.scene import ViewerLimits, viewer_scene
    from sim.hand.model import Hand
    from sim.world.objects import load_object

    require_writable(args.out or args.dataset.parent / "viewer.html", "--out")
    tables = dataset.load(args.dataset)
    if args.object is not None and args.object not in tables:
        raise DexaugError(f"{args.dataset}: no object {args.object!r}; it holds "
                          f"{', '.join(sorted(tables)) or 'no table'}"
                          f"{did_you_mean(args.object, tables)}")
    names = [args.object] if args.object is not None else sorted(tables)
    if args.out is not None and len(names) > 1:
        raise DexaugError(f"{args.dataset} holds {len(names)} objects: --out names one page, "
                          "so pass --object too (or leave --out out: one page per object)")
    for name in names:
        table = tables[name]
        hand_name = str(table.attrs.get("hand") or "")
        if not hand_name:
            raise DexaugError(f"{args.dataset}: table {name!r} does not name its hand "
                              "(attribute 'hand')")
        scene = viewer_scene(table, Hand.load(hand_name), load_object(name),
                             demo=table_demo(args.dataset, name, table),
                             title=f"{args.dataset.name}: {name}",
                             limits=ViewerLimits(max_grasps=args.max_grasps))
        out = args.out or args.dataset.parent / f"viewer_{name}.html"
        write_viewer(out, scene)
        console.print(Text(f"{name}: {scene['grasps']['n']} grasps → {out}"), soft_wrap=True)
    return 0
