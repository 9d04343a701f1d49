"""Cost curve per validation protocol: validated grasps per second against worker processes.

Issue #53 asks for a cost curve per protocol. The same FSG grasps of one object
(:func:`benchmarks.bench_validate_speed.load_grasps`; seed 0 on the hand's manual workspace)
are validated under every registered protocol (lift-drop, six-dir, dgb) with
``validate_many`` at each ``--workers`` count. Each count's workers are started and their
validators built before the clock starts, as in a long ``generate`` run. A row gives grasps/s
and how many verdicts equal the one-worker run's. The GPU axis (worlds per device) needs
MuJoCo Warp and a GPU (``benchmarks/bench_warp_agreement.py``); without a GPU, none is
measured here.

Prints one Markdown table and writes its rows as a record
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/protocol_curves/``).

    .venv/bin/python benchmarks/bench_protocol_curves.py [--object 005_tomato_soup_can]
        [--n 200] [--workers 1 2] [--protocols lift-drop six-dir dgb]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_validate_speed import load_grasps
from benchmarks.record import write_record
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.validate.protocols.registry import names


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--object", default="005_tomato_soup_can")
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--protocols", nargs="+", default=list(names()))
    ap.add_argument("--grasps", type=Path, default=None,
                    help="FSG grasps of --object, made here when the file does not exist "
                         "(default /tmp/dexaug_bench_grasps_<object>.h5: one file per object, "
                         "so another object's file is never read for this one)")
    args = ap.parse_args()
    hand = Hand.load(default_hand_name())
    args.grasps = args.grasps or Path(f"/tmp/dexaug_bench_grasps_{args.object}.h5")
    grasps = load_grasps(args.grasps, hand, args.object, args.n)
    rows: list[dict[str, Any]] = []
    for protocol in args.protocols:
        first: list[bool] | None = None
        for workers in args.workers:
            validate_many(hand.name, args.object, grasps[:workers * 2], protocol, workers=workers)
            t0 = time.perf_counter()
            res = validate_many(hand.name, args.object, grasps, protocol, workers=workers)
            seconds = time.perf_counter() - t0
            verdicts = [bool(r.passed) for r in res]
            first = first or verdicts
            rows.append({"protocol": protocol, "workers": workers, "grasps": len(grasps),
                         "passed": sum(verdicts), "seconds": seconds,
                         "grasps_per_s": len(grasps) / seconds,
                         "same_verdicts_as_first": sum(a == b for a, b in zip(verdicts, first, strict=True))})
            print(rows[-1], flush=True)
    print(f"{args.object}, {len(grasps)} FSG grasps, {hand.name}")
    print("| protocol | workers | grasps/s | passed | verdicts = first row's |\n|---|---|---|---|---|")
    print("\n".join(f"| {r['protocol']} | {r['workers']} | {r['grasps_per_s']:.1f} | "
                    f"{r['passed']}/{r['grasps']} | {r['same_verdicts_as_first']}/{r['grasps']} |"
                    for r in rows))
    path = write_record("protocol_curves", rows, config={k: str(v) for k, v in vars(args).items()},
                        hand=hand.name, objects=[args.object])
    print(f"record: {path}")


if __name__ == "__main__":
    main()
