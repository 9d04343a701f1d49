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

Speeds: ``natural`` closes in 0.3 s and lifts 0.15 s later (a person: first contact → lift
≈ 0.35 s), ``slow`` in 0.8 s and 0.8 s (the synthetic operator's default). Objects are the
generic-grasp ones by default (no hand-built reference grasp); ``--objects`` takes any list.
Also measured: how far a finger servo lags a 0.3 s min-jerk closure of 1.2 rad in free air at
the bridge's servo gains and at the model's own (DESIGN §6 "fingers at human speed").

    .venv/bin/python benchmarks/bench_teleop_loop.py [--seeds 2] [--first-seed 0]
                                                      [--speed natural|slow]
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

OBJECTS = ("006_mustard_bottle", "013_apple", "007_tuna_fish_can", "008_pudding_box",
           "009_gelatin_box", "014_lemon", "016_pear", "017_orange", "021_bleach_cleanser",
           "036_wood_block", "054_softball", "056_tennis_ball", "065_d_cups",
           "002_master_chef_can")
SPEEDS = {"natural": (0.3, 0.15), "slow": (0.8, 0.8)}
HUMAN_TOUCH_M = 0.008
PUSHED_M = 0.005


def _human_fingers(ep, obj: str, hand) -> list[str]:
    """Robot fingers whose operator finger's pad is within HUMAN_TOUCH_M of the object at the
    grasp moment (the mapping of the hand's retarget.toml)."""
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
    return sorted(n for n, g in zip(names, gap, strict=True) if g < HUMAN_TOUCH_M)


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


def run_one(job: tuple[str, str, int, str, str, bool]) -> dict:
    hand_name, obj, seed, speed, out, validate_demo = job
    os.environ.setdefault("MUJOCO_GL", "egl")
    from sim.demo import DemoError
    from sim.hand.model import Hand
    from teleop.bridge.config import load_bridge_config
    from teleop.bridge.rerecord import rerecord
    from teleop.record.demos import extract_demos
    from teleop.synthetic.config import load_synth_config
    from teleop.synthetic.synthesize import synthesize
    from teleop.synthetic.writer import write_session

    close_s, settle_s = SPEEDS[speed]
    rng = np.random.default_rng(seed)
    yaw = float(rng.uniform(-40, 40))
    bridge = load_bridge_config()   # the object's spot on the bridge's table, tracking space
    spot = np.array([*bridge.object_pos_m, 0.0]) - bridge.world_offset_m
    pos = tuple(spot + np.array([rng.uniform(-0.03, 0.03), rng.uniform(-0.05, 0.05), 0.0]))
    cfg = dataclasses.replace(load_synth_config(), close_s=close_s, settle_s=settle_s,
                              object_rpy_deg=(0.0, 0.0, yaw), object_pos_m=pos)
    hand = Hand.load(hand_name)
    row = {"object": obj, "seed": seed}
    try:
        ep = synthesize(obj, hand=hand, seed=seed, config=cfg)
    except Exception as exc:   # no generic grasp for this object: reported, not counted
        row["skipped"] = f"{type(exc).__name__}: {str(exc)[:80]}"
        return row
    d = Path(out) / f"{obj}_{seed}"
    d.mkdir(parents=True, exist_ok=True)
    raw = write_session(ep, d / "raw.mcap", overwrite=True)
    row["human"] = _human_fingers(ep, obj, hand)
    demo_path = rerecord(raw, d / "demo.mcap", object_mode="demo")
    row["pad_gaps_m"] = _pad_gaps_m(demo_path, ep, obj, hand, row["human"])
    try:
        demos = extract_demos(demo_path)
    except DemoError as exc:
        demos, row["why"] = [], str(exc).split(": ", 2)[-1][:90]
    best = max(demos, key=lambda x: len(x.fingers)) if demos else None
    row["fingers"] = sorted(best.fingers) if best else []
    if validate_demo and best is not None:
        from dexaug.pipeline.run import validate_demo_grasp

        row["demo_holds"] = bool(validate_demo_grasp(hand_name, obj, best, "lift-drop")["passed"])
    row["demo"] = bool(demos)
    row["human_fingers"] = bool(demos) and set(row["human"]) <= set(row["fingers"])
    free = rerecord(raw, d / "free.mcap", object_mode="free")
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0,
                    help="seeds first-seed … first-seed + seeds − 1 (a held-out set: --first-seed 4)")
    ap.add_argument("--speed", choices=sorted(SPEEDS), default="natural")
    ap.add_argument("--objects", default=",".join(OBJECTS))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--hand", default=None, help="hand (default: configs/hands/default.toml)")
    ap.add_argument("--validate-demos", action="store_true",
                    help="also check each demo's grasp with the validator's lift-drop")
    args = ap.parse_args()
    from sim.hand.config import default_hand_name
    from teleop.bridge.config import load_bridge_config

    hand = args.hand or default_hand_name()
    kp = load_bridge_config().servos.kp_scale
    print(f"{hand}: finger lag behind a 0.3 s closure of 1.2 rad (free air): "
          f"{finger_lag_s(hand, kp) * 1e3:.0f} ms at the bridge's kp × {kp:g}, "
          f"{finger_lag_s(hand, 1.0) * 1e3:.0f} ms at the model's own")
    objects = args.objects.split(",")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        jobs = [(hand, o, s, args.speed, tmp, args.validate_demos) for o in objects
                for s in range(args.first_seed, args.first_seed + args.seeds)]
        with ProcessPoolExecutor(args.workers) as ex:
            rows = list(ex.map(run_one, jobs))
    wall = time.perf_counter() - t0
    print(f"\n{'object':22s} seed  demo  human fingers → robot fingers{'':14s} hold height  "
          "pushed before closure (first touch)  demo grasp in lift-drop")
    for r in rows:
        if "skipped" in r:
            print(f"{r['object']:22s} {r['seed']:4d}  skipped: {r['skipped']}")
            continue
        fingers = f"{','.join(r['human'])} → {','.join(r['fingers']) or r.get('why', '-')}"
        print(f"{r['object']:22s} {r['seed']:4d}  {'yes' if r['demo'] else 'no ':4s}  "
              f"{fingers[:44]:44s} {r['hold_height_m'] * 1e3:6.0f} mm "
              f"{'lifted' if r['lifted'] else '      '} {r['push_m'] * 1e3:5.1f} mm "
              f"{'(' + r['first_touch'] + ')' if r['first_touch'] else '':16s}"
              f"{'' if 'demo_holds' not in r else 'holds' if r['demo_holds'] else 'slips'}")
    ok = [r for r in rows if "skipped" not in r]
    n = len(ok)
    share = {k: sum(bool(r[k]) for r in ok) for k in ("demo", "human_fingers", "lifted")}
    gaps = np.concatenate([r["pad_gaps_m"] for r in ok]) if ok else np.zeros(0)
    print(f"\nsimulated pads of the human's fingers at the grasp moment (demo mode): gap to the "
          f"object median {np.median(gaps) * 1e3:.1f} mm, |gap| median "
          f"{np.median(np.abs(gaps)) * 1e3:.1f} mm, within 3 mm {np.mean(np.abs(gaps) <= 0.003):.0%}"
          f" ({len(gaps)} pads)")
    print(f"\n{args.speed} speed, {n} episodes ({len(rows) - n} skipped), {wall:.0f} s: demos "
          f"{share['demo']}/{n} ({100 * share['demo'] / max(n, 1):.0f} %), with the human's "
          f"fingers {share['human_fingers']}/{n} ({100 * share['human_fingers'] / max(n, 1):.0f} "
          f"%), lifted in free mode {share['lifted']}/{n} "
          f"({100 * share['lifted'] / max(n, 1):.0f} %)")
    pushed = [r for r in ok if r["push_m"] > PUSHED_M]
    print(f"pushed more than {PUSHED_M * 1e3:.0f} mm before the closure began (free mode): "
          f"{len(pushed)}/{n}; lifted among those: {sum(bool(r['lifted']) for r in pushed)}")
    if args.validate_demos:
        holds = [r for r in ok if r.get("demo_holds")]
        print(f"demo grasps that hold in the validator (lift-drop, real mass): {len(holds)}/"
              f"{share['demo']}; lifted in free mode among those episodes: "
              f"{sum(bool(r['lifted']) for r in holds)}/{len(holds)}")


if __name__ == "__main__":
    main()
