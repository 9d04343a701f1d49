"""Validation speed: grasps/s and simulated steps/s, stepping from Python vs on mujoco.batch.

Workload: FSG grasps of one object (``--grasps FILE``: a dataset from ``dexaug generate
--validate none``; made here with seed 0 on the hand's manual workspace when the file does not
exist). Rows, all on the same grasps:

- ``python loop``: ``Validator.validate`` grasp by grasp in this process (MuJoCo stepped from
  Python, as every protocol ran before sim.validate.batched);
- ``batch, T threads``: the grasps on one ``mujoco.batch`` runner (sim.validate.batched) of
  ``BATCH_SIMS`` simulations and T threads in this process;
- ``validate_many, W processes``: the library default (each worker validates its chunks
  grasp by grasp), workers started and their validators built before the clock starts.

Steps are counted by running each grasp's program once (they are the same in every row), and
every row's verdicts are compared with the python loop's. Prints one Markdown table and writes
its rows as a record (:func:`benchmarks.record.write_record`,
``benchmarks/measured/validate_speed/``).

    .venv/bin/python benchmarks/bench_validate_speed.py [--object 005_tomato_soup_can] [--n 1000]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from augment.autows.build import build_workspace
from augment.object_cloud import object_cloud
from benchmarks.record import write_record
from dexaug.pipeline.run import generate_grasps
from sim.grasp import Grasp
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.validate.batched import BatchRunner, validate_batched
from sim.validate.program import Advance
from sim.validate.validator import BATCH_SIMS, Validator
from sim.world.objects import load_object


def load_grasps(path: Path, hand: Hand, obj: str, n: int) -> list[Grasp]:
    if not path.exists():
        res = generate_grasps(hand, object_cloud(load_object(obj)), build_workspace(hand), n=n,
                              seed=0, workers=2, time_budget_s=600.0)
        table = dataset.from_fsg(res.grasps, hand.joint_names, hand.finger_names, None)
        dataset.save(path, {obj: table})
    t = dataset.load(path)[obj]
    pose, q = t["palm_pose"], t["hand_pose"]
    return [Grasp.from_arrays(pose[i, :3], pose[i, 3:], q[i]) for i in range(min(n, len(t)))]


def count_steps(v: Validator, grasps: list[Grasp], protocol: str) -> int:
    """Simulated steps of all grasps: each program run here, its Advance lengths summed."""
    from sim.validate.program import run_here

    total = 0
    for g in grasps:
        _, program = v.start(g, protocol)
        if program is None:
            continue

        def counted(p=program):
            nonlocal total
            for req in p:
                if isinstance(req, Advance):
                    total += req.nstep
                yield req

        run_here(v.scene(protocol), counted())
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--object", default="005_tomato_soup_can")
    parser.add_argument("--n", type=int, default=1000)
    parser.add_argument("--protocol", default="lift-drop", choices=["lift-drop", "six-dir"])
    parser.add_argument("--grasps", type=Path, default=Path("/tmp/dexaug_bench_grasps.h5"))
    parser.add_argument("--loop-n", type=int, default=300,
                        help="grasps timed in the python loop row (it is the slow one)")
    args = parser.parse_args()
    hand = Hand.load(default_hand_name())
    grasps = load_grasps(args.grasps, hand, args.object, args.n)
    v = Validator(hand, load_object(args.object))
    steps = count_steps(v, grasps, args.protocol)
    per_grasp = steps / len(grasps)
    rows: list[dict[str, Any]] = []

    def row(name: str, n: int, seconds: float, verdicts: list, ref: list) -> None:
        rate = n / seconds
        rows.append({"path": name, "grasps": n, "passed": sum(p for p, _ in verdicts),
                     "grasps_per_s": rate, "steps_per_s": rate * per_grasp,
                     "agree": sum(a == b for a, b in zip(verdicts, ref, strict=False)),
                     "compared": min(len(verdicts), len(ref))})

    loop = grasps[:args.loop_n]
    t0 = time.perf_counter()
    ref = [(r.passed, r.failure) for r in (v.validate(g, args.protocol) for g in loop)]
    row("python loop, 1 process", len(loop), time.perf_counter() - t0, ref, ref)
    for threads in (1, 2):
        t0 = time.perf_counter()
        runner = BatchRunner(v.scene(args.protocol), BATCH_SIMS, threads)
        res = validate_batched(runner, grasps,
                               lambda g, view: v.start(g, args.protocol, scene=view))
        row(f"batch, {threads} thread(s), 1 process", len(grasps), time.perf_counter() - t0,
            [(r.passed, r.failure) for r in res], ref)
    for workers in (1, 2):
        validate_many(hand.name, args.object, grasps[:workers * 4], args.protocol, workers=workers)
        t0 = time.perf_counter()
        res = validate_many(hand.name, args.object, grasps, args.protocol, workers=workers)
        row(f"validate_many, {workers} process(es)", len(grasps), time.perf_counter() - t0,
            [(r.passed, r.failure) for r in res], ref)
    print(f"{args.object}, {args.protocol}, {len(grasps)} FSG grasps, {per_grasp:.0f} simulated "
          f"steps per grasp on average")
    print("| path | grasps | passed | grasps/s | steps/s | verdicts = python loop |")
    print("| --- | --- | --- | --- | --- | --- |")
    print("\n".join(f"| {r['path']} | {r['grasps']} | {r['passed']} | {r['grasps_per_s']:.1f} | "
                    f"{r['steps_per_s']:,.0f} | {r['agree']}/{r['compared']} |" for r in rows))
    path = write_record("validate_speed", rows, summary={"steps_per_grasp": per_grasp},
                        config=vars(args), hand=hand.name, objects=[args.object])
    print(f"record: {path}")


if __name__ == "__main__":
    main()
