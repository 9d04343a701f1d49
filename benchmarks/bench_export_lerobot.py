"""The LeRobot export (augment.export.lerobot, issue #55) on ≥ 100 validated episodes of one
demo: one record per run.

Makes the dataset the way a user does — ``dexaug augment`` of a committed demo (one worker,
seed 0; ``--n 200`` of ``004_sugar_box``) — or takes one (``--dataset``),
then:

- rolls out every grasp, kept and rejected, and writes the successful rollouts as a LeRobot
  dataset, timed as the command does it (rollouts and writing: episodes/s), and the writing
  alone from episodes already rolled out;
- reads the folder back with pyarrow (:mod:`augment.export.lerobot_read`): frames and actions
  against the episodes' arrays (bit for bit), and the actions replayed from the dataset alone
  in a freshly built model: the largest joint error (the issue's acceptance: ≤ 1e-6 rad);
- with ``--lerobot-python PY`` (a venv with LeRobot, outside the project's), loads the folder
  with LeRobot's own ``LeRobotDataset`` in that interpreter
  (``benchmarks/outside/lerobot_reader.py``, which imports nothing of dexaug) and compares
  its frames and actions with the episodes'.

Writes ``benchmarks/measured/export_lerobot/<stamp>.json`` through
:func:`benchmarks.record.write_record`. Usage: ``.venv/bin/python
benchmarks/bench_export_lerobot.py [--demo 004_sugar_box] [--n 200] [--dataset grasps.h5]
[--lerobot-python /tmp/exp/lerobot-venv/bin/python]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: LeRobot's side of the check, run by LeRobot's own interpreter (``--lerobot-python``)
LEROBOT_READER = ROOT / "benchmarks" / "outside" / "lerobot_reader.py"


def _augmented(demo: str, n: int, out: Path) -> Path:
    """``dexaug augment`` of ``recordings/demos/<demo>.json`` into ``out``: its grasps.h5."""
    cmd = [str(Path(sys.executable).parent / "dexaug"), "augment",
           str(ROOT / "recordings" / "demos" / f"{demo}.json"), "--n", str(n), "--seed", "0",
           "--workers", "1", "--gallery", "0", "--out", str(out), "-q"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return next(out.glob("*/grasps.h5"))


def run(args: argparse.Namespace, tmp: Path) -> None:
    sys.path.insert(0, str(ROOT))
    from augment import dataset
    from augment.export.lerobot import write_lerobot
    from augment.export.lerobot_read import read_lerobot, replayable
    from augment.export.lerobot_rollouts import rollouts
    from augment.grasp_table import with_rejected
    from benchmarks.record import write_record
    from sim.episodes.replay import replay
    from sim.hand.model import Hand
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    src = Path(args.dataset) if args.dataset else _augmented(args.demo, args.n, tmp / "aug")
    tables = {k: with_rejected(t) for k, t in dataset.load(src).items()}
    hand = Hand.load(str(next(iter(tables.values())).attrs["hand"]))
    t0 = time.perf_counter()
    episodes = list(rollouts(tables, hand))   # kept for the checks: what the command streams
    rollout_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    done = write_lerobot(tmp / "lerobot", episodes, source=str(src))
    write_s = time.perf_counter() - t0
    kept = [e for e in episodes if e.success]
    stored = [bool(p) for t in tables.values() for p in t["passed"]]   # the dataset's verdicts
    data = read_lerobot(tmp / "lerobot")
    rows: list[dict[str, Any]] = []
    fresh: dict[str, Any] = {}
    for i, ep in enumerate(kept):
        f, n = data.episode_frames(i), len(ep)
        same = (np.array_equal(f["action"], np.concatenate(
            [ep.ctrl, ep.base_target_pos, ep.base_target_quat], axis=1))
            and np.array_equal(f["observation.state"][:, :len(ep.joint_names)],
                               ep.states["hand_qpos"][:n]))
        back = replayable(data, i)
        if back.object not in fresh:
            fresh[back.object] = Validator(hand, load_object(back.object)).scene("lift-drop")
        err = float(np.abs(replay(back, fresh[back.object])["hand_qpos"][:n]
                           - back.states["hand_qpos"]).max())
        rows.append({"episode_index": i, "object": ep.object, "grasp_index": ep.grasp_index,
                     "frames": n, "arrays_equal": same, "replay_max_joint_error_rad": err})
    n_roll = len(episodes)
    summary: dict[str, Any] = {
        "source": "dataset" if args.dataset else f"dexaug augment {args.demo} --n {args.n}",
        "rollouts": n_roll, "episodes": done.episodes, "failed_rollouts": done.failed,
        "frames": done.frames, "data_files": len(done.data_files),
        "bytes_on_disk": sum(p.stat().st_size for p in (tmp / "lerobot").rglob("*") if p.is_file()),
        "export_episodes_per_s": n_roll / (rollout_s + write_s),
        "rollout_episodes_per_s": n_roll / rollout_s,
        "write_episodes_per_s": done.episodes / write_s,
        "rollout_s": rollout_s, "write_s": write_s,
        "rollout_dataset_verdict_agreement": sum(
            e.success == p for e, p in zip(episodes, stored, strict=True)) / n_roll,
        "arrays_equal": all(r["arrays_equal"] for r in rows),
        "replay_max_joint_error_rad": max(r["replay_max_joint_error_rad"] for r in rows),
        "at_least_100_episodes": done.episodes >= 100,
    }
    if args.lerobot_python:
        np.savez(tmp / "expected.npz", **{k: data.frames[k] for k in
                                          ("observation.state", "action", "episode_index")})
        for i, ep in enumerate(kept):   # the episodes' own arrays, not the export's reading
            sel = slice(data.episodes[i]["dataset_from_index"], data.episodes[i]["dataset_to_index"])
            assert np.array_equal(data.frames["action"][sel][:, :len(ep.actuator_names)], ep.ctrl)
        proc = subprocess.run([args.lerobot_python, str(LEROBOT_READER),
                               str(tmp / "lerobot"), str(tmp / "expected.npz")],
                              capture_output=True, text=True, timeout=1200,
                              env={"PATH": "/usr/bin:/bin", "HF_HUB_OFFLINE": "1",
                                   "HF_DATASETS_OFFLINE": "1", "HOME": str(tmp)})
        if proc.returncode != 0:
            summary["lerobot_error"] = proc.stderr.strip().splitlines()[-1:]
        else:
            summary["lerobot"] = json.loads(proc.stdout.strip().splitlines()[-1])
    path = write_record("export_lerobot", rows, summary=summary,
                        config={"demo": args.demo, "n": args.n, "rejected": True,
                                "lerobot_python": args.lerobot_python},
                        hand=hand.name, objects=list(tables))
    for k, v in summary.items():
        print(f"{k}: {v}")
    print(f"record: {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--demo", default="004_sugar_box", help="committed demo to augment")
    ap.add_argument("--n", type=int, default=200, help="grasps to augment (kept and rejected "
                    "are all rolled out)")
    ap.add_argument("--dataset", help="a grasps.h5 to export instead of augmenting the demo")
    ap.add_argument("--lerobot-python", help="a Python with LeRobot installed: load the export "
                    "with its LeRobotDataset there")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        run(args, Path(tmp))


if __name__ == "__main__":
    main()
