"""Before/after a change: the same augmentation bit for bit, and no slowdown of validation.

Why: a refactor (issue #51's protocol plug-ins) or a speed-up (#53) promises "identical
verdicts and pass counts, no slowdown"; this measures it between two commits instead of
asserting it. Each commit is checked out into its own git worktree (``../shared`` linked beside
it) and run by this venv's Python with that worktree first on ``PYTHONPATH``:

- ``dexaug augment`` of the committed demos (``recordings/demo_*.mcap``; ``--n`` grasps each,
  seed 0, one worker) at both commits, then every HDF5 dataset both results hold is compared
  bit for bit (NaN equal to NaN); columns one side adds are listed, not compared;
- ``benchmarks/bench_validate_speed.py`` (grasps/s on one FSG dataset, made once and shared)
  alternately before, after, before, after (``--rounds``), so machine load falls on both.

One record (:func:`benchmarks.record.write_record`, ``benchmarks/measured/before_after/``):
rows per demo (pass counts, datasets compared and equal, columns only one side has) and per
speed run (commit, round, path, grasps/s).

    .venv/bin/python benchmarks/bench_before_after.py BEFORE AFTER [--n 60] [--speed-n 200]
        [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
from sim.paths import REPO_ROOT

SPEED_ROW = re.compile(r"^\| (?P<path>[^|]+?) \| (?P<grasps>\d+) \| (?P<passed>\d+) \| "
                       r"(?P<rate>[\d.]+) \|")
PASSED = re.compile(r"^(?P<demo>\S+): (?P<passed>\d+)/(?P<n>\d+) passed")


def worktree(rev: str, parent: Path) -> Path:
    """A checkout of ``rev`` under ``parent`` with ``../shared`` beside it."""
    where = parent / rev[:12]
    subprocess.run(["git", "worktree", "add", "-q", "--detach", str(where), rev], cwd=REPO_ROOT,
                   check=True)
    shared = parent / "shared"
    if not shared.exists():
        shared.symlink_to(REPO_ROOT.parent / "shared")
    return where


def run_in(tree: Path, args: list[str]) -> str:
    """Run this venv's Python in ``tree`` with ``tree`` first on the path; its stdout+stderr."""
    env = {**os.environ, "PYTHONPATH": str(tree), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"),
           "DEXAUG_RECORD_DIR": str(tree / "records")}
    done = subprocess.run([sys.executable, *args], cwd=tree, env=env, capture_output=True,
                          text=True, check=False)
    if done.returncode not in (0, 3):
        raise SystemExit(f"{tree.name}: {' '.join(args[:3])} exited {done.returncode}:\n"
                         f"{done.stdout[-2000:]}{done.stderr[-2000:]}")
    return done.stdout + done.stderr


