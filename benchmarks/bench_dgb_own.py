"""``dgb`` against DexGraspBench's own evaluator on fresh grasps of held-out objects: agreement
and time per grasp on one core (issues #53, #54).

Per object, as a user would: ``dexaug generate --object X --validate dgb --n N`` (the default
squeeze convention and mode), ``dexaug export --format dexgraspbench --rejected``, then DGB's
unmodified ``fcMocapEval`` in its own venv with its pinned MuJoCo 3.3.2 / numpy 1.26.4
(``benchmarks/outside/dgb_own/run_dgb.py``, built by ``setup.sh`` there; the glue reproduces
all 300 recorded verdicts of ``../shared/reference/dexgraspbench/grasps.jsonl``). Printed per
object: how often generate's verdict and DGB's agree (count, %, Cohen's κ), the grasps we pass
and DGB fails and the reverse; and ms per grasp on one core: DGB's evaluator (the whole
``fcMocapEval`` constructor + ``run()``, which builds its model per grasp and computes its
analytic metrics too, and its simulation part alone) against our ``dgb`` as ``generate`` runs
it (stages derived: derive + rehearse + run) and with the stages given (the dataset's
pregrasp / grasp stage / squeeze), both in this process, one worker, one grasp at a time on
the same grasps, after the validator of the object is built (its one-off build time is listed).
Both sides are pinned to the same core (``--cpu``) and run one after the other. One record
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/dgb_own/``) with every grasp.

Without DGB's side venv this prints why and exits 0 (a skip). Objects default to held-out YCB
objects the ``dgb`` protocol was not developed on (not 004, 005, 043, 024, 062).

Usage: ``.venv/bin/python benchmarks/bench_dgb_own.py [--objects ...] [--n 50]
[--dgb-venv /tmp/exp/dgb-venv] [--cpu 1] [--quick]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment.dataset import load
from augment.grasp_table import grasp_stage_poses, with_rejected
from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.paths import REPO_ROOT
from sim.validate.batch import cached_validator, validate_many
from sim.validate.dgb_reference import cohen_kappa, reference_hand

RUNNER = REPO_ROOT / "benchmarks" / "outside" / "dgb_own" / "run_dgb.py"
SETUP = RUNNER.parent / "setup.sh"
#: the hand of DexGraspBench's reference file (its palm body names it), the hand DGB evaluates
HAND = reference_hand(REPO_ROOT.parent / "shared" / "reference" / "dexgraspbench" / "grasps.jsonl").name
DEFAULT_OBJECTS = ("006_mustard_bottle", "013_apple", "040_large_marker", "042_adjustable_wrench")


def dgb_python(venv: Path) -> Path | None:
    """The side venv's interpreter when the venv and DGB's source are both there."""
    py = venv / "bin" / "python"
    ok = py.is_file() and (venv / "dgb-src" / "src" / "task" / "eval_func" / "fc_mocap.py").is_file()
    return py if ok else None


def _run(cmd: list[str], what: str, ok: tuple[int, ...] = (0,)) -> None:
    """Run ``cmd``; a non-accepted exit status ends the benchmark with its output's tail."""
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode not in ok:
        tail = (proc.stdout + proc.stderr).strip().splitlines()[-5:]
        raise SystemExit(f"{what}: exit {proc.returncode}: " + " | ".join(tail))


def generate_and_export(obj: str, n: int, seed: int, workers: int, folder: Path) -> tuple[Path, Path]:
    """``dexaug generate`` (``dgb``, defaults otherwise) and its DGB JSONL export, every grasp."""
    h5, jsonl = folder / f"{obj}.h5", folder / f"{obj}.jsonl"
    h5.unlink(missing_ok=True)   # this benchmark's own earlier output (--keep): generate refuses it
    dexaug = [sys.executable, "-m", "dexaug"]
    _run([*dexaug, "generate", "--object", obj, "--validate", "dgb", "--n", str(n), "--seed",
          str(seed), "--workers", str(workers), "--out", str(h5), "-q"], f"generate {obj}", (0, 3))
    _run([*dexaug, "export", str(h5), "--format", "dexgraspbench", "--rejected", "--out",
          str(jsonl), "-q"], f"export {obj}")
    return h5, jsonl


def run_dgb(py: Path, jsonl: Path, cpu: int, out: Path) -> list[dict[str, Any]]:
    """DGB's verdicts and times per exported line (the side runner, one process, one core)."""
    _run([str(py), str(RUNNER), str(jsonl), "--out", str(out), "--cpu", str(cpu)], "run_dgb")
    return list(json.loads(out.read_text())["grasps"])


