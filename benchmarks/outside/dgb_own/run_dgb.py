"""DexGraspBench's own ``fc`` evaluator (``fcMocapEval``, unmodified) on grasps in DGB's reference
JSONL layout (what ``dexaug export --format dexgraspbench`` writes): verdicts and wall time.

Run by the Python of DGB's side venv (``setup.sh``: MuJoCo 3.3.2, numpy 1.26.4), never by the
project's; it imports nothing of dexaug (its own folder's ``dgb_objects`` only). All of it is
file-format glue around DGB's code:

- each line's ``rh_palm_pose_world`` (Menagerie's ``rh_palm`` body) becomes DGB's hand root pose:
  in DGB's Shadow asset the root sits at ``rh_palm`` − (0, 0, 0.034) m in ``rh_palm``'s frame,
  same orientation (``assets/hand/shadow/right_hand.xml``: ``<body name="rh_palm"
  pos="0 0 0.034">``); DGB's hand qpos is [root xyz, root wxyz, its 22 finger joints by name]
  (the wrist joints of the line are not in DGB's asset and are dropped: the palm pose already
  holds them);
- pregrasp / grasp / squeeze: the line's ``q_pregrasp`` / ``q_grasp`` / ``q_squeeze``
  (``--stages given``; ``bodex`` and ``rule`` make them from ``q_grasp`` as the reference
  README's variants do); a line without pregrasp or squeeze (never simulated) is skipped;
- the object: ``dgb_objects.prepare_object`` (its docstring), pose ``object_pose_world``,
  scale 1;
- configuration: DGB's own ``config/task/eval.yaml`` and ``config/hand/shadow.yaml`` (object
  mass 0.1 kg, friction, thresholds), ``setting: fc``, as ``src/main.py`` would compose them.

Per grasp it writes DGB's verdict (``succ_flag``, ``delta_pos``, ``delta_angle``; a penetration
reject is DGB's sentinel 100/100), the directions DGB pushed, the simulation steps DGB took
(the ``step_inner`` of its ``control_hand_step`` calls, counted by wrapping that method on the
instance: no per-step cost) and wall times (ms): ``build`` (``fcMocapEval(...)``: reading the
grasp, building and compiling DGB's MjSpec), ``pene_contact`` and ``fc_metrics`` (DGB's
analytic metrics, which ``run()`` computes too), ``simulate`` (``_eval_simulate_under_extforce``:
penetration filter and the six pushes, the verdict), ``total`` (constructor + ``run()``,
saving included). One process; ``--cpu K`` pins it to one core; BLAS/OpenMP get one thread.

Usage: ``VENV/bin/python run_dgb.py GRASPS.jsonl --out RESULT.json [--ycb DIR] [--dgb-src DIR]
[--stages given|bodex|rule] [--cpu K] [--limit N] [--compare-variant dexaug_mass0.1]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"   # one core: before numpy/torch load their thread pools

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dgb_objects import prepare_object  # noqa: E402

#: DGB's Shadow asset: hand root = rh_palm − this offset (m) along rh_palm's z
ROOT_BELOW_PALM_M = 0.034
#: DGB's sentinel delta_pos / delta_angle of a grasp its penetration filter rejects
PENETRATION_SENTINEL = 100


def _rotate(q_wxyz: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` rotated by the unit quaternion ``q_wxyz``."""
    w, u = q_wxyz[0], q_wxyz[1:]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def hand_root_pose(palm_pose: list[float]) -> np.ndarray:
    """DGB's hand root pose [xyz, wxyz] from Menagerie's ``rh_palm`` pose (module docstring)."""
    p, q = np.asarray(palm_pose[:3], float), np.asarray(palm_pose[3:], float)
    q = q / np.linalg.norm(q)
    return np.concatenate([p + _rotate(q, np.array([0.0, 0.0, -ROOT_BELOW_PALM_M])), q])


def stage_joints(row: dict[str, Any], stages: str) -> tuple[dict, dict, dict] | None:
    """(pregrasp, grasp, squeeze) joint angles by name under ``stages``; None when absent."""
    grasp = row.get("q_grasp")
    if grasp is None:
        return None
    if stages == "rule":   # DGB's rule for grasp-only methods
        return ({k: 0.9 * v for k, v in grasp.items()}, grasp, {k: 1.1 * v for k, v in grasp.items()})
    pre = row.get("q_pregrasp")
    if pre is None:
        return None
    if stages == "bodex":   # BODex: squeeze = 2·grasp − pregrasp
        return pre, grasp, {k: 2 * grasp[k] - pre[k] for k in grasp}
    squeeze = row.get("q_squeeze")
    return None if squeeze is None else (pre, grasp, squeeze)