def h5_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every dataset of an HDF5 file by its path."""
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
    return out


def same(a: np.ndarray, b: np.ndarray) -> bool:
    """Bit-for-bit equal arrays (NaN equal to NaN)."""
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))


def compare_augment(before: Path, after: Path, n: int) -> list[dict[str, Any]]:
    """Augment the committed demos at both commits; one row per demo."""
    demos = sorted(str(p.relative_to(REPO_ROOT)) for p in (REPO_ROOT / "recordings").glob("demo_*.mcap"))
    passed: dict[str, dict[str, str]] = {}
    for tag, tree in (("before", before), ("after", after)):
        log = run_in(tree, ["-m", "dexaug.cli", "augment", *demos, "--n", str(n), "--seed", "0",
                            "--workers", "1", "--out", str(tree / "out"), "-q"])
        passed[tag] = {m["demo"]: m["passed"] for line in log.splitlines() if (m := PASSED.match(line))}
    rows = []
    for folder in sorted(p.name for p in (before / "out").iterdir() if p.is_dir()):
        a = h5_arrays(before / "out" / folder / "grasps.h5")
        b = h5_arrays(after / "out" / folder / "grasps.h5")
        both = sorted(set(a) & set(b))
        rows.append({"table": "augment", "demo": folder, "n": n,
                     "passed_before": int(passed["before"].get(folder, -1)),
                     "passed_after": int(passed["after"].get(folder, -1)),
                     "datasets_compared": len(both),
                     "datasets_equal": sum(same(a[k], b[k]) for k in both),
                     "only_before": sorted(set(a) - set(b)), "only_after": sorted(set(b) - set(a))})
    return rows


def compare_speed(before: Path, after: Path, n: int, rounds: int, grasps: Path) -> list[dict[str, Any]]:
    """``bench_validate_speed.py`` alternately at both commits; one row per printed path."""
    rows = []
    for r in range(rounds):
        for tag, tree in (("before", before), ("after", after)):
            out = run_in(tree, ["benchmarks/bench_validate_speed.py", "--n", str(n),
                                "--grasps", str(grasps)])
            rows += [{"table": "speed", "commit": tag, "round": r, "path": m["path"],
                      "grasps": int(m["grasps"]), "passed": int(m["passed"]),
                      "grasps_per_s": float(m["rate"])}
                     for line in out.splitlines() if (m := SPEED_ROW.match(line))]
    return rows


def speed_summary(speed: list[dict[str, Any]]) -> dict[str, Any]:
    """Per speed path the median grasps/s over the rounds at each commit, and after/before.

    Why medians: one round on a 2-core machine moves by up to a fifth when anything else runs
    (a python-loop round read 16.0 and then 13.3 grasps/s on the same commit), so a mean of two
    rounds reads load as a slowdown; the median of several alternating rounds does not.
    """
    out: dict[str, Any] = {"median_grasps_per_s": {}}
    for path in dict.fromkeys(r["path"] for r in speed):
        med = {tag: float(np.median([r["grasps_per_s"] for r in speed
                                     if r["path"] == path and r["commit"] == tag]))
               for tag in ("before", "after")}
        out["median_grasps_per_s"][path] = {**med, "after_over_before": med["after"] / med["before"]}
    ratios = [v["after_over_before"] for v in out["median_grasps_per_s"].values()]
    out["after_over_before_geomean"] = float(np.exp(np.mean(np.log(ratios)))) if ratios else None
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before", help="the commit before the change")
    ap.add_argument("after", nargs="?", default="HEAD", help="the commit after it (default HEAD)")
    ap.add_argument("--n", type=int, default=60, help="grasps per committed demo (default 60)")
    ap.add_argument("--speed-n", type=int, default=200, help="grasps of the speed runs (default 200)")
    ap.add_argument("--rounds", type=int, default=3,
                    help="alternating before/after speed rounds, medians taken (default 3)")
    args = ap.parse_args()
    revs = {tag: subprocess.run(["git", "rev-parse", rev], cwd=REPO_ROOT, capture_output=True,
                                text=True, check=True).stdout.strip()
            for tag, rev in (("before", args.before), ("after", args.after))}
    with tempfile.TemporaryDirectory(prefix="dexaug-before-after-") as tmp:
        parent = Path(tmp)
        trees = {tag: worktree(rev, parent) for tag, rev in revs.items()}
        try:
            rows = compare_augment(trees["before"], trees["after"], args.n)
            rows += compare_speed(trees["before"], trees["after"], args.speed_n, args.rounds,
                                  parent / "speed_grasps.h5")
        finally:
            for tree in trees.values():
                subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=REPO_ROOT,
                               check=False)
    aug = [r for r in rows if r["table"] == "augment"]
    summary = {"before": revs["before"], "after": revs["after"],
               "demos_identical": sum(r["datasets_equal"] == r["datasets_compared"] and
                                      r["passed_before"] == r["passed_after"] for r in aug),
               "demos": len(aug)}
    summary.update(speed_summary([r for r in rows if r["table"] == "speed"]))
    for r in aug:
        print(f"{r['demo']}: passed {r['passed_before']} → {r['passed_after']} of {r['n']}; "
              f"{r['datasets_equal']}/{r['datasets_compared']} datasets bit-identical; "
              f"only after: {r['only_after']}")
    for path, med in summary["median_grasps_per_s"].items():
        print(f"{path}: median grasps/s before {med['before']:.1f}, after {med['after']:.1f} "
              f"({med['after_over_before']:.3f}x)")
    path = write_record("before_after", rows, summary=summary,
                        config={"n": args.n, "speed_n": args.speed_n, "rounds": args.rounds})
    print(f"record: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
