"""Subcommand ``demo``: the main job on its embedded default (what ``make demo`` runs).

The teleop path (a synthetic session replayed through the bridge) and the augmentation of the
committed demonstration, or of a scripted procedural one when the YCB objects are missing.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from rich.console import Console

from dexaug.commands.registry import command


def _demo_args(p: argparse.ArgumentParser) -> None:
    from sim.paths import REPO_ROOT

    p.add_argument("--session", type=Path,
                   default=REPO_ROOT / "recordings" / "demo_005_tomato_soup_can.mcap",
                   help="the demonstration session to augment (default: the committed Shadow "
                   "Hand grasp of the tomato soup can)")
    p.add_argument("--out", type=Path, default=Path("datasets/demo"), help="output folder")
    p.add_argument("--n", type=int, default=100, help="grasps to generate")


@command("demo", _demo_args)
def demo(args: argparse.Namespace, console: Console) -> int:
    """Run the main job on its embedded default (what `make demo` runs).

    1. The teleop path: the synthetic operator's session (recordings/synth_*.mcap, raw hand
       tracking) replays through the real bridge (zenoh, mink retargeting, MuJoCo) into a new
       recording, as a headset's would.
    2. The augmentation: the demonstration session (--session) → grasp demo → AutoWS → FSG →
       lift-drop validation of every grasp → HDF5 dataset and HTML report, whose paths are
       printed. Without the YCB objects, a scripted demonstration on a procedural cylinder is
       recorded first and augmented instead.
    """
    import tempfile

    from dexaug.commands.augment import progress_bars, stage_ticker
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_session
    from sim.errors import DexaugError
    from sim.paths import REPO_ROOT
    from sim.world.objects import load_object
    from teleop.bridge.rerecord import rerecord
    from teleop.record.session import open_session

    args.out.mkdir(parents=True, exist_ok=True)
    session = args.session
    raw = sorted((REPO_ROOT / "recordings").glob("synth_*.mcap"))
    try:   # the committed sessions hold YCB objects: are they installed here?
        for path in (session, *raw[:1]):
            load_object(open_session(path).metadata.get("object", ""))
    except DexaugError as exc:
        console.print(f"[yellow]{exc}\n→ recording a scripted demonstration on a procedural "
                      f"cylinder instead", highlight=False)
        session = _procedural_demo_session(args.out / "demo_cylinder.mcap")
        raw = []
    if raw:
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            rec = open_session(rerecord(raw[0], Path(tmp) / "replayed.mcap"))
            console.print(f"1. replayed {raw[0].name} through the bridge: {rec.counts['/hands']} "
                          f"frames → {rec.counts['/state']} states, "
                          f"{rec.counts['/contacts']} contact records in "
                          f"{time.perf_counter() - start:.1f} s")
    console.print(f"2. augmenting {session}")
    opts = AugmentOptions(n=args.n, time_budget_s=90.0, gallery=4)
    start = time.perf_counter()
    with progress_bars(console) as bar:
        summaries = augment_session(session, args.out, opts, progress=stage_ticker(bar),
                                    force=True)
    for s in summaries:
        console.print(f"demo {s.demo_id}: {s.generated} grasps generated, {s.passed} passed "
                      f"lift-drop in {time.perf_counter() - start:.1f} s")
        console.print(f"dataset: {s.dataset}")
        console.print(f"report:  {s.report}")
    return 0


def _procedural_demo_session(out: Path) -> Path:
    """A scripted demonstration on the procedural cylinder: the first FSG grasp (manual
    workspace, table mode) that passes lift-drop, performed and recorded."""
    from dexaug.pipeline.scripted_demos import demonstrable_grasps
    from sim.errors import DexaugError
    from sim.hand.config import default_hand_name
    from sim.hand.model import Hand
    from teleop.synthetic.scripted import record_scripted_demo

    hand = Hand.load(default_hand_name())
    passing = demonstrable_grasps(hand, "cylinder", 30)
    if not passing:
        raise DexaugError("no FSG grasp of the procedural cylinder passed lift-drop")
    return record_scripted_demo(hand, "cylinder", passing[0], out, overwrite=True)
