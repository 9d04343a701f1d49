"""Ray scale-out throughput: the committed demos augmented and validated locally and on Ray.

The units are the demos in ``recordings/demos/`` (``dexaug batch recordings/demos/*.json``),
``--n`` grasps each, lift-drop, no report. Three runs, each into a fresh folder:

- local pool, 2 processes (``dexaug batch``'s default on this machine);
- local pool, 1 FSG process (what ``--ray --workers 1`` must reproduce);
- Ray: a local cluster on loopback with ``--cpus`` worker CPUs, FSG one task per demo (1 process),
  validation in ``--chunk``-grasp tasks (``dexaug batch --ray``).

Printed as a Markdown table: wall seconds (Ray's includes starting its cluster), grasps
generated and passed, and grasps generated + validated per second; then whether the Ray run's
datasets equal the one-process local run's, column by column. The rows go to a record as well
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/ray/``).

    .venv/bin/python benchmarks/bench_ray.py [--n 300] [--cpus 2] [--chunk 32] [--quick]

``--quick``: n = 8 per demo (a smoke run: the Ray cluster still starts).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from benchmarks.record import write_record
from dexaug.pipeline.options import AugmentOptions
from dexaug.pipeline.summary import DemoSummary
from dexaug.scale.ray_cluster import ray_cluster
from dexaug.scale.ray_jobs import run_on_ray
from dexaug.scale.units import Unit, gather_units, run_local

DEMOS = sorted((Path(__file__).resolve().parents[1] / "recordings" / "demos").glob("*.json"))


def tables(folder: Path) -> dict[str, dataset.ObjectTable]:
    return {sub.name: dataset.with_rejected(next(iter(dataset.load(sub / "grasps.h5").values())))
            for sub in sorted(folder.iterdir())}


def same(a: dict[str, dataset.ObjectTable], b: dict[str, dataset.ObjectTable]) -> bool:
    return a.keys() == b.keys() and all(
        a[k].columns.keys() == b[k].columns.keys()
        and all(np.array_equal(x, b[k].columns[c], equal_nan=x.dtype.kind == "f")
                for c, x in a[k].columns.items()) for k in a)


def stats(label: str, wall_s: float, summaries: list[DemoSummary]) -> dict[str, Any]:
    """One run's row as data: wall seconds, grasps generated and passed, grasps/s."""
    made = sum(s.generated for s in summaries)
    return {"run": label, "wall_s": wall_s, "grasps": made,
            "passed": sum(s.passed for s in summaries), "grasps_per_s": made / wall_s}


def row(r: dict[str, Any]) -> str:
    return f"| {r['run']} | {r['wall_s']:.1f} | {r['grasps']} | {r['passed']} | {r['grasps_per_s']:.1f} |"


def local(units: list[Unit], out: Path, workers: int) -> tuple[float, list[DemoSummary]]:
    t0 = time.perf_counter()
    done = [run_local(replace(u, opts=replace(u.opts, workers=workers)), out) for u in units]
    return time.perf_counter() - t0, done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--n", type=int, default=300, help="grasps per demo (default %(default)s)")
    parser.add_argument("--cpus", type=int, default=2, help="Ray worker CPUs (default %(default)s)")
    parser.add_argument("--chunk", type=int, default=32, help="grasps per validation task")
    parser.add_argument("--quick", action="store_true", help="n = 8 per demo (smoke run)")
    args = parser.parse_args()
    if args.quick:
        args.n = min(args.n, 8)
    opts = AugmentOptions(n=args.n, seed=0, workers=1, gallery=0, validate="lift-drop",
                          time_budget_s=1800.0)
    units, errors = gather_units(DEMOS, opts)
    if errors:
        raise SystemExit("\n".join(errors))
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        print(f"\n{len(units)} demos ({', '.join(u.object for u in units)}), n = {args.n} each, "
              "lift-drop\n| run | wall s | grasps | passed | grasps/s |\n| --- | --- | --- | --- | --- |")
        rows = [stats("local pool, 2 processes", *local(units, root / "local2", 2))]
        print(row(rows[-1]), flush=True)
        rows.append(stats("local pool, 1 process", *local(units, root / "local1", 1)))
        print(row(rows[-1]), flush=True)
        t0 = time.perf_counter()
        with ray_cluster(num_cpus=args.cpus):
            outcomes = run_on_ray(units, root / "ray", chunk=args.chunk)
        wall = time.perf_counter() - t0
        failed = [o.error for o in outcomes if o.summary is None]
        if failed:
            raise SystemExit(f"Ray units failed: {failed}")
        rows.append(stats(f"Ray, {args.cpus} local worker CPUs", wall,
                          [o.summary for o in outcomes if o.summary is not None]))
        print(row(rows[-1]))
        equal = same(tables(root / "local1"), tables(root / "ray"))
        print(f"Ray datasets equal the 1-process local ones: {equal}")
    hands = {u.hand for u in units}
    path = write_record("ray", rows, summary={"ray_equals_local": equal},
                        config={**vars(args), "demos": [str(d) for d in DEMOS]},
                        hand=next(iter(hands)) if len(hands) == 1 else None,
                        objects=sorted({u.object for u in units}))
    print(f"record: {path}")


if __name__ == "__main__":
    main()
