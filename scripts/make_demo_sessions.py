"""Make the committed demonstration sessions: one precision grasp per paper object.

How a demonstration is made, with dexaug's own tools only (no human, no shared recording):

1. **A grasp worth demonstrating.** FSG on the hand's manual workspace (no demo, table mode,
   link penetration check) proposes grasps of the object resting on the table; each is
   validated by the MuJoCo lift-and-drop test, and the passing ones are the candidates.
2. **Performed and recorded.** Each candidate is performed as a scripted demonstration in the
   bridge's scene (``teleop.scripted``: pregrasp → close → hold → lift → hold on the table,
   gravity on) and recorded in the bridge's session format.
3. **Kept when it is a demo.** ``augment.demo.extract_demos`` must find the grasp in the
   recording (at least two fingertips, the thumb among them, in stable contact); of the
   candidates, the one with the most fingers in contact (then held longest) is kept as
   ``recordings/demo_<object>.mcap``, and its
   extracted demo as ``recordings/demos/<object>.json``.

The synthetic operator (``teleop.synth``) through the bridge was tried first and did not yield
demos: its retargeted precision grasps knock light objects over or stop a few millimetres short.

Run: ``.venv/bin/python scripts/make_demo_sessions.py [--objects ...]`` (about a minute each).
"""

from __future__ import annotations

import argparse
import logging
import shutil
import tempfile
from pathlib import Path

from augment.demo import Demo, DemoError, extract_demos, save_demo
from sim.hand import Hand
from sim.io import atomic_path
from sim.paths import REPO_ROOT, ensure_menagerie_root
from teleop.scripted import demonstrable_grasps, record_scripted_demo

OBJECTS = ("004_sugar_box", "005_tomato_soup_can", "024_bowl", "043_phillips_screwdriver",
           "062_dice")
log = logging.getLogger("make_demo_sessions")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hand", default="shadow_right")
    ap.add_argument("--objects", nargs="*", default=list(OBJECTS))
    ap.add_argument("--candidates", type=int, default=60, help="FSG grasps proposed per object")
    ap.add_argument("--tries", type=int, default=8, help="passing grasps tried per object")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    for noisy in ("teleop", "augment.fsg", "sim"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    ensure_menagerie_root()
    hand = Hand.load(args.hand)
    rec_dir = REPO_ROOT / "recordings"
    for obj in args.objects:
        passing = demonstrable_grasps(hand, obj, args.candidates)[:args.tries]
        best: tuple[tuple[int, float], Path, Demo] | None = None
        with tempfile.TemporaryDirectory() as tmp:
            for i, grasp in enumerate(passing):
                path = record_scripted_demo(hand, obj, grasp, Path(tmp) / f"{i}.mcap")
                try:
                    demo = max(extract_demos(path), key=lambda d: d.duration_s)
                except DemoError as exc:
                    log.info("%s candidate %d: %s", obj, i, exc)
                    continue
                score = (len(demo.fingers), demo.duration_s)
                if best is None or score > best[0]:
                    best = (score, path, demo)
            if best is None:
                log.warning("%s: no candidate became a demo", obj)
                continue
            out = rec_dir / f"demo_{obj}.mcap"
            with atomic_path(out) as dst:
                shutil.copyfile(best[1], dst)
        demo = max(extract_demos(out), key=lambda d: d.duration_s)
        save_demo(rec_dir / "demos" / f"{obj}.json", demo)
        log.info("%s: demo %s (%s, fingers %s, held %.2f s)", obj, demo.id, demo.how,
                 demo.fingers, demo.duration_s)


if __name__ == "__main__":
    main()
