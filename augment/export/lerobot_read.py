"""Read a LeRobot export back with pyarrow alone, and turn its episodes into replayable ones.

Why: the export must be checkable without LeRobot (a heavy, torch-based install kept out of
dexaug's): :func:`read_lerobot` reads meta and frames as LeRobot's format defines them, and
:func:`replayable` rebuilds from one exported episode (its actions, the protocol's conditions
and its initial MuJoCo state, :mod:`augment.export.lerobot_frames`) an
:class:`sim.episodes.episode.Episode` that :func:`sim.episodes.replay.replay` plays in a fresh
model: the dataset alone, not the run that wrote it, reproduces the recorded states.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from augment.export.lerobot import EPISODES_PATH, pyarrow_modules
from augment.export.lerobot_images import decode_column
from sim.episodes.episode import Episode

__all__ = ["LeRobotData", "read_lerobot", "replayable"]


@dataclass
class LeRobotData:
    """An export as read: info.json, stats.json, the task texts by index, one dict per
    meta/episodes row, and every data column over all files (rows = frames, in file order)."""

    info: dict[str, Any]
    stats: dict[str, dict[str, np.ndarray]]
    tasks: list[str]
    episodes: list[dict[str, Any]]
    frames: dict[str, np.ndarray]

    def episode_frames(self, episode_index: int) -> dict[str, np.ndarray]:
        """The frames of one episode (by its ``dataset_from_index`` / ``dataset_to_index``)."""
        row = self.episodes[episode_index]
        sel = slice(row["dataset_from_index"], row["dataset_to_index"])
        return {k: v[sel] for k, v in self.frames.items()}


def read_lerobot(root: Path | str) -> LeRobotData:
    """Read the export at ``root`` (module docstring); vector features as (frames, n) arrays,
    cameras as (frames, h, w, 3) uint8 images."""
    _, pq = pyarrow_modules()
    root = Path(root)
    info = json.loads((root / "meta" / "info.json").read_text())
    stats = {k: {s: np.asarray(v) for s, v in per.items()}
             for k, per in json.loads((root / "meta" / "stats.json").read_text()).items()}
    tasks_table = pq.read_table(root / "meta" / "tasks.parquet").to_pydict()
    tasks = [t for _, t in sorted(zip(tasks_table["task_index"], tasks_table["task"],
                                      strict=True))]
    episodes = pq.read_table(root / EPISODES_PATH.format(chunk_index=0, file_index=0)).to_pylist()
    files = sorted((root / "data").glob("chunk-*/file-*.parquet"))
    tables = [pq.read_table(f) for f in files]
    frames = {k: np.concatenate([_column(t[k], ft) for t in tables])
              for k, ft in info["features"].items()}
    return LeRobotData(info, stats, tasks, episodes, frames)


def _column(col: Any, ft: dict[str, Any]) -> np.ndarray:
    """An Arrow column as NumPy: (rows,) for a shape-(1,) feature, (rows, h, w, 3) uint8 for
    a camera (its PNGs decoded), else (rows, n)."""
    if ft["dtype"] == "image":
        return decode_column(col)
    if list(ft["shape"]) == [1]:
        return col.to_numpy()
    flat = col.combine_chunks().flatten().to_numpy()
    return flat.reshape(len(col), *ft["shape"])


def replayable(data: LeRobotData, episode_index: int) -> Episode:
    """The exported episode ``episode_index`` as an :class:`Episode` that
    :func:`sim.episodes.replay.replay` plays (actions, conditions, initial state; the states
    are the exported frames', without the row after the last step, which is no frame). Its
    arrays are copies: changing them leaves ``data`` as read."""
    row = data.episodes[episode_index]
    f = {k: v.copy() for k, v in data.episode_frames(episode_index).items()}   # not views
    names = data.info["features"]
    n_act = len(names["action"]["names"]) - 7
    joints = tuple(n.removesuffix(".pos") for n in names["observation.state"]["names"]
                   if n.endswith(".pos"))
    nj = len(joints)
    state, act, pin = f["observation.state"], f["action"], f["protocol.pin_pose"]
    pin_pose = np.where(pin[:, :1] > 0.5, pin[:, 1:], np.nan)
    return Episode(
        hand=row["dexaug/hand"], object=row["dexaug/object"], protocol=row["dexaug/protocol"],
        grasp_index=row["dexaug/grasp_index"], success=bool(f["next.success"][-1]), failure=None,
        timestep_s=1.0 / data.info["fps"], joint_names=joints,
        actuator_names=tuple(names["action"]["names"][:n_act]),
        finger_names=tuple(names["observation.fingertip_force"]["names"]),
        initial_state=np.asarray(row["dexaug/initial_state"]),
        initial_gravity=np.asarray(row["dexaug/initial_gravity"]),
        time_s=f["timestamp"].astype(np.float64), stage=np.full(len(act), ""),
        ctrl=act[:, :n_act], base_target_pos=act[:, n_act:n_act + 3],
        base_target_quat=act[:, n_act + 3:], gravity=f["protocol.gravity"],
        object_force=f["protocol.object_force"], pin_pose=pin_pose,
        states={"hand_qpos": state[:, :nj], "hand_qvel": state[:, nj:2 * nj],
                "palm_pose": state[:, 2 * nj:2 * nj + 7], "object_pose": state[:, 2 * nj + 7:]},
        result=json.loads(row["dexaug/result"]), approach_m=row["dexaug/approach_m"])