def dgb_configs(src: Path, work: Path) -> Any:
    """DGB's configuration for ``setting: fc`` with the Shadow hand, from its own YAML files;
    output folders under ``work`` (DGB saves one evaluation file per grasp there)."""
    from omegaconf import OmegaConf

    cfg = OmegaConf.create({
        "setting": "fc", "save_dir": str(work), "grasp_dir": str(work / "graspdata"),
        "eval_dir": str(work / "evaluation"), "succ_dir": str(work / "succgrasp"),
        "task": OmegaConf.load(src / "config" / "task" / "eval.yaml"),
        "hand": OmegaConf.load(src / "config" / "hand" / "shadow.yaml")})
    cfg.hand.xml_path = str(src / cfg.hand.xml_path)
    return cfg


def dgb_joint_names(hand_xml: str) -> list[str]:
    """The finger joints of DGB's hand asset in its qpos order."""
    import mujoco

    model = mujoco.MjSpec.from_file(hand_xml).compile()
    return [model.joint(i).name for i in range(model.njnt)]


class Timed:
    """A method wrapped to add its wall time (ms) to ``times[key]``."""

    def __init__(self, fn: Any, times: dict[str, float], key: str) -> None:
        self.fn, self.times, self.key = fn, times, key

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.times[self.key] = self.times.get(self.key, 0.0) + 1e3 * (time.perf_counter() - t0)


def evaluate(npy: Path, cfg: Any) -> dict[str, Any]:
    """DGB's ``fcMocapEval(npy, cfg).run()`` with its parts timed, steps and pushes counted."""
    from task.eval_func.fc_mocap import fcMocapEval

    times: dict[str, float] = {}
    counts = {"steps": 0, "directions": 0}
    t0 = time.perf_counter()
    ev = fcMocapEval(str(npy), cfg)
    times["build"] = 1e3 * (time.perf_counter() - t0)
    for method, key in (("_eval_pene_and_contact", "pene_contact"),
                        ("_eval_analytic_fc_metric", "fc_metrics"),
                        ("_eval_simulate_under_extforce", "simulate")):
        setattr(ev, method, Timed(getattr(ev, method), times, key))
    step, push = ev.mj_ho.control_hand_step, ev.mj_ho.set_ext_force_on_obj

    def counted_step(step_inner: int) -> None:
        counts["steps"] += step_inner
        step(step_inner)

    def counted_push(force: np.ndarray) -> None:
        counts["directions"] += 1
        push(force)

    ev.mj_ho.control_hand_step, ev.mj_ho.set_ext_force_on_obj = counted_step, counted_push
    ev.run()
    times["total"] = 1e3 * (time.perf_counter() - t0)
    res = np.load(str(npy).replace(cfg.grasp_dir, cfg.eval_dir), allow_pickle=True).item()
    rejected = res["delta_pos"] == PENETRATION_SENTINEL and res["delta_angle"] == PENETRATION_SENTINEL
    return {"success": bool(res["succ_flag"]), "delta_pos_m": float(res["delta_pos"]),
            "delta_angle_deg": float(res["delta_angle"]), "rejected_penetration": bool(rejected),
            "directions_tested": counts["directions"], "steps": counts["steps"],
            "ho_pene_m": float(res["ho_pene"]), "self_pene_m": float(res["self_pene"]),
            "wall_ms": {k: round(v, 3) for k, v in times.items()}}


