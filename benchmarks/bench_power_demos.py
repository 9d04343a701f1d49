"""Whole-hand wraps a person makes become power demos that augment into grasps that hold (#49).

For each object and seed, the human-timed operator of ``benchmarks/bench_teleop_loop.py``
(a person's geometry and timing: tips 3–8 mm short of the surface, the lift 0.12–0.60 s after
touching) grasps the object where the bridge's table has it, and :func:`wrap_episode` turns
that grasp into a wrap: while the fingers close, the operator's whole hand moves along the
robot palm's normal until the palm box's face would lie ``press_m`` inside the object (a person
wrapping a virtual object has nothing to stop the palm; the fingers keep their posture), and
back out on the release. The raw session is re-recorded through the real bridge in the
demonstration mode (object held, the paper's) and in the free mode, and measured:

- **before** (the code as it was): extraction with the wrap rule off
  (``DemoParams(power_min_s=inf)``): a demo or not, and its fingertip (precision) demo
  augmented by FSG (demo mode);
- **after**: extraction as it is (``DemoParams()``): demos extracted as power demos, and the
  demo-mode power demo augmented by the demo-seeded power generator
  (:mod:`augment.power.demo_seed`, routed by :func:`dexaug.pipeline.run.augment_demo`);
- for both: grasps found, grasps that pass the validator's lift-drop (real mass), the demo's
  own grasp in lift-drop.

Each run writes a record under ``benchmarks/measured/power_demos/`` (:mod:`benchmarks.record`).

    .venv/bin/python benchmarks/bench_power_demos.py [--objects a,b] [--seeds 2] [--n 50]
                                                      [--budget-s 60] [--press-m 0.04]
                                                      [--workers 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np

from benchmarks.bench_teleop_loop import OPERATORS

#: the wrap objects of the issue (the person's hand closes around them, palm on)
OBJECTS = ("004_sugar_box", "005_tomato_soup_can")
#: how far past the object surface the palm box's face is carried (metres): a person's palm
#: pressed onto a virtual object; the bridge's robot palm stops on the surface
PRESS_M = 0.04


def human_episode(obj: str, seed: int, hand: Any) -> Any:
    """The human-timed operator's grasp of ``obj`` (bench_teleop_loop's placement: the bridge's
    object spot moved up to 3 cm along x and 5 cm along y, a yaw within ±40°)."""
    from teleop.bridge.config import load_bridge_config
    from teleop.synthetic.config import load_synth_config
    from teleop.synthetic.synthesize import synthesize

    rng = np.random.default_rng(seed)
    yaw = float(rng.uniform(-40, 40))
    bridge = load_bridge_config()
    spot = np.array([*bridge.object_pos_m, 0.0]) - bridge.world_offset_m
    pos = tuple(spot + np.array([rng.uniform(-0.03, 0.03), rng.uniform(-0.05, 0.05), 0.0]))
    cfg = dataclasses.replace(load_synth_config(), **OPERATORS["human"],
                              object_rpy_deg=(0.0, 0.0, yaw), object_pos_m=pos)
    return synthesize(obj, hand=hand, seed=seed, config=cfg)


def wrap_episode(ep: Any, hand: Any, press_m: float = PRESS_M) -> Any:
    """``ep`` with the operator's hand carried onto the object as the fingers close (module
    docstring): every tracked joint shifted along the retargeted robot palm's normal (+y of
    frame_palm at the grasp) by the gap between the robot palm box's face and the object
    (over the box's footprint) plus ``press_m``, with the close phase's minimum-jerk timing in
    and the release's out."""
    from sim.transforms import quat_to_mat
    from sim.world.objects import load_object
    from teleop.synthetic.episode import min_jerk

    palm = hand.config.palm
    rot = quat_to_mat(np.asarray(ep.target_palm_quat_wxyz, float))
    mesh = load_object(ep.object_name).surface_mesh()
    verts = (np.asarray(mesh.vertices) @ quat_to_mat(np.asarray(ep.object_quat_wxyz)).T
             + ep.object_pos_m - ep.target_palm_pos_m) @ rot          # frame_palm
    c, h = np.asarray(palm.box_center, float), np.asarray(palm.box_half_extents, float)
    front = ((np.abs(verts[:, 0] - c[0]) <= h[0]) & (np.abs(verts[:, 2] - c[2]) <= h[2])
             & (verts[:, 1] > c[1]))
    gap = float(verts[front, 1].min() - (c[1] + h[1])) if front.any() else 0.0
    shift = (gap + press_m) * rot[:, 1]
    c0, c1 = ep.phases["close"]
    r0, r1 = ep.phases["release"]
    frames = []
    for f in ep.frames:
        t = f.device_time_s
        s = float(min_jerk((t - c0) / (c1 - c0)) if t < r0 else 1.0 - min_jerk((t - r0) / (r1 - r0)))
        if f.right is not None and f.right.tracked and s > 0.0:
            f = dataclasses.replace(f, right=dataclasses.replace(
                f.right, positions=f.right.positions + s * shift))
        frames.append(f)
    return dataclasses.replace(ep, frames=frames)


def _extract(path: Path, wraps: bool) -> tuple[list[Any], str]:
    """Demos of the recording (``wraps``: the rule as it is; else as before it, the wrap rule
    off), and why there are none."""
    from sim.demo import DemoError
    from teleop.record.demos import DemoParams, extract_demos

    params = DemoParams() if wraps else DemoParams(power_min_s=math.inf)
    try:
        return extract_demos(path, params), ""
    except DemoError as exc:
        return [], str(exc).split(": ", 2)[-1][:120]


def _augment(demo: Any, out: Path, n: int, budget_s: float) -> dict[str, Any]:
    """Augment ``demo`` (one process), validate with lift-drop: grasps found and passing."""
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_demo

    t0 = time.perf_counter()
    s = augment_demo(demo, out, AugmentOptions(n=n, time_budget_s=budget_s, gallery=0,
                                               workers=1, validate="lift-drop"), force=True)
    return {"grasp_type": demo.grasp_type, "fingers": list(demo.fingers),
            "link_contacts": list(demo.link_contacts), "generated": s.generated,
            "passed": s.passed, "stopped": s.fsg_stopped, "failures": s.failures,
            "demo_holds": bool((s.demo_grasp or {}).get("passed")),
            "wall_s": time.perf_counter() - t0}


def run_one(job: tuple[str, str, int, float, int, float, str]) -> dict[str, Any]:
    hand_name, obj, seed, press_m, n, budget_s, out = job
    os.environ.setdefault("MUJOCO_GL", "egl")
    from sim.demo import POWER
    from sim.hand.model import Hand
    from teleop.bridge.rerecord import rerecord
    from teleop.synthetic.writer import write_session

    hand = Hand.load(hand_name)
    d = Path(out) / f"{obj}_{seed}"
    d.mkdir(parents=True, exist_ok=True)
    raw = write_session(wrap_episode(human_episode(obj, seed, hand), hand, press_m),
                        d / "raw.mcap", overwrite=True)
    row: dict[str, Any] = {"object": obj, "seed": seed}
    for mode in ("demo", "free"):
        path = rerecord(raw, d / f"{mode}.mcap", object_mode=mode)
        for when, wraps in (("before", False), ("after", True)):
            demos, why = _extract(path, wraps)
            row[f"{when}_{mode}"] = {"demos": len(demos), "why": why,
                                     "power": sum(x.grasp_type == POWER for x in demos)}
            if mode != "demo" or not demos:
                continue
            # the demo augmented: the power one when there is one, else the fullest
            best = max(demos, key=lambda x: (x.grasp_type == POWER, len(x.fingers)))
            row[f"{when}_{mode}"].update(_augment(best, d / f"aug_{when}", n, budget_s))
    return row


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per object and overall, before and after: demo-mode and free-mode demos (power ones),
    and of the demo-mode augmentation the grasps found, passing lift-drop, and the pass rate."""
    def block(sel: list[dict[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {"episodes": len(sel)}
        for when in ("before", "after"):
            aug = [r[f"{when}_demo"] for r in sel]
            found = sum(a.get("generated", 0) for a in aug)
            passed = sum(a.get("passed", 0) for a in aug)
            out[when] = {
                "demos_demo_mode": sum(a["demos"] > 0 for a in aug),
                "power_demos_demo_mode": sum(a["power"] > 0 for a in aug),
                "demos_free": sum(r[f"{when}_free"]["demos"] > 0 for r in sel),
                "power_demos_free": sum(r[f"{when}_free"]["power"] > 0 for r in sel),
                "augmented": sum("generated" in a for a in aug),
                "with_grasps": sum(a.get("generated", 0) > 0 for a in aug),
                "grasps_found": found, "grasps_passed": passed,
                "pass_rate": passed / found if found else None,
                "demo_grasp_holds": sum(a.get("demo_holds", False) for a in aug)}
        return out

    return {**block(rows), "per_object": {o: block([r for r in rows if r["object"] == o])
                                          for o in dict.fromkeys(r["object"] for r in rows)}}


def _print(summary: dict[str, Any], wall_s: float) -> None:
    print(f"\n{summary['episodes']} episodes, {wall_s:.0f} s")
    keys = ("demos_demo_mode", "power_demos_demo_mode", "demos_free", "power_demos_free",
            "with_grasps", "grasps_found", "grasps_passed", "pass_rate")
    print(f"{'object':22s} {'':6s} " + " ".join(f"{k:>22s}" for k in keys))
    for obj, block in [*summary["per_object"].items(), ("all", summary)]:
        for when in ("before", "after"):
            b = block[when]
            cells = [f"{b[k]:.2f}" if isinstance(b[k], float) else str(b[k]) for k in keys]
            print(f"{obj:22s} {when:6s} " + " ".join(f"{c:>22s}" for c in cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--objects", default=",".join(OBJECTS))
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--n", type=int, default=50, help="grasps asked of each augmentation")
    ap.add_argument("--budget-s", type=float, default=60.0,
                    help="generator time budget per augmentation (wall seconds)")
    ap.add_argument("--press-m", type=float, default=PRESS_M,
                    help="how far past the surface the operator carries the palm box (metres)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--hand", default=None, help="hand (default: configs/hands/default.toml)")
    ap.add_argument("--no-record", action="store_true")
    args = ap.parse_args()
    from sim.hand.config import default_hand_name

    hand = args.hand or default_hand_name()
    objects = args.objects.split(",")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        jobs = [(hand, o, s, args.press_m, args.n, args.budget_s, tmp) for o in objects
                for s in range(args.first_seed, args.first_seed + args.seeds)]
        with ProcessPoolExecutor(args.workers) as ex:
            rows = list(ex.map(run_one, jobs))
    wall = time.perf_counter() - t0
    summary = summarize(rows)
    _print(summary, wall)
    if not args.no_record:
        from benchmarks.record import write_record

        path = write_record("power_demos", rows, summary={**summary, "wall_s": wall},
                            config={**vars(args), "operator_settings": OPERATORS["human"]},
                            hand=hand, objects=objects)
        print(f"record: {path}")


if __name__ == "__main__":
    main()
