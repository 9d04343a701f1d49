"""AutoWS workspace-cloud build times and sizes for every hand config, on one core.

Run: ``.venv/bin/python benchmarks/bench_workspace.py [--repeats N] [--hands HAND ...]``.

For each hand: per-finger point counts, faces and memory, then the time to build all clouds
from the manual ranges (the paper's Table 1 for the Shadow Hand) and from a demonstration,
cold (in-memory fingertip caches cleared, empty disk cache in a temporary ``DEXAUG_CACHE_DIR``)
and cached (the ``.npz`` read back from the disk cache). Targets (issue): < 2 s cold, < 50 ms
cached. The demo is synthetic: each independent joint at the middle of its manual range,
contacts at the fingertip surface point nearest the pulp site. Times are the best of
``--repeats`` runs; the hand model load is reported separately. One row per hand and source
(manual ranges, demo) goes to a record as well (:func:`benchmarks.record.write_record`,
``benchmarks/measured/workspace/``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from augment.autows.build import build_workspace  # noqa: E402
from augment.autows.cache import cache_path  # noqa: E402
from augment.autows.cloud import WorkspaceCloud  # noqa: E402
from augment.autows.fingertip import clear_caches, hand_fingertip_faces  # noqa: E402
from augment.autows.params import load_autows_params  # noqa: E402
from augment.autows.seed import DemoSeed  # noqa: E402
from benchmarks.record import write_record  # noqa: E402
from sim.hand.config import hand_names  # noqa: E402
from sim.hand.model import Hand  # noqa: E402


def synthetic_demo(hand: Hand) -> DemoSeed:
    q = np.zeros(hand.nq)
    for f in hand.config.fingers:
        for joint, (lo, hi) in f.ranges_rad.items():
            q[hand.joint_names.index(joint)] = 0.5 * (lo + hi)
    q = hand.clip(hand.fill_coupled(q))
    contacts = {}
    for f in hand.config.fingers:
        surface = hand_fingertip_faces(hand, f.name).cloud_points
        contacts[f.name] = surface[np.argmin(np.linalg.norm(surface - f.tip_site_pos, axis=1))]
    return DemoSeed(joints=q, contacts=contacts, id=f"{hand.name}-synthetic")


def time_builds(hand: Hand, demo: DemoSeed | None,
                repeats: int) -> tuple[float, float, WorkspaceCloud, int]:
    """Best cold and cached wall times (seconds) of build_workspace, the cloud and the size of
    its cache file (bytes)."""
    params = load_autows_params()
    cold, cached = [], []
    cloud, size = None, 0
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            os.environ["DEXAUG_CACHE_DIR"] = tmp
            clear_caches()
            t0 = time.perf_counter()
            cloud = build_workspace(hand, params, demo)
            cold.append(time.perf_counter() - t0)
            assert not cloud.from_cache
            t0 = time.perf_counter()
            again = build_workspace(hand, params, demo)
            cached.append(time.perf_counter() - t0)
            assert again.from_cache
            size = cache_path(hand, cloud.provenance["key"]).stat().st_size
    assert cloud is not None
    return min(cold), min(cached), cloud, size


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--hands", nargs="+", default=hand_names())
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    print(f"AutoWS benchmark, one core, best of {args.repeats}")
    rows = []
    for name in args.hands:
        t0 = time.perf_counter()
        hand = Hand.load(name)
        t_load = time.perf_counter() - t0
        demo = synthetic_demo(hand)
        print(f"\n== {name} (hand load {t_load * 1e3:.0f} ms)")
        for label, seed in (("manual ranges", None), ("demo", demo)):
            cold, cached, cloud, size = time_builds(hand, seed, args.repeats)
            print(f"-- {label}: cold {cold * 1e3:.0f} ms, cached {cached * 1e3:.1f} ms, "
                  f"{cloud.nbytes / 1e6:.2f} MB in memory, cache file {size / 1e6:.2f} MB")
            print(f"   {'finger':<12}{'points':>8}{'faces':>7}{'combos':>8}{'skel pts':>10}"
                  f"{'MB':>8}")
            fingers = []
            for f in cloud.fingers:
                combos = int(np.prod([len(v) for v in
                                      cloud.provenance["grids_rad"][f.name].values()]))
                print(f"   {f.name:<12}{f.n_points:>8}{f.n_faces:>7}{combos:>8}"
                      f"{f.skeleton.shape[1]:>10}{f.nbytes / 1e6:>8.2f}")
                fingers.append({"finger": f.name, "points": f.n_points, "faces": f.n_faces,
                                "combos": combos, "skeleton_points": f.skeleton.shape[1],
                                "mb": f.nbytes / 1e6})
            rows.append({"hand": name, "source": label, "hand_load_ms": t_load * 1e3,
                         "cold_ms": cold * 1e3, "cached_ms": cached * 1e3,
                         "memory_mb": cloud.nbytes / 1e6, "cache_file_mb": size / 1e6,
                         "fingers": fingers})
    path = write_record("workspace", rows, config=vars(args),
                        hand=args.hands[0] if len(args.hands) == 1 else None)
    print(f"record: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