def grasp_file(row: dict, stages: tuple[dict, dict, dict], joints: list[str], obj_dir: Path,
               folder: Path) -> Path:
    """The grasp as DGB's input ``.npy`` (a dict: obj_path, obj_scale, obj_pose and the hand
    qpos of each stage); its path."""
    root = hand_root_pose(row["rh_palm_pose_world"])
    missing = [j for j in joints if j not in stages[1]]
    if missing:
        raise SystemExit(f"run_dgb: {row['object']}#{row['index']}: no angle for {missing[:3]}")
    pre, grasp, squeeze = (np.concatenate([root, [float(s[j]) for j in joints]]) for s in stages)
    data = {"obj_path": str(obj_dir), "obj_scale": 1.0,
            "obj_pose": np.asarray(row["object_pose_world"], float),
            "pregrasp_qpos": pre, "grasp_qpos": grasp, "squeeze_qpos": squeeze}
    path = folder / row["object"] / f"{int(row['index']):05d}.npy"
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, data, allow_pickle=True)
    return path


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("grasps", type=Path, help="DGB reference-layout JSONL")
    ap.add_argument("--out", type=Path, required=True, help="result JSON")
    ap.add_argument("--ycb", type=Path, default=Path("/work/shared/assets/ycb"))
    ap.add_argument("--dgb-src", type=Path, default=Path(sys.prefix) / "dgb-src",
                    help="DexGraspBench source (setup.sh puts it in VENV/dgb-src)")
    ap.add_argument("--stages", choices=("given", "bodex", "rule"), default="given")
    ap.add_argument("--cpu", type=int, default=None, help="pin the process to this core")
    ap.add_argument("--limit", type=int, default=0, help="first N grasps of each object only")
    ap.add_argument("--compare-variant", default=None,
                    help="count matches with the line's recorded dgb[VARIANT] verdict")
    return ap.parse_args()


def summarise(rows: list[dict], variant: str | None) -> dict[str, Any]:
    """Totals, median/mean times per grasp and, with ``variant``, matches with recorded verdicts."""
    done = [r for r in rows if "success" in r]
    out: dict[str, Any] = {"grasps": len(rows), "evaluated": len(done),
                           "dgb_success": sum(r["success"] for r in done),
                           "rejected_penetration": sum(r["rejected_penetration"] for r in done)}
    for key in ("total", "simulate", "build"):
        ms = np.array([r["wall_ms"].get(key, 0.0) for r in done])
        if len(ms):
            out[f"{key}_ms_mean"], out[f"{key}_ms_median"] = float(ms.mean()), float(np.median(ms))
    if done:
        out["steps_mean"] = float(np.mean([r["steps"] for r in done]))
    if variant:
        rec = [r for r in done if r.get("recorded_success") is not None]
        out["compare_variant"] = variant
        out["recorded_n"] = len(rec)
        out["recorded_match"] = sum(r["success"] == r["recorded_success"] for r in rec)
        out["recorded_mismatch"] = [f"{r['object']}#{r['index']}" for r in rec
                                    if r["success"] != r["recorded_success"]]
    return out


def main() -> None:
    args = parse_args()
    if args.cpu is not None:
        os.sched_setaffinity(0, {args.cpu})
    src = args.dgb_src.resolve()
    if not (src / "src" / "task" / "eval_func" / "fc_mocap.py").is_file():
        raise SystemExit(f"run_dgb: no DexGraspBench source at {src} (run setup.sh)")
    sys.path.insert(0, str(src / "src"))
    import mujoco

    lines = [json.loads(t) for t in args.grasps.read_text().splitlines() if t.strip()]
    if args.limit:
        lines = [r for o in dict.fromkeys(r["object"] for r in lines)
                 for r in [x for x in lines if x["object"] == o][:args.limit]]
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="dgb_own_") as tmp:
        work = Path(tmp)
        cfg = dgb_configs(src, work)
        joints = dgb_joint_names(cfg.hand.xml_path)
        objects = {o: prepare_object(args.ycb, o, work / "objects")
                   for o in dict.fromkeys(r["object"] for r in lines)}
        for row in lines:
            out: dict[str, Any] = {"object": row["object"], "index": int(row["index"])}
            if args.compare_variant:
                rec = row.get("dgb", {}).get(args.compare_variant)
                out["recorded_success"] = None if rec is None else bool(rec["success"])
            stages = stage_joints(row, args.stages)
            if stages is None:
                out["skipped"] = "no pregrasp/squeeze in the line (never simulated)"
            else:
                npy = grasp_file(row, stages, joints, objects[row["object"]], Path(cfg.grasp_dir))
                out.update(evaluate(npy, cfg))
            rows.append(out)
    summary = summarise(rows, args.compare_variant)
    result = {"dgb_source": str(src), "dgb_commit": _commit(src), "mujoco": mujoco.__version__,
              "numpy": np.__version__, "stages": args.stages, "cpu": args.cpu,
              "summary": summary, "grasps": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1))
    print(json.dumps(summary))


def _commit(src: Path) -> str | None:
    f = src / "COMMIT"
    return f.read_text().strip() if f.is_file() else None


if __name__ == "__main__":
    main()
