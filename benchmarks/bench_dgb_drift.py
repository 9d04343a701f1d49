"""Where do ``dgb`` failures come from: the closing, or the pushes?

DexGraspBench measures every drift from the object's pose *before* the fingers close
(``sim.validate.dgb``), so a grasp that turns the free object while closing has spent part of
its 15° and 5 cm before the first push. This replays a dataset's ``dgb``-validated grasps
(passing and failing, up to ``--n`` of each per object) through the benchmark's two closing
stages and an idle half second (:func:`sim.validate.dgb.closing_drift`) and reports, per
object and verdict, the median drift after each stage, the share of failing grasps that had
already turned ≥ 7.5° (half the limit) or left the limits before any push, and the push
direction each failing grasp failed in.

    .venv/bin/python benchmarks/bench_dgb_drift.py DATASET.h5 [DATASET.h5 ...] [--n 40]

Prints one Markdown table and writes its rows as a record (:func:`benchmarks.record.write_record`,
``benchmarks/measured/dgb_drift/``). The stored verdicts are recomputed (the replay is the
validator's).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.config import ValidateConfig
from sim.validate.dgb import closing_drift
from sim.validate.stages import SQUEEZE_CONVENTIONS
from sim.validate.validator import Validator
from sim.world.objects import load_object

STAGES = ("grasp", "squeeze", "idle")


def replay(path: Path, n: int) -> list[dict[str, object]]:
    """One dict per replayed grasp: object, squeeze convention, verdict, drift per stage (mm,
    degrees), and the first failing push direction."""
    rows = []
    for name, table in dataset.load(path).items():
        validator = Validator(Hand.load(str(table.attrs["hand"])), load_object(name))
        for t in (table, table.rejected):
            if t is None:
                continue
            for i in range(min(len(t), n)):
                made_by = str(t.columns["stages_made_by"][i])
                convention = made_by if made_by in SQUEEZE_CONVENTIONS else None
                pose = t.columns["palm_pose"][i]
                grasp = Grasp(pose[:3], pose[3:], t.columns["hand_pose"][i])
                result = validator.validate(grasp, "dgb", squeeze_convention=convention)
                stages = validator.stages(grasp, convention, sized_for="dgb")
                drift = closing_drift(validator.scene("dgb"), validator.config.dgb,
                                      validator.palm_world(grasp), stages)
                failed = [k for k, ph in result.phases.items() if not ph.passed]
                rows.append({"object": name, "convention": stages.made_by,
                             "passed": result.passed,
                             "direction": failed[0] if failed else None,
                             **{f"{s}_mm": 1e3 * drift[s][0] for s in STAGES},
                             **{f"{s}_deg": float(np.degrees(drift[s][1])) for s in STAGES}})
    return rows


def group(label: str, rows: list[dict[str, object]], limits: tuple[float, float]) -> dict[str, Any]:
    """One row of the table for ``rows`` (one object and verdict, at least one grasp), as data:
    median drifts per stage (mm, degrees), the counts and the failing push directions;
    ``limits``: the benchmark's (millimetres, degrees)."""
    return {"group": label, "grasps": len(rows),
            **{k: float(np.median([float(r[k]) for r in rows]))
               for s in STAGES for k in (f"{s}_mm", f"{s}_deg")},
            "squeeze_half_limit": sum(float(r["squeeze_deg"]) >= 7.5 for r in rows),
            "out_at_squeeze": sum(float(r["squeeze_deg"]) >= limits[1]
                                  or float(r["squeeze_mm"]) >= limits[0] for r in rows),
            "failing_push": dict(sorted(Counter(str(r["direction"]) for r in rows
                                                if r["direction"]).items()))}


def line(g: dict[str, Any]) -> str:
    """The Markdown row of :func:`group`'s dict."""
    drift = " | ".join(f"{g[s + '_mm']:.1f} mm, {g[s + '_deg']:.1f}°" for s in STAGES)
    return (f"| {g['group']} | {g['grasps']} | {drift} | {g['squeeze_half_limit']} | "
            f"{g['out_at_squeeze']} | "
            f"{' '.join(f'{k}:{v}' for k, v in g['failing_push'].items())} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("datasets", nargs="+", type=Path)
    ap.add_argument("--n", type=int, default=40,
                    help="grasps replayed per object and verdict (default: 40)")
    args = ap.parse_args()
    dgb = ValidateConfig.load().dgb
    limits = (1e3 * dgb.max_displacement_m, float(np.degrees(dgb.max_rotation_rad)))
    print("| object (squeeze convention) / verdict | grasps | after grasp stage | after squeeze "
          "| idle 0.5 s more | squeeze ≥ 7.5° | out of limits at squeeze | failing push |")
    print("|---|---|---|---|---|---|---|---|")
    out: list[dict[str, Any]] = []
    hands: set[str] = set()
    for path in args.datasets:
        rows = replay(path, args.n)
        for key in sorted({(str(r["object"]), str(r["convention"])) for r in rows}):
            for verdict in (True, False):
                members = [r for r in rows
                           if (r["object"], r["convention"]) == key and r["passed"] == verdict]
                if members:
                    out.append({"dataset": path, "object": key[0], "convention": key[1],
                                "passed": verdict,
                                **group(f"{key[0]} ({key[1]}) / {'pass' if verdict else 'fail'}",
                                        members, limits)})
                    print(line(out[-1]))
        hands |= {str(t.attrs["hand"]) for t in dataset.load(path).values()}
    record = write_record("dgb_drift", out, config={**vars(args), "limits_mm_deg": limits},
                          hand=next(iter(hands)) if len(hands) == 1 else None,
                          objects=sorted({r["object"] for r in out}))
    print(f"record: {record}")


if __name__ == "__main__":
    main()