def dexaug_grasps(h5: Path, obj: str) -> tuple[list[Grasp], list[Grasp | None]]:
    """The export's grasps in its order (kept, then rejected): as generate validated them (no
    stages) and with the recorded stages attached (None where never simulated)."""
    t = with_rejected(load(h5)[obj])
    palm, hand = t["palm_pose"], t["hand_pose"]
    stage = grasp_stage_poses(t)
    pre, sq = t.columns.get("pregrasp_pose"), t.columns.get("squeeze_pose")
    derived = [Grasp.from_arrays(palm[i][:3], palm[i][3:], hand[i]) for i in range(len(t))]
    given: list[Grasp | None] = []
    for i in range(len(t)):
        ok = pre is not None and sq is not None and np.isfinite(pre[i]).all() and np.isfinite(sq[i]).all()
        given.append(Grasp.from_arrays(palm[i][:3], palm[i][3:], stage[i], pregrasp=pre[i],
                                       squeeze=sq[i]) if ok else None)
    return derived, given


def time_dexaug(obj: str, grasps: list[Grasp | None]) -> list[tuple[float, bool] | None]:
    """(ms, passed) of our ``dgb`` per grasp, one at a time in this process (one worker)."""
    out: list[tuple[float, bool] | None] = []
    for g in grasps:
        if g is None:
            out.append(None)
            continue
        t0 = time.perf_counter()
        (res,) = validate_many(HAND, obj, [g], "dgb", workers=1)
        out.append((1e3 * (time.perf_counter() - t0), bool(res.passed)))
    return out


def grasp_rows(obj: str, jsonl: Path, dgb: list[dict], derived: list, given: list) -> list[dict]:
    """One row per exported grasp: generate's verdict, DGB's, both sides' times."""
    lines = [json.loads(t) for t in jsonl.read_text().splitlines() if t.strip()]
    rows = []
    for line, d, de, gi in zip(lines, dgb, derived, given, strict=True):
        rows.append({
            "object": obj, "index": line["index"], "dexaug_passed": bool(line["dexaug"]["passed"]),
            "dexaug_failure": line["dexaug"]["failure"] or None,
            "stages_made_by": line["dexaug"]["stages_made_by"] or None,
            "dgb_success": d.get("success"), "dgb_skipped": d.get("skipped"),
            "dgb_delta_pos_m": d.get("delta_pos_m"), "dgb_delta_angle_deg": d.get("delta_angle_deg"),
            "dgb_rejected_penetration": d.get("rejected_penetration"),
            "dgb_directions_tested": d.get("directions_tested"), "dgb_steps": d.get("steps"),
            "dgb_ms": d.get("wall_ms"),
            "dexaug_derived_ms": None if de is None else de[0],
            "dexaug_derived_passed": None if de is None else de[1],
            "dexaug_given_ms": None if gi is None else gi[0],
            "dexaug_given_passed": None if gi is None else gi[1]})
    return rows


def _mean(rows: list[dict], key: str, sub: str | None = None) -> float | None:
    vals = [r[key] if sub is None else r[key][sub] for r in rows if r[key] is not None]
    return float(np.mean(vals)) if vals else None


def summarise(rows: list[dict], setup_s: float | None) -> dict[str, Any]:
    """Agreement and timing of one object's (or all) rows DGB evaluated."""
    ev = [r for r in rows if r["dgb_success"] is not None]
    ours = np.array([r["dexaug_passed"] for r in ev], bool)
    theirs = np.array([r["dgb_success"] for r in ev], bool)
    dgb_ms, der_ms = _mean(ev, "dgb_ms", "total"), _mean(ev, "dexaug_derived_ms")
    return {
        "grasps": len(rows), "dgb_evaluated": len(ev), "agree": int((ours == theirs).sum()),
        "agreement": float(np.mean(ours == theirs)) if len(ev) else None,
        "kappa": cohen_kappa(ours, theirs) if len(ev) else None,
        "dexaug_pass": int(ours.sum()), "dgb_pass": int(theirs.sum()),
        "dexaug_pass_dgb_fail": int((ours & ~theirs).sum()),
        "dexaug_fail_dgb_pass": int((~ours & theirs).sum()),
        "dgb_total_ms": dgb_ms, "dgb_simulate_ms": _mean(ev, "dgb_ms", "simulate"),
        "dgb_build_ms": _mean(ev, "dgb_ms", "build"), "dgb_steps": _mean(ev, "dgb_steps"),
        "dexaug_derived_ms": der_ms, "dexaug_given_ms": _mean(ev, "dexaug_given_ms"),
        "derived_over_dgb": None if not (dgb_ms and der_ms) else der_ms / dgb_ms,
        "rerun_same_verdict": int(sum(r["dexaug_derived_passed"] == r["dexaug_passed"] for r in ev)),
        "given_same_verdict": int(sum(r["dexaug_given_passed"] == r["dexaug_passed"] for r in ev)),
        "validator_setup_s": setup_s}


