"""The LeRobot export (augment.export.lerobot, issue #55): rollouts of one demo, with or without a
camera, or recorded sessions; one record per run.

Rollouts (the default) make the dataset the way a user does — ``dexaug augment`` of a committed
demo (one worker, seed 0; ``--n 200`` of ``004_sugar_box``) — or take one (``--dataset``),
then:

- roll out every grasp, kept and rejected, and write the successful rollouts as a LeRobot
  dataset, timed as the command does it (rollouts and writing: episodes/s), and the writing
  alone from episodes already rolled out; with ``--camera HxW`` every frame is rendered too
  (the feature ``observation.images.overview``): episodes/s with images;
- read the folder back with pyarrow (:mod:`augment.export.lerobot_read`): frames, actions
  (and images) against the episodes' arrays (bit for bit), and the actions replayed from the
  dataset alone in a freshly built model: the largest joint error (the issue's acceptance:
  ≤ 1e-6 rad).

Sessions (``--sessions MCAP...``, e.g. ``recordings/*.mcap``) are exported as the command
does (:mod:`augment.export.lerobot_sessions`: reading each MCAP, resampling it to ``--fps``,
writing), ``--repeat`` times: episodes/s and frames/s of the median pass; each frame checked
against the step it holds (bit for bit). A file that is no bridge session (the scripted
``demo_*.mcap`` hold no joint targets) is listed with its one-line reason and left out.

With ``--lerobot-python PY`` (a venv with LeRobot, outside the project's), either mode loads
the folder with LeRobot's own ``LeRobotDataset`` in that interpreter
(``benchmarks/outside/lerobot_reader.py``, which imports nothing of dexaug) and compares its
frames, actions (and images) with the export's.

Writes ``benchmarks/measured/export_lerobot/<stamp>.json`` through
:func:`benchmarks.record.write_record` (its ``config.mode``: rollouts, or sessions).
Usage: ``.venv/bin/python benchmarks/bench_export_lerobot.py [--demo 004_sugar_box] [--n 200]
[--dataset grasps.h5] [--camera 32x32] [--sessions recordings/*.mcap [--fps 50] [--repeat 3]]
[--lerobot-python /tmp/exp/lerobot-venv/bin/python]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
#: LeRobot's side of the check, run by LeRobot's own interpreter (``--lerobot-python``)
LEROBOT_READER = ROOT / "benchmarks" / "outside" / "lerobot_reader.py"


def _augmented(demo: str, n: int, out: Path) -> Path:
    """``dexaug augment`` of ``recordings/demos/<demo>.json`` into ``out``: its grasps.h5."""
    cmd = [str(Path(sys.executable).parent / "dexaug"), "augment",
           str(ROOT / "recordings" / "demos" / f"{demo}.json"), "--n", str(n), "--seed", "0",
           "--workers", "1", "--gallery", "0", "--out", str(out), "-q"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return next(out.glob("*/grasps.h5"))


def lerobot_check(python: str, root: Path, expected: dict[str, np.ndarray],
                  tmp: Path) -> dict[str, Any]:
    """LeRobot's reading of the export at ``root`` (``benchmarks/outside/lerobot_reader.py`` in
    the interpreter ``python``) against ``expected`` (per feature its rows over the dataset):
    its JSON summary, or ``{"lerobot_error": last line}`` where it fails."""
    np.savez(tmp / "expected.npz", **expected)
    proc = subprocess.run([python, str(LEROBOT_READER), str(root), str(tmp / "expected.npz")],
                          capture_output=True, text=True, timeout=1200,
                          env={"PATH": "/usr/bin:/bin", "HF_HUB_OFFLINE": "1",
                               "HF_DATASETS_OFFLINE": "1", "HOME": str(tmp)})
    if proc.returncode != 0:
        return {"lerobot_error": proc.stderr.strip().splitlines()[-1:]}
    return {"lerobot": json.loads(proc.stdout.strip().splitlines()[-1])}


def _replay_error(data: Any, i: int, hand: Any, fresh: dict[str, Any]) -> float:
    """The largest joint error (rad) of episode ``i``'s actions replayed from the dataset alone
    in a freshly built lift-drop scene of its object (``fresh``: one per object)."""
    from augment.export.lerobot_read import replayable
    from sim.episodes.replay import replay
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    back = replayable(data, i)
    if back.object not in fresh:
        fresh[back.object] = Validator(hand, load_object(back.object)).scene("lift-drop")
    return float(np.abs(replay(back, fresh[back.object])["hand_qpos"][:len(back)]
                        - back.states["hand_qpos"]).max())


def run_rollouts(args: argparse.Namespace, tmp: Path) -> Path:
    """Rollouts mode (module docstring); returns the record's path."""
    from augment import dataset
    from augment.export.lerobot import write_lerobot
    from augment.export.lerobot_frames import CAMERA_FEATURE
    from augment.export.lerobot_read import read_lerobot
    from augment.export.lerobot_rollouts import rollouts
    from augment.grasp_table import with_rejected
    from benchmarks.record import write_record
    from sim.hand.model import Hand

    if args.camera is not None:
        from sim.world.render import select_gl_backend

        select_gl_backend()
    src = Path(args.dataset) if args.dataset else _augmented(args.demo, args.n, tmp / "aug")
    tables = {k: with_rejected(t) for k, t in dataset.load(src).items()}
    hand = Hand.load(str(next(iter(tables.values())).attrs["hand"]))
    t0 = time.perf_counter()
    episodes = list(rollouts(tables, hand, camera=args.camera))   # what the command streams
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
                               ep.states["hand_qpos"][:n])
            and (args.camera is None or np.array_equal(f[CAMERA_FEATURE], ep.frames[:n])))
        rows.append({"episode_index": i, "object": ep.object, "grasp_index": ep.grasp_index,
                     "frames": n, "arrays_equal": same,
                     "replay_max_joint_error_rad": _replay_error(data, i, hand, fresh)})
    n_roll = len(episodes)
    summary: dict[str, Any] = {
        "source": "dataset" if args.dataset else f"dexaug augment {args.demo} --n {args.n}",
        "camera": None if args.camera is None else "x".join(map(str, args.camera)),
        "rollouts": n_roll, "episodes": done.episodes, "failed_rollouts": done.failed,
        "frames": done.frames, "fps": data.info["fps"], "data_files": len(done.data_files),
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
        keys = ["observation.state", "action", "episode_index"]
        keys += [CAMERA_FEATURE] if args.camera is not None else []
        summary.update(lerobot_check(args.lerobot_python, tmp / "lerobot",
                                     {k: data.frames[k] for k in keys}, tmp))
    return write_record("export_lerobot", rows, summary=summary,
                        config={"mode": "rollouts", "demo": args.demo, "n": args.n,
                                "rejected": True, "camera": summary["camera"],
                                "lerobot_python": args.lerobot_python},
                        hand=hand.name, objects=list(tables))


def _session_rows(paths: list[Path], fps: int) -> tuple[list[dict[str, Any]], list[Path]]:
    """Per session given: its hand, object, steps and step rate and the frames it gives at
    ``fps``, or the one-line reason it is no episode; and the sessions that are."""
    from augment.export.lerobot_sessions import session_episode, step_rate_hz
    from sim.errors import DexaugError
    from teleop.record.session_steps import read_session_steps

    rows: list[dict[str, Any]] = []
    ok: list[Path] = []
    for p in paths:
        try:
            steps = read_session_steps(p)
            ep = session_episode(steps, fps)
        except DexaugError as exc:
            rows.append({"session": p.name, "refused": str(exc)})
            continue
        ok.append(p)
        rows.append({"session": p.name, "hand": steps.hand, "object": steps.object,
                     "steps": len(steps), "step_hz": step_rate_hz(steps), "frames": len(ep),
                     "refused": None})
    return rows, ok


def _frames_are_the_steps(data: Any, paths: list[Path]) -> list[bool]:
    """Per exported session: each frame's state and action the recorded step it holds
    (``session.step``), bit for bit, no step held twice."""
    from teleop.record.session_steps import read_session_steps

    out = []
    for i, p in enumerate(paths):
        steps, f = read_session_steps(p), data.episode_frames(i)
        at = f["session.step"]
        state = np.concatenate([steps.qpos, steps.palm_pose, steps.object_pose], axis=1)[at]
        out.append(bool(np.array_equal(f["observation.state"], state)
                        and np.array_equal(f["action"], steps.q_target[at])
                        and np.all(np.diff(at) > 0)))
    return out


def run_sessions(args: argparse.Namespace, tmp: Path) -> Path:
    """Sessions mode (module docstring); returns the record's path."""
    from augment.export.lerobot import write_lerobot
    from augment.export.lerobot_read import read_lerobot
    from augment.export.lerobot_sessions import session_episode
    from benchmarks.record import write_record
    from teleop.record.session_steps import read_session_steps

    rows, ok = _session_rows([Path(p) for p in args.sessions], args.fps)
    if not ok:
        raise SystemExit("no session given can be an episode: " + "; ".join(
            r["refused"] for r in rows))
    pass_s = []
    for k in range(args.repeat):
        t0 = time.perf_counter()
        done = write_lerobot(tmp / f"lerobot{k}", (session_episode(read_session_steps(p), args.fps)
                                                   for p in ok), source="bench")
        pass_s.append(time.perf_counter() - t0)
    wall_s = statistics.median(pass_s)
    data = read_lerobot(tmp / "lerobot0")
    exact = _frames_are_the_steps(data, ok)
    exported = [r for r in rows if r["refused"] is None]
    for row, same in zip(exported, exact, strict=True):
        row["arrays_equal"] = same
    ts, fi = data.frames["timestamp"], data.frames["frame_index"]
    summary: dict[str, Any] = {
        "sessions": len(ok), "refused": len(rows) - len(ok), "episodes": done.episodes,
        "frames": done.frames, "fps": data.info["fps"],
        "fps_is_int": type(data.info["fps"]) is int, "repeat": args.repeat,
        "export_s": pass_s, "episodes_per_s": done.episodes / wall_s,
        "frames_per_s": done.frames / wall_s, "arrays_equal": all(exact),
        "timestamps_exact": bool(np.array_equal(ts, (fi / args.fps).astype(np.float32)))}
    if args.lerobot_python:
        summary.update(lerobot_check(args.lerobot_python, tmp / "lerobot0", {
            k: data.frames[k] for k in ("observation.state", "action", "episode_index")}, tmp))
    return write_record("export_lerobot", rows, summary=summary,
                        config={"mode": "sessions", "sessions": [str(p) for p in args.sessions],
                                "fps": args.fps, "repeat": args.repeat,
                                "lerobot_python": args.lerobot_python},
                        hand=exported[0]["hand"], objects=sorted({r["object"] for r in exported}))


def main() -> None:
    from augment.export.lerobot_sessions import SESSION_FPS
    from dexaug.commands.argtypes import count
    from dexaug.commands.export import camera_size

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--demo", default="004_sugar_box", help="committed demo to augment")
    ap.add_argument("--n", type=int, default=200, help="grasps to augment (kept and rejected "
                    "are all rolled out)")
    ap.add_argument("--dataset", help="a grasps.h5 to export instead of augmenting the demo")
    ap.add_argument("--camera", type=camera_size, metavar="HxW",
                    help="rollouts: render every frame (HEIGHTxWIDTH pixels) into the export")
    ap.add_argument("--sessions", nargs="+", metavar="MCAP",
                    help="export these recorded sessions instead of rollouts")
    ap.add_argument("--fps", type=count, default=SESSION_FPS,
                    help="sessions: frames a second; default %(default)s")
    ap.add_argument("--repeat", type=count, default=3,
                    help="sessions: export passes timed (the median is reported); default "
                         "%(default)s")
    ap.add_argument("--lerobot-python", help="a Python with LeRobot installed: load the export "
                    "with its LeRobotDataset there")
    args = ap.parse_args()
    if args.sessions and args.camera is not None:
        ap.error("--camera renders rollouts; sessions have no camera")
    with tempfile.TemporaryDirectory() as tmp:
        path = (run_sessions if args.sessions else run_rollouts)(args, Path(tmp))
    record = json.loads(path.read_text())
    for k, v in record["summary"].items():
        print(f"{k}: {v}")
    print(f"record: {path}")


if __name__ == "__main__":
    main()
