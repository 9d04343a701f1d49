"""Per-frame retargeting latency and accuracy on the real Quest 3 capture (right hand → robot hand).

Run: ``.venv/bin/python benchmarks/bench_retarget.py [--repeats N] [--hand NAME]`` (default: the
default hand, ``configs/hands/default.toml``).

DESIGN §6 budgets ≤ 1 ms median and ≤ 3 ms p99 per frame on one core, so the process is pinned
to one CPU and BLAS threads are limited to one before NumPy loads. The capture is replayed
``--repeats`` times (after one warm-up pass) with the configured IK iterations and, for
comparison, with 1–3 iterations; the table gives per-frame wall time of ``Retargeter.step``
(frames where the hand is missing are excluded), fingertip errors (scaled operator target vs
achieved robot pulp site) and the robot thumb–index pulp distance at the capture's pinch and
open-hand frames (acceptance: < 2 cm at the three closest pinch frames, > 6 cm where the
operator's thumb–index distance is over 8 cm).

Then contact-aware retargeting on human grasps that touch the object (the synthetic human hand
closing its pads onto 005_tomato_soup_can and 004_sugar_box, through the synthetic headset
sensor; ``tests/test_retarget_contact.py`` builds and measures them): the median distance of
the retargeted robot pads (forward kinematics of the IK solution, world frame) to the object
surface over the grasp phase, for the legacy mapping (tip-joint targets, no phalanx tasks, no
snapping), pad targets + phalanx tasks without the object, and with the object's surface
given (snapping; acceptance ≤ 3 mm), with the per-frame wall time of each; once with the
tracked pads on the surface and once 5 mm in front of it (real tracked grasps: 3–7 mm).

Both tables' rows go to a record as well (:func:`benchmarks.record.write_record`,
``benchmarks/measured/retarget/``; ``table``: iterations or contact).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from benchmarks.record import write_record  # noqa: E402
from sim.hand.config import default_hand_name  # noqa: E402
from sim.hand.model import Hand  # noqa: E402
from sim.paths import SHARED_ASSETS  # noqa: E402
from teleop.input.iwer import iwer_hand_frames, load_iwer_capture  # noqa: E402
from teleop.messages import JOINT_INDEX  # noqa: E402
from teleop.retarget.config import load_retarget_config  # noqa: E402
from teleop.retarget.retargeter import Retargeter  # noqa: E402
from teleop.retarget.trace import RetargetTrace, retarget_frames  # noqa: E402

CAPTURE = SHARED_ASSETS / "handdata" / "quest3_webxr" / "cap.min.js"


def _pin_one_core() -> str:
    if hasattr(os, "sched_setaffinity"):
        cpu = sorted(os.sched_getaffinity(0))[-1]
        os.sched_setaffinity(0, {cpu})
        return f"pinned to CPU {cpu}"
    return "not pinned (no sched_setaffinity)"


def _run(hand: Hand, config, frames, repeats: int) -> tuple[RetargetTrace, np.ndarray]:
    rt = Retargeter(hand, config)
    rt.calibrate_scale(frames)
    retarget_frames(rt, frames)  # warm-up: imports, caches, first-call allocations
    times = []
    trace = None
    for _ in range(repeats):
        rt.reset()
        trace = retarget_frames(rt, frames)
        times.append(trace.step_time_s[~trace.held])
    assert trace is not None
    return trace, np.concatenate(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed passes over the capture")
    parser.add_argument("--hand", default=default_hand_name())
    parser.add_argument("--capture", type=Path, default=CAPTURE)
    args = parser.parse_args()

    pinned = _pin_one_core()
    hand = Hand.load(args.hand)
    config = load_retarget_config()
    frames = iwer_hand_frames(load_iwer_capture(args.capture))
    side = config.hand(hand.name).side
    ops = np.array([np.linalg.norm(h.positions[JOINT_INDEX["thumb_tip"]]
                                   - h.positions[JOINT_INDEX["index_tip"]])
                    if (h := f.hand(side)) is not None and h.tracked else np.nan
                    for f in frames])
    pinch = np.argsort(np.nan_to_num(ops, nan=np.inf))[:3]
    open_ = ops > 0.08
    thumb, fore = hand.finger_names.index("thumb"), hand.finger_names.index("forefinger")

    print(f"capture {args.capture.name}: {len(frames)} hand frames ({side} hand), "
          f"hand {hand.name}, {pinned}, repeats {args.repeats}")
    print(f"operator thumb–index at the pinch frames: "
          f"{', '.join(f'{d * 100:.2f}' for d in ops[pinch])} cm; open frames (> 8 cm): "
          f"{int(open_.sum())}")
    print()
    header = (f"{'iters':>5} {'median ms':>9} {'p99 ms':>7} {'max ms':>7} | "
              f"{'pinch robot cm':>20} {'open min cm':>11} | fingertip error median / p95 mm")
    print(header)
    print("-" * (len(header) + 40))
    iterations = sorted({config.iterations, 1, 2, 3})
    rows: list[dict[str, Any]] = []
    for iters in iterations:
        cfg = dataclasses.replace(config, iterations=iters)
        trace, times = _run(hand, cfg, frames, args.repeats)
        tips = hand.fingertip_sites(trace.q)
        robot = np.linalg.norm(tips[:, thumb] - tips[:, fore], axis=-1)
        live = ~trace.held
        err = trace.tip_errors_m[live] * 1e3
        errs = "  ".join(f"{n[:5]} {np.median(err[:, k]):.1f}/{np.percentile(err[:, k], 95):.1f}"
                         for k, n in enumerate(trace.finger_names))
        mark = "*" if iters == config.iterations else " "
        print(f"{iters:>4}{mark} {np.median(times) * 1e3:9.3f} {np.percentile(times, 99) * 1e3:7.3f} "
              f"{times.max() * 1e3:7.3f} | "
              f"{', '.join(f'{d * 100:.2f}' for d in robot[pinch]):>20} "
              f"{robot[open_].min() * 100:11.2f} | {errs}")
        rows.append({"table": "iterations", "iterations": iters,
                     "configured": iters == config.iterations,
                     "median_ms": float(np.median(times) * 1e3),
                     "p99_ms": float(np.percentile(times, 99) * 1e3),
                     "max_ms": float(times.max() * 1e3), "pinch_robot_cm": robot[pinch] * 100,
                     "open_min_cm": float(robot[open_].min() * 100),
                     "tip_error_mm": {n: {"median": float(np.median(err[:, k])),
                                          "p95": float(np.percentile(err[:, k], 95))}
                                      for k, n in enumerate(trace.finger_names)}})
    print()
    print("* = configured (configs/teleop.toml [retarget] iterations); budget: median ≤ 1 ms, "
          "p99 ≤ 3 ms")
    rows += _contact(hand, config, args.repeats)
    path = write_record("retarget", rows,
                        config={**vars(args), "pinned": pinned, "ik_iterations": config.iterations,
                                "operator_pinch_cm": ops[pinch] * 100,
                                "open_frames": int(open_.sum())},
                        hand=hand.name)
    print(f"record: {path}")


def _contact(hand: Hand, config, repeats: int) -> list[dict[str, Any]]:
    """The contact section of the module docstring: prints its table, returns its rows."""
    from tests.test_retarget_contact import (
        OBJECTS,
        legacy_config,
        pad_surface_distances,
        retarget_episode,
        touching_episode,
    )

    print()
    print(f"{'object':>20} {'gap':>4} {'mapping':>22} | {'pad–surface median mm':>21} "
          f"{'per finger mm':>28} | {'median ms':>9} {'p99 ms':>7}")
    print("-" * 120)
    rows = []
    variants = (("legacy (tip joints)", legacy_config(config), False),
                ("pads + phalanges", config, False), ("pads + phalanges + snap", config, True))
    for name, gap_m in ((n, g) for g in (0.0, 0.005) for n in OBJECTS):
        ep = touching_episode(hand, name, seed=3, gap_m=gap_m)
        for label, cfg, snap in variants:
            times = []
            for _ in range(repeats):
                rt, _ = retarget_episode(hand, cfg, ep, snap)   # warm-up pass, then timed
                rt.reset()
                trace = retarget_frames(rt, ep.frames)
                times.append(trace.step_time_s[~trace.held])
            rt, results = retarget_episode(hand, cfg, ep, snap)
            d = pad_surface_distances(hand, rt, ep, results) * 1e3
            per = " ".join(f"{f[:5]} {v:.1f}" for f, v in zip(ep.touching, np.median(d, axis=0),
                                                               strict=True))
            t = np.concatenate(times) * 1e3
            print(f"{name:>20} {gap_m * 1e3:4.0f} {label:>22} | {np.median(d):21.2f} {per:>28} | "
                  f"{np.median(t):9.3f} {np.percentile(t, 99):7.3f}")
            rows.append({"table": "contact", "object": name, "gap_mm": gap_m * 1e3,
                         "mapping": label, "pad_surface_median_mm": float(np.median(d)),
                         "per_finger_mm": dict(zip(ep.touching, np.median(d, axis=0), strict=True)),
                         "median_ms": float(np.median(t)), "p99_ms": float(np.percentile(t, 99))})
    print("gap: where the tracked human pads stop in front of the surface (mm; real tracked grasps: "
          "3–7); fingers: those whose pad is at that gap at the grasp; acceptance: pad–surface "
          "median ≤ 3 mm with snapping")
    return rows


if __name__ == "__main__":
    main()
