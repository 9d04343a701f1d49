"""Closed-loop teleop without a headset: the synthetic operator's grasps through the real bridge.

For each object and seed (the object placed on the bridge's table at its spot ``object_pos_m``
moved up to 3 cm along x and 5 cm along y, with a random yaw within ±40°) the synthetic
operator (``teleop.synthetic``: human hand, headset noise and dropouts) grasps and lifts it at
a given speed; the raw session is re-recorded through a real bridge
twice — in demonstration mode (object held) and in free mode — and measured:

- **demo**: the demo-mode recording yields a demonstration (``extract_demos``);
- **human fingers**: the demo's fingers include every finger whose *human* pad was within
  8 mm of the object at the grasp moment (the fingers the human used);
- **pad gap**: at the grasp moment in demo mode, the gap between the simulated distal link of each
  of the human's fingers and the object (``mj_geomDistance``; the issue's "simulated pads to the
  object surface");
- **lifted**: in free mode the object's median height over the hold phase is ≥ 60 % of the
  operator's lift height above where it rested;
- **pushed** (free mode): how far the object had moved when the operator began to close, and
  which hand body touched it first before that: the robot's links reaching the object where
  the operator's fingers did not (counted above 5 mm);
- **demo holds** (``--validate-demos``): the demo's own grasp passes the validator's lift-drop
  (real mass, :func:`dexaug.pipeline.run.validate_demo_grasp`; "holds" or "slips" per
  episode), and how many of those episodes lifted: a grasp that does not hold in the
  validator cannot be lifted by steadier teleop.

Operators (:data:`OPERATORS`): ``human`` (the default) has a person's geometry and timing as
measured on real Quest recordings — each fingertip stops 3–8 mm *short* of the surface (no
press-in) and the lift begins 0.12–0.60 s (median 0.36 s) after the fingers reach the object;
``synthetic`` is the operator's old natural speed (closes in 0.3 s pressing the tips 1 cm
into the object, lifts 0.15 s later), which flatters the teleop path. Both recordings (free
and demo mode) go through demo extraction; "person's fingers" needs every finger the human
put within 10 mm of the object, and the thumb, among the demo's fingers. Each run writes a
record under ``benchmarks/measured/teleop_loop/`` (:mod:`benchmarks.record`). Objects are the
generic-grasp ones by default (no hand-built reference grasp); ``--objects`` takes any list.
Also measured: how far a finger servo lags a 0.3 s min-jerk closure of 1.2 rad in free air at
the bridge's servo gains and at the model's own (DESIGN §6 "fingers at human speed").

    .venv/bin/python benchmarks/bench_teleop_loop.py [--seeds 2] [--first-seed 0]
                                                      [--operator human|synthetic]
                                                      [--objects a,b,...] [--workers 2]
                                                      [--validate-demos]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np

#: the six objects of the real human recordings first, then generic-grasp objects
OBJECTS = ("004_sugar_box", "005_tomato_soup_can", "021_bleach_cleanser", "024_bowl",
           "006_mustard_bottle", "002_master_chef_can", "013_apple", "007_tuna_fish_can",
           "008_pudding_box", "009_gelatin_box", "014_lemon", "016_pear", "017_orange",
           "036_wood_block", "054_softball", "056_tennis_ball", "065_d_cups")
#: operator settings (SynthConfig fields): a person's geometry and timing as measured on real
#: Quest recordings (tips 3–8 mm short of the surface, lift 0.12–0.60 s after the fingers reach
#: the object, uniform: median 0.36 s), and the synthetic operator's old natural speed
#: (presses 1 cm in, lifts 0.24 s after touching, holds)
OPERATORS = {"human": {"close_s": 0.3, "standoff_m": (0.003, 0.008),
                       "lift_delay_s": (0.12, 0.60), "press_depth_m": 0.0},
             "synthetic": {"close_s": 0.3, "settle_s": 0.15}}
HUMAN_TOUCH_M = 0.010
PUSHED_M = 0.005


def _human_fingers(ep, obj: str, hand) -> dict[str, float]:
    """Robot fingers whose operator finger's pad is within HUMAN_TOUCH_M of the object at the
    grasp moment (the mapping of the hand's retarget.toml), each with that pad's gap to the
    surface (metres, negative: inside; the operator's tracked pad, not the robot's)."""
    from sim.transforms import quat_to_mat
    from sim.world.objects import load_object
    from teleop.messages import JOINT_INDEX
    from teleop.retarget.config import load_retarget_config
    from teleop.synthetic.surface import surface_distance_m

    mapping = load_retarget_config().hand(hand.name).fingers
    robot_fingers = hand.finger_names
    frame = min((f for f in ep.frames if f.right is not None and f.right.tracked),
                key=lambda f: abs(f.device_time_s - ep.grasp_time_s))
    rows = [JOINT_INDEX[mapping[f]] for f in robot_fingers if f in mapping]
    names = [f for f in robot_fingers if f in mapping]
    h = frame.right
    local = (h.positions[rows] - ep.object_pos_m) @ quat_to_mat(ep.object_quat_wxyz)
    gap = surface_distance_m(load_object(obj).surface_mesh(), local) - h.radii[rows]
    return {n: round(float(g), 5) for n, g in sorted(zip(names, gap, strict=True))
            if g < HUMAN_TOUCH_M}


def _states_on_operator_clock(path: Path, ep, topic: str = "/state"
                              ) -> tuple[list[dict], np.ndarray]:
    """The recording's ``topic`` messages (``/state`` or ``/contacts``) and each one's operator
    device time (seconds): each names the frame (seq) it answers; simulated time runs at
    steps_per_frame × timestep per frame, not the frames' pace."""
    from teleop.record.session import open_session

    msgs = [m for _, m in open_session(path).json_messages(topic)]
    device_s = {f.seq: f.device_time_s for f in ep.frames}
    return msgs, np.array([device_s.get(m["seq"], np.nan) for m in msgs])


def _pad_gaps_m(path: Path, ep, obj: str, hand, fingers: list[str]) -> list[float]:
    """For each finger in ``fingers``: the gap (metres, negative: pressed in) between its
    distal link's collision geoms and the object in the simulated state nearest the human's
    grasp moment (``mj_geomDistance`` on the recorded hand joints, palm and object poses)."""
    import mujoco

    from sim.world.objects import load_object
    from sim.world.scene import HAND_PREFIX, Scene

    states, t = _states_on_operator_clock(path, ep)
    m_state = states[int(np.nanargmin(np.abs(t - ep.grasp_time_s)))]
    sc = Scene(hand, load_object(obj))
    q = np.asarray(m_state["qpos"], float)
    sc.set_palm_pose(m_state["palm_pos_m"], m_state["palm_quat_wxyz"], q)
    sc.set_hand_joints(q)
    sc.set_object_pose(np.asarray(m_state["object_pos_m"]), np.asarray(m_state["object_quat_wxyz"]))
    model, data = sc.model, sc.data
    mujoco.mj_forward(model, data)
    collides = (model.geom_contype | model.geom_conaffinity) > 0
    obj_geoms = np.flatnonzero(sc.obj_geom_mask & collides)
    gaps = []
    for f in fingers:
        body = model.body(HAND_PREFIX + hand.config.finger(f).links[-1]).id
        geoms = np.flatnonzero((model.geom_bodyid == body) & collides)
        gaps.append(min(mujoco.mj_geomDistance(model, data, int(a), int(b), 0.05, None)
                        for a in geoms for b in obj_geoms))
    return gaps


def _approach_push(path: Path, ep, states: list[dict], t: np.ndarray) -> tuple[float, str]:
    """How far (metres) the object had moved when the operator's closure began, from where it
    rested when the approach began, and the hand body that touched it first ("" if none did
    before the closure; of several in the same step, the first by name): the robot's links
    reaching what the operator's fingers did not. ``states``, ``t``: the recording's
    :func:`_states_on_operator_clock`."""
    p = np.array([m["object_pos_m"] for m in states])
    start = int(np.nanargmin(np.abs(t - ep.phases["approach"][0])))
    close = int(np.nanargmin(np.abs(t - ep.phases["close"][0])))
    contacts, tc = _states_on_operator_clock(path, ep, "/contacts")
    first = next((min(x["hand_body"] for x in c["contacts"])
                  for c, ti in zip(contacts, tc, strict=True)
                  if c["contacts"] and ti < ep.phases["close"][0]), "")
    return float(np.linalg.norm(p[close] - p[start])), first


def _hold_height_m(ep, states: list[dict], t: np.ndarray) -> float:
    z = np.array([m["object_pos_m"][2] for m in states])
    hold = (t >= ep.phases["hold"][0]) & (t <= ep.phases["hold"][1])
    return float(np.median(z[hold]) - np.median(z[t < ep.phases["approach"][0]]))


def _demos_of(path: Path, human: list[str]) -> dict:
    """What demo extraction gives for the recording at ``path``: whether a demo came out, the
    fingers of its fullest one, whether those include every finger the human used and the
    thumb (the issue's "with the fingers the person used"), or why none came out."""
    from sim.demo import DemoError
    from teleop.record.demos import extract_demos

    try:
        demos, why = extract_demos(path), ""
    except DemoError as exc:
        demos, why = [], str(exc).split(": ", 2)[-1][:90]
    best = max(demos, key=lambda x: len(x.fingers)) if demos else None
    fingers = sorted(best.fingers) if best else []
    return {"demo": bool(demos), "fingers": fingers, "why": why, "best": best,
            "human_fingers": bool(demos) and set(human) <= set(fingers) and "thumb" in fingers}


def _thumb_links_touching(path: Path, ep, hand) -> dict[str, bool]:
    """Which thumb links touched the object from the closure's start to the lift's: its
    distal (the pad the person used) and the rest (the middle phalanx touching instead is the
    issue's commonest thumb failure)."""
    contacts, tc = _states_on_operator_clock(path, ep, "/contacts")
    during = (tc >= ep.phases["close"][0]) & (tc <= ep.phases["lift"][0])
    bodies = {x["hand_body"] for c, d in zip(contacts, during, strict=True) if d
              for x in c["contacts"]}
    links = list(hand.config.finger(hand.finger_names[0]).links)
    return {"thumb_tip": links[-1] in bodies, "thumb_other": bool(bodies & set(links[:-1]))}


def run_one(job: tuple[str, str, int, str, str, bool]) -> dict:
    hand_name, obj, seed, operator, out, validate_demo = job
    os.environ.setdefault("MUJOCO_GL", "egl")
    from sim.hand.model import Hand
    from teleop.bridge.config import load_bridge_config
    from teleop.bridge.rerecord import rerecord
    from teleop.synthetic.config import load_synth_config
    from teleop.synthetic.synthesize import synthesize
    from teleop.synthetic.writer import write_session

    rng = np.random.default_rng(seed)
    yaw = float(rng.uniform(-40, 40))
    bridge = load_bridge_config()   # the object's spot on the bridge's table, tracking space
    spot = np.array([*bridge.object_pos_m, 0.0]) - bridge.world_offset_m
    pos = tuple(spot + np.array([rng.uniform(-0.03, 0.03), rng.uniform(-0.05, 0.05), 0.0]))
    cfg = dataclasses.replace(load_synth_config(), **OPERATORS[operator],
                              object_rpy_deg=(0.0, 0.0, yaw), object_pos_m=pos)
    hand = Hand.load(hand_name)
    row = {"object": obj, "seed": seed}
    try:
        ep = synthesize(obj, hand=hand, seed=seed, config=cfg)
    except Exception as exc:   # no generic grasp for this object: reported, not counted
        row["skipped"] = f"{type(exc).__name__}: {str(exc)[:80]}"
        return row
    row["lift_delay_s"] = ep.metadata["lift_delay_s"]
    row["standoff_m"] = ep.metadata["standoff_m"]
    d = Path(out) / f"{obj}_{seed}"
    d.mkdir(parents=True, exist_ok=True)
    raw = write_session(ep, d / "raw.mcap", overwrite=True)
    row["human_pad_gaps_m"] = _human_fingers(ep, obj, hand)
    row["human"] = list(row["human_pad_gaps_m"])
    demo_path = rerecord(raw, d / "demo.mcap", object_mode="demo")
    row["pad_gaps_m"] = _pad_gaps_m(demo_path, ep, obj, hand, row["human"])
    held = _demos_of(demo_path, row["human"])
    row.update({f"{k}_demo_mode": held[k] for k in ("demo", "fingers", "why", "human_fingers")})
    row.update({f"{k}_demo_mode": v for k, v in _thumb_links_touching(demo_path, ep, hand).items()})
    if validate_demo and held["best"] is not None:
        from dexaug.pipeline.run import validate_demo_grasp

        row["demo_holds"] = bool(validate_demo_grasp(hand_name, obj, held["best"],
                                                     "lift-drop")["passed"])
    free = rerecord(raw, d / "free.mcap", object_mode="free")
    loose = _demos_of(free, row["human"])
    row.update({f"{k}_free": loose[k] for k in ("demo", "fingers", "why", "human_fingers")})
    row.update({f"{k}_free": v for k, v in _thumb_links_touching(free, ep, hand).items()})
    states, t = _states_on_operator_clock(free, ep)
    row["hold_height_m"] = _hold_height_m(ep, states, t)
    row["push_m"], row["first_touch"] = _approach_push(free, ep, states, t)
    row["lifted"] = row["hold_height_m"] >= 0.6 * cfg.lift_height_m
    return row


def finger_lag_s(hand_name: str, kp_scale: float, close_s: float = 0.3,
                 rad: float = 1.2) -> float:
    """Time (seconds) by which the first finger joint of the hand's second finger (the Shadow's
    FFJ4 is its spread, so the joint after it: FFJ3) trails a min-jerk closure of ``rad`` in
    ``close_s`` in free air, at the crossing of half the closure."""
    import mujoco

    from sim.hand.model import Hand
    from sim.world.hand_spec import ServoSettings
    from sim.world.scene import Scene

    hand = Hand.load(hand_name)
    sc = Scene(hand, None, servos=ServoSettings(kp_scale=kp_scale))
    m, d = sc.model, sc.data
    names = list(hand.joint_names)
    k = names.index(hand.config.finger(hand.finger_names[1]).joints[1])
    q1 = np.zeros(len(names))
    q1[k] = rad
    sc.set_hand_joints(np.zeros(len(names)))
    mujoco.mj_forward(m, d)
    t_cmd = t_sim = None
    for step in range(int(1.0 / m.opt.timestep)):
        t = step * m.opt.timestep
        s = np.clip(t / close_s, 0.0, 1.0)
        target = (s ** 3 * (10 - 15 * s + 6 * s * s)) * q1
        sc.set_hand_ctrl(target)
        mujoco.mj_step(m, d)
        if t_cmd is None and target[k] >= rad / 2:
            t_cmd = t
        if t_sim is None and d.qpos[sc.hand_qadr[k]] >= rad / 2:
            t_sim = t
    return float("nan") if t_cmd is None or t_sim is None else t_sim - t_cmd


#: the figures per episode that the summary counts, and their labels
COUNTED = (("demo_free", "demo (free)"), ("human_fingers_free", "person's fingers (free)"),
           ("lifted", "lifted (free)"), ("demo_demo_mode", "demo (demo mode)"),
           ("human_fingers_demo_mode", "person's fingers (demo mode)"),
           ("thumb_tip_demo_mode", "thumb tip touched (demo mode)"),
           ("thumb_other_demo_mode", "other thumb link touched (demo mode)"))


def summarize(rows: list[dict]) -> dict:
    """Counts of :data:`COUNTED` over the episodes that ran, overall and per object."""
    ok = [r for r in rows if "skipped" not in r]

    def counts(sel: list[dict]) -> dict:
        return {"episodes": len(sel), **{k: sum(bool(r.get(k)) for r in sel) for k, _ in COUNTED}}

    gaps = np.concatenate([r["pad_gaps_m"] for r in ok]) if ok else np.zeros(0)
    human = np.array([g for r in ok for g in r["human_pad_gaps_m"].values()])
    return {**counts(ok), "skipped": len(rows) - len(ok),
            "pushed": sum(r["push_m"] > PUSHED_M for r in ok),
            "pad_gap_median_m": float(np.median(gaps)) if len(gaps) else None,
            "human_pad_gap_median_m": float(np.median(human)) if len(human) else None,
            "human_pads_inside": int((human < 0.0).sum()), "human_pads": len(human),
            "per_object": {o: counts([r for r in ok if r["object"] == o])
                           for o in dict.fromkeys(r["object"] for r in ok)}}


def _print_rows(rows: list[dict]) -> None:
    print(f"\n{'object':22s} seed  human fingers  | free: robot fingers, lifted | demo mode: "
          "robot fingers | pushed (first touch)")
    for r in rows:
        if "skipped" in r:
            print(f"{r['object']:22s} {r['seed']:4d}  skipped: {r['skipped']}")
            continue
        free = ",".join(r["fingers_free"]) or r["why_free"][:40]
        held = ",".join(r["fingers_demo_mode"]) or r["why_demo_mode"][:40]
        print(f"{r['object']:22s} {r['seed']:4d}  {','.join(r['human'])} | {free} "
              f"{'LIFTED' if r['lifted'] else ''} | {held} | {r['push_m'] * 1e3:.1f} mm "
              f"{'(' + r['first_touch'] + ')' if r['first_touch'] else ''}")


def _print_summary(summary: dict, label: str, wall_s: float) -> None:
    n = summary["episodes"]

    def pct(k: str, sel: dict) -> str:
        return f"{sel[k]}/{sel['episodes']} ({100 * sel[k] / max(sel['episodes'], 1):.0f} %)"

    print(f"\n{label}: {n} episodes ({summary['skipped']} skipped), {wall_s:.0f} s")
    for k, name in COUNTED:
        print(f"  {name:38s} {pct(k, summary)}")
    print(f"  pushed > {PUSHED_M * 1e3:.0f} mm before the closure (free): {summary['pushed']}/{n}")
    if summary["human_pads"]:
        print(f"  the person's touching pads at the grasp: median "
              f"{summary['human_pad_gap_median_m'] * 1e3:.1f} mm off the surface, "
              f"{summary['human_pads_inside']}/{summary['human_pads']} inside it")
    print(f"\n{'object':22s} " + "  ".join(f"{name[:22]:>22s}" for _, name in COUNTED[:5]))
    for obj, c in summary["per_object"].items():
        print(f"{obj:22s} " + "  ".join(f"{pct(k, c):>22s}" for k, _ in COUNTED[:5]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0,
                    help="seeds first-seed … first-seed + seeds − 1 (a held-out set: --first-seed 4)")
    ap.add_argument("--operator", choices=sorted(OPERATORS), default="human",
                    help="human: a person's standoff and lift timing (default); synthetic: the "
                    "operator's old natural-speed settings (presses 1 cm in, holds)")
    ap.add_argument("--objects", default=",".join(OBJECTS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--hand", default=None, help="hand (default: configs/hands/default.toml)")
    ap.add_argument("--validate-demos", action="store_true",
                    help="also check each demo's grasp with the validator's lift-drop")
    ap.add_argument("--no-record", action="store_true",
                    help="do not write a record under benchmarks/measured/teleop_loop/")
    args = ap.parse_args()
    from sim.hand.config import default_hand_name
    from teleop.bridge.config import load_bridge_config

    hand = args.hand or default_hand_name()
    kp = load_bridge_config().servos.kp_scale
    lag = {"bridge": finger_lag_s(hand, kp), "model": finger_lag_s(hand, 1.0)}
    print(f"{hand}: finger lag behind a 0.3 s closure of 1.2 rad (free air): "
          f"{lag['bridge'] * 1e3:.0f} ms at the bridge's kp × {kp:g}, "
          f"{lag['model'] * 1e3:.0f} ms at the model's own")
    objects = args.objects.split(",")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        jobs = [(hand, o, s, args.operator, tmp, args.validate_demos) for o in objects
                for s in range(args.first_seed, args.first_seed + args.seeds)]
        with ProcessPoolExecutor(args.workers) as ex:
            rows = list(ex.map(run_one, jobs))
    wall = time.perf_counter() - t0
    _print_rows(rows)
    summary = summarize(rows)
    _print_summary(summary, f"{args.operator} operator", wall)
    if args.validate_demos:
        ok = [r for r in rows if "skipped" not in r]
        holds = [r for r in ok if r.get("demo_holds")]
        print(f"demo grasps that hold in the validator (lift-drop, real mass): {len(holds)}/"
              f"{sum(bool(r['demo_demo_mode']) for r in ok)}")
    if not args.no_record:
        from benchmarks.record import write_record

        path = write_record("teleop_loop", rows, summary={**summary, "wall_s": wall,
                                                          "finger_lag_s": lag},
                            config={**vars(args), "operator_settings": OPERATORS[args.operator],
                                    "human_touch_m": HUMAN_TOUCH_M},
                            hand=hand, objects=objects)
        print(f"record: {path}")


if __name__ == "__main__":
    main()
