"""Early exit (issue #53): grasps/s and MuJoCo steps per grasp with each protocol's
``early_exit`` off and on, on the same grasps, and how many verdicts (and whole results) agree.

Workload: FSG grasps (seed 0, the hand's manual workspace; made with
:func:`benchmarks.bench_validate_speed.load_grasps` into ``--grasps-dir`` when absent):

- ``lift-drop`` on ``--lift-object`` (005_tomato_soup_can, the issue's 44.9/s baseline):
  lift-drop has no early exit beyond its own (``sim/validate/lift_drop.py``), so there is one
  row, and the summary says why none is possible: the share of steps that passing grasps, which
  must run every phase, take, and the speed-up an oracle that knew every failure before
  simulating anything would give (``oracle_bound``);
- ``six-dir`` on the first ``--n-six`` of them, ``[six_dir] early_exit`` off and on;
- ``dgb`` as ``dexaug generate --validate dgb`` runs it (the ``dexaug`` convention: stages
  derived, rehearsed, then the benchmark) on ``--dgb-objects``, ``[dgb] early_exit`` off and on.

Each configuration is run twice: once grasp by grasp in this process with MuJoCo's steps
counted (a counter around ``mujoco.mj_step``, through which every protocol steps) and timed,
off and on interleaved grasp by grasp (``ms_per_grasp_in_process``; a shared machine's load
drifts alike over both), and once timed on ``--workers`` processes
(:func:`sim.validate.batch.validate_many`, validators built before the clock starts), which is
how the pipeline validates. ``ms_per_grasp_per_core`` is that wall time × workers / grasps.
Writes ``benchmarks/measured/early_exit/<UTC>-<commit>.json``.

    .venv/bin/python benchmarks/bench_early_exit.py [--n-lift 400] [--n-six 100] [--n-dgb 40]
        [--dgb-objects 005_tomato_soup_can 003_cracker_box] [--protocols ...] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import mujoco

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_validate_speed import load_grasps
from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.validate.batch import cached_validator, validate_many
from sim.validate.config import VALIDATE_TOML
from sim.validate.result import ValidationResult

#: the config section holding each protocol's switch (None: it has none)
SECTIONS = {"lift-drop": None, "six-dir": "six_dir", "dgb": "dgb"}


@contextmanager
def counted_steps() -> Iterator[list[int]]:
    """``[n]``: MuJoCo steps taken in this process inside the block (the real step, counted)."""
    real, counter = mujoco.mj_step, [0]

    def step(m: mujoco.MjModel, d: mujoco.MjData, nstep: int = 1) -> None:
        counter[0] += nstep
        real(m, d, nstep=nstep)

    mujoco.mj_step = step
    try:
        yield counter
    finally:
        mujoco.mj_step = real


def config_file(folder: Path, section: str, early_exit: bool) -> Path:
    """configs/validate.toml with ``[section] early_exit`` set, written into ``folder``."""
    head, sep, tail = VALIDATE_TOML.read_text().partition(f"[{section}]")
    assert sep and "early_exit = true" in tail, f"[{section}] has no early_exit line"
    path = folder / f"validate_{section}_{'on' if early_exit else 'off'}.toml"
    path.write_text(head + sep + tail.replace("early_exit = true",
                                              f"early_exit = {str(early_exit).lower()}", 1))
    return path


@dataclass
class InProcess:
    """Grasp by grasp in this process under one config: steps, results, seconds in all."""

    steps: list[int] = field(default_factory=list)
    results: list[ValidationResult] = field(default_factory=list)
    seconds: float = 0.0


def in_process(hand: str, obj: str, grasps: Sequence[Grasp], protocol: str,
               configs: Sequence[Path | None]) -> list[InProcess]:
    """Each grasp validated here under every config in turn, its steps counted and timed.
    Interleaved grasp by grasp, so that the load of a shared machine, which drifts over
    minutes, weighs on every config alike."""
    validators = [cached_validator(hand, obj, None if c is None else str(c)) for c in configs]
    runs = [InProcess() for _ in configs]
    with counted_steps() as n:
        for g in grasps:
            for v, run in zip(validators, runs, strict=True):
                n[0] = 0
                t0 = time.perf_counter()
                run.results.append(v.validate(g, protocol))
                run.seconds += time.perf_counter() - t0
                run.steps.append(n[0])
    return runs


def timed(hand: str, obj: str, grasps: Sequence[Grasp], protocol: str, config: Path | None,
          workers: int) -> tuple[float, list[ValidationResult]]:
    """Wall seconds of validating ``grasps`` on ``workers`` processes, and the results."""
    validate_many(hand, obj, grasps[:workers * 4], protocol, workers=workers, config_path=config)
    t0 = time.perf_counter()
    results = validate_many(hand, obj, grasps, protocol, workers=workers, config_path=config)
    return time.perf_counter() - t0, results


def _flat(r: ValidationResult) -> str:
    return json.dumps(r.summary(), default=str, sort_keys=True)


def measure(hand: str, obj: str, grasps: Sequence[Grasp], protocol: str, config: Path | None,
            workers: int, early_exit: bool | None, here: InProcess) -> dict[str, object]:
    """One row: ``here``'s counted steps, outcomes and one-process time, and the speed on
    ``workers`` processes."""
    steps, results = here.steps, here.results
    seconds, pooled = timed(hand, obj, grasps, protocol, config, workers)
    n = len(grasps)
    failing = [s for s, r in zip(steps, results, strict=True) if not r.passed]
    row: dict[str, object] = {
        "protocol": protocol, "object": obj, "early_exit": early_exit, "grasps": n,
        "passed": sum(bool(r.passed) for r in results),
        "failures": dict(Counter(str(r.failure) for r in results if not r.passed)),
        "workers": workers, "wall_s": round(seconds, 2), "grasps_per_s": round(n / seconds, 1),
        "ms_per_grasp_per_core": round(1e3 * seconds * workers / n, 1),
        "ms_per_grasp_in_process": round(1e3 * here.seconds / n, 1),
        "steps_per_grasp": round(sum(steps) / n, 1),
        "steps_per_failing_grasp": round(sum(failing) / len(failing), 1) if failing else None,
        "steps_share_of_passing": round(1 - sum(failing) / max(sum(steps), 1), 4),
        "stopped_early": sum(r.stopped_early is not None for r in results),
        "pool_equals_in_process": sum(_flat(a) == _flat(b) for a, b in zip(pooled, results, strict=True)),
    }
    return row


def compare(row: dict[str, object], base_row: dict[str, object], base: list[ValidationResult],
            steps_base: list[int], results: list[ValidationResult], steps: list[int]) -> None:
    """Add to ``row`` (early exit on) how it agrees with ``base`` (off) grasp by grasp."""
    pairs = list(zip(base, results, strict=True))
    row["verdicts_identical"] = sum(bool(a.passed) == bool(b.passed) and a.failure == b.failure
                                    for a, b in pairs)
    row["results_identical"] = sum(_flat(a) == _flat(b) for a, b in pairs)
    row["steps_saved_share"] = round(1 - sum(steps) / max(sum(steps_base), 1), 4)
    row["failing_grasps_with_fewer_steps"] = sum(
        s < s0 for s, s0, r in zip(steps, steps_base, results, strict=True) if not r.passed)
    row["failing_grasps"] = sum(not r.passed for r in results)
    row["grasps_with_more_steps"] = sum(s > s0 for s, s0 in zip(steps, steps_base, strict=True))
    row["speedup_pool"] = round(float(row["grasps_per_s"]) / float(base_row["grasps_per_s"]), 3)  # type: ignore[arg-type]
    row["speedup_in_process"] = round(float(base_row["ms_per_grasp_in_process"])  # type: ignore[arg-type]
                                      / float(row["ms_per_grasp_in_process"]), 3)  # type: ignore[arg-type]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--lift-object", default="005_tomato_soup_can")
    ap.add_argument("--n-lift", type=int, default=400, help="grasps for lift-drop")
    ap.add_argument("--n-six", type=int, default=100, help="grasps for six-dir (the first of lift-drop's)")
    ap.add_argument("--dgb-objects", nargs="+", default=["005_tomato_soup_can", "003_cracker_box"])
    ap.add_argument("--n-dgb", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--grasps-dir", type=Path, default=Path(tempfile.gettempdir()))
    ap.add_argument("--protocols", nargs="+", default=list(SECTIONS), choices=list(SECTIONS))
    args = ap.parse_args()
    hand = Hand.load(default_hand_name())
    rows: list[dict[str, object]] = []
    summary: dict[str, object] = {}
    jobs = [("lift-drop", args.lift_object, args.n_lift), ("six-dir", args.lift_object, args.n_six)] + \
        [("dgb", o, args.n_dgb) for o in args.dgb_objects]
    with tempfile.TemporaryDirectory() as tmp:
        for protocol, obj, n in jobs:
            if protocol not in args.protocols:
                continue
            # one file per object, made with the most grasps any protocol asks of it
            most = max(k for _, o, k in jobs if o == obj)
            grasps = load_grasps(args.grasps_dir / f"dexaug_early_exit_{obj}_{most}.h5", hand, obj, n)
            section = SECTIONS[protocol]
            if section is None:
                (here,) = in_process(hand.name, obj, grasps, protocol, [None])
                steps, results = here.steps, here.results
                row = measure(hand.name, obj, grasps, protocol, None, args.workers, None, here)
                rows.append(row)
                print(json.dumps(row), flush=True)
                floor = sum(s for s, r in zip(steps, results, strict=True) if r.passed) + \
                    sum(min(s, 1) for s, r in zip(steps, results, strict=True) if not r.passed)
                summary[f"{protocol} {obj}"] = {
                    "grasps_per_s": row["grasps_per_s"],
                    "steps_share_of_passing": row["steps_share_of_passing"],
                    # every failure known before its first step, every pass simulated in full
                    "oracle_bound": round(sum(steps) / max(floor, 1), 3)}
                continue
            files = [config_file(Path(tmp), section, e) for e in (False, True)]
            here_off, here_on = in_process(hand.name, obj, grasps, protocol, files)
            off = measure(hand.name, obj, grasps, protocol, files[0], args.workers, False, here_off)
            on = measure(hand.name, obj, grasps, protocol, files[1], args.workers, True, here_on)
            compare(on, off, here_off.results, here_off.steps, here_on.results, here_on.steps)
            rows += [off, on]
            print(json.dumps(off), json.dumps(on), sep="\n", flush=True)
            summary[f"{protocol} {obj}"] = {
                k: on[k] for k in ("speedup_pool", "speedup_in_process", "steps_saved_share",
                                   "verdicts_identical", "results_identical", "grasps")} | {
                "steps_per_grasp_off_on": [off["steps_per_grasp"], on["steps_per_grasp"]],
                "ms_per_grasp_per_core_off_on": [off["ms_per_grasp_per_core"],
                                                 on["ms_per_grasp_per_core"]],
                "ms_per_grasp_in_process_off_on": [off["ms_per_grasp_in_process"],
                                                   on["ms_per_grasp_in_process"]]}
    for key, value in summary.items():
        print(key, value)
    bad = [r for r in rows if r.get("verdicts_identical", r["grasps"]) != r["grasps"]
           or not math.isfinite(float(r["grasps_per_s"]))]  # type: ignore[arg-type]
    path = write_record("early_exit", rows, summary=summary,
                        config={"workers": args.workers, "n_lift": args.n_lift, "n_six": args.n_six,
                                "n_dgb": args.n_dgb,
                                "grasps": "FSG seed 0, manual workspace",
                                "protocols": args.protocols},
                        hand=hand.name, objects=sorted({o for _, o, _ in jobs}))
    print(f"record: {path}")
    if bad:
        raise SystemExit(f"verdicts differ with early exit: {bad}")


if __name__ == "__main__":
    main()
