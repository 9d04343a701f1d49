"""What a user gets unasked: ``dexaug generate --object X`` (default mode and protocol), no demo.

Issue #54's acceptance line: the default mode on objects nobody tuned on, mean lift-drop
≥ 80 %, none below 50 %. Per object this runs the command a user would type (``--n``, seed 0,
``--workers``; everything else at its default: ``--mode auto``, ``--validate lift-drop``, the
Shadow Hand) and reads the dataset it writes: the share of its grasps that hold (main table
over main + ``rejected``), the mode auto chose, its pilots (``auto_pilots``) and the wall time
of the command.

Object sets (``--set``):

- ``untouched`` (the default): ten shared YCB objects that no file of this repository named
  before this benchmark (no test, benchmark, config or document): fruit, a plate, cutlery,
  clamps, a ball and toy blocks;
- ``power-decision``: the ten of docs/decisions/2026-12-07-power-grasps.md ("not used in
  development"), whose per-mode figures motivated the pilots of ``--mode auto``. They are
  not untuned for this design.

``--objects`` takes any list instead. One record (:func:`benchmarks.record.write_record`,
``benchmarks/measured/default_mode/``) with a row per object and the mean.

    .venv/bin/python benchmarks/bench_default_mode.py [--set untouched|power-decision]
        [--objects ...] [--n 20] [--workers 2] [--quick]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment.dataset import load
from benchmarks.record import write_record
from sim.hand.config import default_hand_name

SETS = {
    "untouched": ("015_peach", "018_plum", "029_plate", "030_fork", "031_spoon", "032_knife",
                  "050_medium_clamp", "052_extra_large_clamp", "053_mini_soccer_ball",
                  "070_b_colored_wood_blocks"),
    "power-decision": ("071_nine_hole_peg_test", "004_sugar_box", "003_cracker_box",
                       "006_mustard_bottle", "042_adjustable_wrench", "008_pudding_box",
                       "051_large_clamp", "044_flat_screwdriver", "065_a_cups", "013_apple"),
}


def run_object(obj: str, n: int, workers: int, folder: Path) -> dict[str, Any]:
    """``dexaug generate --object obj`` as a user runs it, and what its dataset holds."""
    out = folder / f"{obj}.h5"
    cmd = [sys.executable, "-m", "dexaug", "generate", "--object", obj, "--n", str(n),
           "--seed", "0", "--workers", str(workers), "--out", str(out), "-q"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall_s = time.perf_counter() - t0
    row: dict[str, Any] = {"object": obj, "exit": proc.returncode, "wall_s": wall_s}
    if not out.exists():
        row["error"] = (proc.stdout + proc.stderr).strip().splitlines()[-1:]
        return row
    t = load(out)[obj]
    passed, failed = len(t), len(t.rejected)
    pilots = t.attrs.get("auto_pilots") or ""
    row.update(grasps=passed + failed, passed=passed,
               pass_rate=passed / (passed + failed) if passed + failed else None,
               modes_run=t.attrs.get("modes_run"), mode=t.attrs.get("mode"),
               protocol=t.attrs.get("protocol"), auto_pilots=json.loads(pilots) if pilots else None)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--set", choices=sorted(SETS), default="untouched")
    ap.add_argument("--objects", nargs="+", help="these objects instead of --set's")
    ap.add_argument("--n", type=int, default=20, help="generate's --n (the issue's 20)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="2 objects at n = 4 (a smoke run)")
    args = ap.parse_args()
    objects = list(args.objects or SETS[args.set])
    if args.quick:
        objects, args.n = objects[:2], min(args.n, 4)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_default_mode_") as tmp:
        for obj in objects:
            rows.append(run_object(obj, args.n, args.workers, Path(tmp)))
            print(json.dumps(rows[-1]), flush=True)
    rates = [r["pass_rate"] for r in rows if r.get("pass_rate") is not None]
    summary = {"objects": len(rows), "measured": len(rates),
               "mean_pass_rate": sum(rates) / len(rates) if rates else None,
               "min_pass_rate": min(rates) if rates else None,
               "below_50": [r["object"] for r in rows if (r.get("pass_rate") or 0.0) < 0.5],
               "power_chosen": [r["object"] for r in rows if r.get("modes_run") == "power"]}
    print("| object | mode | grasps | pass | pilots (grasps, passed) | wall s |\n|---|---|---|---|---|---|")
    for r in rows:
        pilots = ", ".join(f"{m} {p['grasps']}/{p['passed']}"
                           for m, p in (r.get("auto_pilots") or {}).items())
        print(f"| {r['object']} | {r.get('modes_run', '–')} | {r.get('grasps', '–')} | "
              f"{100 * (r.get('pass_rate') or 0):.0f} % | {pilots} | {r['wall_s']:.0f} |")
    print(f"mean {summary['mean_pass_rate']}, min {summary['min_pass_rate']}")
    path = write_record("default_mode", rows, summary=summary,
                        config={"set": None if args.objects else args.set, "n": args.n,
                                "workers": args.workers, "quick": args.quick},
                        hand=default_hand_name(), objects=objects)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
