"""Augmentation throughput: validated grasps per minute per demo, on this machine's cores.

For each committed demonstration session (``recordings/demo_*.mcap``, one per paper object
that has one): the whole pipeline of ``dexaug augment`` (demo extraction, demo-centred AutoWS
from the cache, FSG with link penetration check, lift-drop validation of every grasp, dataset;
no report images) with ``--n`` grasps, in a fresh output folder. Prints per demo the grasps
generated and passed, the seconds per stage and validated grasps per minute (passed grasps over
the wall time of workspace + FSG + validation) and whether the demonstrated grasp itself passes,
as a Markdown table, and writes the rows (with each demo's failure counts) as a record
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/augment/``).

``--quick``: n = 20 on the soup-can session only (a smoke run, not the figures).

Usage: ``.venv/bin/python benchmarks/bench_augment.py [--n 200] [--workers 2] [--quick]``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
from dexaug.pipeline.options import AugmentOptions
from dexaug.pipeline.run import augment_session
from sim.paths import REPO_ROOT
from sim.validate.batch import default_workers


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--workers", type=int, default=default_workers())
    ap.add_argument("--sessions", nargs="*", type=Path,
                    default=sorted((REPO_ROOT / "recordings").glob("demo_*.mcap")))
    ap.add_argument("--quick", action="store_true", help="n = 20, one session (smoke run)")
    args = ap.parse_args()
    if args.quick:
        args.n = min(args.n, 20)
        args.sessions = [s for s in args.sessions if "005_tomato_soup_can" in s.name][:1]
    logging.basicConfig(level=logging.WARNING)
    opts = AugmentOptions(n=args.n, workers=args.workers, gallery=0, time_budget_s=300.0)
    print(f"| Demo | Generated | Passed lift-drop | Pass % | Demo grasp | Workspace s | FSG s "
          f"| Validate s | Validated / min ({args.workers} workers) |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows, hands, objects = [], set(), set()
    with tempfile.TemporaryDirectory() as out:
        for session in args.sessions:
            for s in augment_session(session, out, opts, force=True):
                t = s.timings_s
                rate = 100.0 * s.passed / s.generated if s.generated else 0.0
                demo = s.demo_grasp or {}
                verdict = "pass" if demo.get("passed") else (demo.get("failure") or "—")
                print(f"| {s.demo_id} | {s.generated} | {s.passed} | {rate:.0f} | {verdict} "
                      f"| {t['workspace']:.2f} | {t['fsg']:.2f} | {t['validate']:.2f} "
                      f"| {s.validated_per_min:.0f} |", flush=True)
                rows.append({"demo": s.demo_id, "hand": s.hand, "object": s.object,
                             "generated": s.generated, "passed": s.passed, "pass_pct": rate,
                             "demo_grasp": verdict, "workspace_s": t["workspace"],
                             "fsg_s": t["fsg"], "validate_s": t["validate"],
                             "validated_per_min": s.validated_per_min,
                             "failures": s.failures, "fsg_stopped": s.fsg_stopped})
                hands.add(s.hand)
                objects.add(s.object)
    path = write_record("augment", rows, config={**vars(args), "time_budget_s": opts.time_budget_s},
                        hand=next(iter(hands)) if len(hands) == 1 else None, objects=sorted(objects))
    print(f"record: {path}")


if __name__ == "__main__":
    main()
