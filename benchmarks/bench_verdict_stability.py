"""How firm is a verdict? Each grasp of a dataset validated again, as stored and nudged.

A pass rate is read as a property of the grasps; it is one only as far as a grasp's verdict is
not decided by sub-millimetre details no hand or generator controls. Here every grasp (passing
and rejected rows alike) is validated once as stored and ``--copies`` times with its palm moved
``--pos-mm`` in a random direction and each joint moved uniformly within ``±--joint-deg``
(clipped to the joint limits; 0.1 mm and 0.1° by default, far below any placement or
tracking error). Printed per object: the grasps, passes as stored, the nudged copies' pass
rate, the grasps whose verdicts all agree (always pass / always fail) or not (mixed), and the
share of nudged verdicts that differ from the grasp's own; the rows go to a record as well
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/verdict_stability/``).

    .venv/bin/python benchmarks/bench_verdict_stability.py DATASET.h5 [...] [--protocol dgb]
        [--copies 3] [--pos-mm 0.1] [--joint-deg 0.1] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from augment.grasp_table import grasps_of, with_rejected
from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.validate.config import PROTOCOLS


def nudged(grasps: list[Grasp], hand: Hand, copies: int, pos_m: float, joint_rad: float,
           rng: np.random.Generator) -> list[Grasp]:
    """``copies`` nudged versions of each grasp, grasp by grasp: palm moved ``pos_m`` along a
    random unit direction, joints by uniform ``±joint_rad`` within the hand's limits."""
    out = []
    for g in grasps:
        for _ in range(copies):
            step = rng.normal(size=3)
            q = g.joints + rng.uniform(-joint_rad, joint_rad, len(g.joints))
            out.append(Grasp.from_arrays(g.palm_pos + pos_m * step / np.linalg.norm(step),
                                         g.palm_quat_wxyz, np.clip(q, hand.lower, hand.upper)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="+", type=Path, help="grasp datasets (.h5)")
    ap.add_argument("--protocol", choices=PROTOCOLS, default="dgb",
                    help="validation protocol (default dgb)")
    ap.add_argument("--copies", type=int, default=3, help="nudged copies per grasp (default 3)")
    ap.add_argument("--pos-mm", type=float, default=0.1, help="palm nudge, mm (default 0.1)")
    ap.add_argument("--joint-deg", type=float, default=0.1, help="joint nudge bound, degrees "
                    "(default 0.1)")
    ap.add_argument("--seed", type=int, default=1, help="nudge seed (default 1)")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print("| object | grasps | pass as stored | nudged pass rate | always pass | always fail | mixed "
          "| nudged verdicts that differ |")
    print("|---|---|---|---|---|---|---|---|")
    rows, hands = [], set()
    for path in args.datasets:
        for name, table in dataset.load(path).items():
            hand = Hand.load(table.attrs["hand"])
            grasps = grasps_of(with_rejected(table))
            own = np.array([r.passed for r in validate_many(hand.name, name, grasps, args.protocol)])
            copies = nudged(grasps, hand, args.copies, args.pos_mm / 1000, np.radians(args.joint_deg), rng)
            moved = np.array([r.passed for r in validate_many(hand.name, name, copies, args.protocol)]
                             ).reshape(len(grasps), args.copies)
            share = np.c_[own, moved].mean(axis=1)
            print(f"| {name} | {len(grasps)} | {own.sum()} | {moved.mean():.1%} | {np.sum(share == 1)} "
                  f"| {np.sum(share == 0)} | {np.sum((share > 0) & (share < 1))} "
                  f"| {np.mean(moved != own[:, None]):.1%} |")
            rows.append({"dataset": path, "object": name, "hand": hand.name,
                         "grasps": len(grasps), "pass_as_stored": int(own.sum()),
                         "nudged_pass_rate": float(moved.mean()),
                         "always_pass": int(np.sum(share == 1)),
                         "always_fail": int(np.sum(share == 0)),
                         "mixed": int(np.sum((share > 0) & (share < 1))),
                         "nudged_differ": float(np.mean(moved != own[:, None]))})
            hands.add(hand.name)
    record = write_record("verdict_stability", rows, config=vars(args),
                          hand=next(iter(hands)) if len(hands) == 1 else None,
                          objects=sorted({r["object"] for r in rows}))
    print(f"record: {record}")


if __name__ == "__main__":
    main()
