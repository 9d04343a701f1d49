"""Validated grasps as episodes (sim.episodes) and the grasp environment (sim.envs), on a real
dataset: one record per run.

Makes the dataset the way a user does — ``dexaug augment`` of a committed demo at ``--n 20``
(one worker, seed 0) — and takes its grasps, kept and rejected alike (the rejected side table
holds the ones validation failed). Then, per grasp:

- rolls it out as an episode (:func:`sim.episodes.rollout.rollout`), timed: episodes/s on this
  machine, one core;
- checks the episode's verdict against the validator's (``Validator.validate``) and the one
  the dataset stored;
- replays the episode's actions in a freshly built model (:func:`sim.episodes.replay.replay`):
  the largest joint error (the issue's acceptance: ≤ 1e-6 rad);
- replays them through the dm_env environment (:func:`sim.envs.grasp_env.grasp_env`, the table
  under the object) and takes its verdict: the agreement with lift-drop (the issue's: ≥ 95 %
  of 20 grasps);
- rolls it out again with a 5 cm approach (:mod:`sim.episodes.approach`): whether the approach
  was kept (collision-free), the verdict's agreement with the validator's, the replay error.

Writes ``benchmarks/measured/episodes/<stamp>.json`` through :func:`benchmarks.record.write_record`.
Usage: ``.venv/bin/python benchmarks/bench_episodes.py [--demo 004_sugar_box] [--n 20]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from augment import dataset
from augment.grasp_table import grasps_of, with_rejected
from benchmarks.record import write_record
from sim.envs.grasp_env import episode_actions, grasp_env, run_actions
from sim.episodes.replay import max_joint_error, replay
from sim.episodes.rollout import rollout
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.paths import REPO_ROOT
from sim.validate.validator import Validator
from sim.world.objects import load_object

#: the approach the second pass rolls out with (metres out along the palm normal)
APPROACH_M = 0.05


def _augmented(demo: str, n: int, out: Path) -> tuple[str, dataset.ObjectTable]:
    """``dexaug augment`` of ``recordings/demos/<demo>.json`` into ``out``: its object and
    table (kept and rejected grasps)."""
    cmd = [str(Path(sys.executable).parent / "dexaug"), "augment",
           str(REPO_ROOT / "recordings" / "demos" / f"{demo}.json"), "--n", str(n), "--seed", "0",
           "--workers", "1", "--gallery", "0", "--out", str(out), "-q"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    path = next(out.glob("*/grasps.h5"))
    tables = dataset.load(path)
    name = next(iter(tables))
    return name, with_rejected(tables[name])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--demo", default="004_sugar_box", help="committed demo to augment")
    ap.add_argument("--n", type=int, default=20, help="grasps to augment and roll out")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        name, table = _augmented(args.demo, args.n, Path(tmp))
    grasps = grasps_of(table, args.n)
    stored = [bool(p) for p in table["passed"][:len(grasps)]]
    hand = Hand.load(str(table.attrs.get("hand", default_hand_name())))
    validator = Validator(hand, load_object(name))
    fresh = Validator(hand, load_object(name)).scene("lift-drop")   # a model of its own

    t0 = time.perf_counter()
    episodes = [rollout(validator, g, index=i) for i, g in enumerate(grasps)]
    rollout_s = time.perf_counter() - t0
    steps = sum(len(e) for e in episodes)

    env = grasp_env(validator, grasps)
    rows = []
    t0 = time.perf_counter()
    for i, (g, ep) in enumerate(zip(grasps, episodes, strict=True)):
        want = validator.validate(g, "lift-drop")
        env.task.select(i)
        env.reset()
        last = run_actions(env, episode_actions(ep))
        err = max_joint_error(ep, replay(ep, fresh)) if len(ep) else 0.0
        rows.append({"index": i, "steps": len(ep), "validator_passed": want.passed,
                     "validator_failure": want.failure, "dataset_passed": stored[i],
                     "episode_passed": ep.success, "episode_failure": ep.failure,
                     "env_passed": last.reward == 1.0, "env_failure": env.task.failure,
                     "replay_max_joint_error_rad": err})
    env_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    approached = [rollout(validator, g, index=i, approach_m=APPROACH_M)
                  for i, g in enumerate(grasps)]
    approach_s = time.perf_counter() - t0
    for row, ep in zip(rows, approached, strict=True):
        row.update(approach_kept=ep.approach_m > 0, approach_passed=ep.success,
                   approach_failure=ep.failure,
                   approach_replay_max_joint_error_rad=max_joint_error(ep, replay(ep, fresh))
                   if len(ep) else 0.0)
    n = len(rows)
    summary = {
        "object": name, "grasps": n,
        "validator_passes": sum(r["validator_passed"] for r in rows),
        "episodes_per_s": n / rollout_s, "steps_per_s": steps / rollout_s,
        "episode_validator_agreement": sum(r["episode_passed"] == r["validator_passed"]
                                           for r in rows) / n,
        "dataset_validator_agreement": sum(r["dataset_passed"] == r["validator_passed"]
                                           for r in rows) / n,
        "env_validator_agreement": sum(r["env_passed"] == r["validator_passed"] for r in rows) / n,
        "env_failure_reason_agreement": sum(r["env_failure"] == r["validator_failure"]
                                            for r in rows) / n,
        "replay_max_joint_error_rad": max(r["replay_max_joint_error_rad"] for r in rows),
        "env_replay_s": env_s,
        "approach_m": APPROACH_M,
        "approach_kept": sum(r["approach_kept"] for r in rows),
        "approach_episodes_per_s": n / approach_s,
        "approach_validator_agreement": sum(r["approach_passed"] == r["validator_passed"]
                                            for r in rows) / n,
        "approach_replay_max_joint_error_rad": max(r["approach_replay_max_joint_error_rad"]
                                                   for r in rows),
    }
    path = write_record("episodes", rows, summary=summary,
                        config={"demo": args.demo, "n": args.n, "table": True, "n_sub_steps": 1,
                                "approach_m": APPROACH_M, "approach_s": 0.5},
                        hand=hand.name, objects=[name])
    for k, v in summary.items():
        print(f"{k}: {v}")
    print(f"record: {path}")


if __name__ == "__main__":
    main()