def measure_object(obj: str, args: argparse.Namespace, py: Path, tmp: Path) -> tuple[list, dict]:
    """Generate, export, DGB, our timing and the summary of one object."""
    h5, jsonl = generate_and_export(obj, args.n, args.seed, args.gen_workers, tmp)
    dgb = run_dgb(py, jsonl, args.cpu, tmp / f"{obj}.dgb.json")
    derived, given = dexaug_grasps(h5, obj)
    t0 = time.perf_counter()
    cached_validator(HAND, obj)
    setup_s = time.perf_counter() - t0
    rows = grasp_rows(obj, jsonl, dgb, time_dexaug(obj, derived), time_dexaug(obj, given))
    return rows, summarise(rows, setup_s)


def _fmt(v: Any, spec: str) -> str:
    return "–" if v is None else format(v, spec)


def print_tables(summary: dict[str, dict]) -> None:
    print("| object | DGB evaluated | agree | % | κ | ours pass / DGB fail | ours fail / DGB pass "
          "| ours pass | DGB pass |\n|---|---|---|---|---|---|---|---|---|")
    for o, s in summary.items():
        print(f"| {o} | {s['dgb_evaluated']} | {s['agree']} | {_fmt(100 * (s['agreement'] or 0), '.1f')} "
              f"| {_fmt(s['kappa'], '.2f')} | {s['dexaug_pass_dgb_fail']} | {s['dexaug_fail_dgb_pass']} "
              f"| {s['dexaug_pass']} | {s['dgb_pass']} |")
    print("\n| object | DGB ms/grasp (evaluator) | DGB simulate ms | DGB steps | dexaug dgb ms "
          "(as generate) | dexaug dgb ms (stages given) | generate / DGB |\n|---|---|---|---|---|---|---|")
    for o, s in summary.items():
        print(f"| {o} | {_fmt(s['dgb_total_ms'], '.0f')} | {_fmt(s['dgb_simulate_ms'], '.0f')} | "
              f"{_fmt(s['dgb_steps'], '.0f')} | {_fmt(s['dexaug_derived_ms'], '.0f')} | "
              f"{_fmt(s['dexaug_given_ms'], '.0f')} | {_fmt(s['derived_over_dgb'], '.2f')} |")


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--objects", nargs="+", default=list(DEFAULT_OBJECTS))
    ap.add_argument("--n", type=int, default=50, help="grasps generated (and compared) per object")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--gen-workers", type=int, default=1, help="generate's --workers")
    ap.add_argument("--cpu", type=int, default=1, help="the core both timed sides are pinned to")
    ap.add_argument("--dgb-venv", type=Path,
                    default=Path(os.environ.get("DGB_VENV", "/tmp/exp/dgb-venv")))
    ap.add_argument("--keep", type=Path, default=None,
                    help="keep the datasets, exports and DGB results in this folder")
    ap.add_argument("--quick", action="store_true", help="2 objects × 6 grasps (a smoke run)")
    args = ap.parse_args()
    if args.quick:
        args.objects, args.n = args.objects[:2], min(args.n, 6)
    return args


def main() -> None:
    args = parse_args()
    py = dgb_python(args.dgb_venv)
    if py is None:
        print(f"skipped: no DexGraspBench side venv at {args.dgb_venv} (build it with {SETUP})")
        return
    os.sched_setaffinity(0, {args.cpu})
    rows: list[dict] = []
    summary: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="bench_dgb_own_") as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for obj in args.objects:
            obj_rows, summary[obj] = measure_object(obj, args, py, folder)
            rows += obj_rows
            print(f"{obj}: {json.dumps(summary[obj])}", flush=True)
    summary["all"] = summarise(rows, None)
    print_tables(summary)
    path = write_record("dgb_own", rows, summary=summary,
                        config={k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
                        hand=HAND, objects=args.objects)
    print(f"record: {path}")


if __name__ == "__main__":
    main()
