"""An episode as LeRobot frames: the features, their names, and one episode's columns.

Why a module of its own: what a frame *is* (which arrays of :class:`sim.episodes.episode.Episode`
go into ``observation.state`` and ``action``, in which order, under which names) is the
contract a policy trained on the export depends on; the file layout around it
(:mod:`augment.export.lerobot`) is LeRobot's. Pure NumPy, no pyarrow.

Frame t of an episode of T steps is the state *before* step t and the action of step t (the
episode's state row t and action row t, :mod:`sim.episodes.episode`): T frames; the last
state row (after the final step) has no action and is not a frame. Floats stay float64, so
frames and actions are the episode's arrays bit for bit (LeRobot's reader gives float64
tensors; cast to float32 for a policy as usual). ``timestamp`` is float32 as LeRobot fixes
it. The protocol's conditions (gravity, the force on the object, the object pinned while
closing) ride along as ``protocol.*`` features, so the dataset alone replays in MuJoCo
(:mod:`augment.export.lerobot_read`). Units: metres, radians, rad/s, newtons, seconds;
quaternions wxyz.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sim.episodes.episode import Episode

__all__ = ["INDEX_FEATURES", "POSE_NAMES", "episode_columns", "features_of", "fps_of",
           "same_layout", "task_text"]

#: LeRobot's own per-frame bookkeeping features (dtype, as its reader expects them)
INDEX_FEATURES = {"timestamp": "float32", "frame_index": "int64", "episode_index": "int64",
                  "index": "int64", "task_index": "int64"}
#: the seven numbers of a pose: position (metres, world) and orientation (wxyz)
POSE_NAMES = ("x", "y", "z", "qw", "qx", "qy", "qz")


def fps_of(timestep_s: float) -> int:
    """Frames per second of an episode recorded every ``timestep_s`` (LeRobot's ``fps`` is an
    integer: a timestep whose inverse is not one is refused rather than rounded silently)."""
    fps = round(1.0 / timestep_s)
    if fps < 1 or abs(fps * timestep_s - 1.0) > 1e-9:
        raise ValueError(f"a control step of {timestep_s} s is no whole number of frames a second")
    return fps


def task_text(episode: Episode) -> str:
    """The task in words, as LeRobot stores it per episode (object names as dexaug has them,
    ``004_sugar_box`` → ``sugar box``)."""
    obj = episode.object.split("_", 1)[-1] if episode.object[:3].isdigit() else episode.object
    return f"grasp and lift the {obj.replace('_', ' ')} with the {episode.hand.replace('_', ' ')}"


def _names(episode: Episode) -> dict[str, list[str]]:
    """Per vector feature the names of its columns."""
    j = episode.joint_names
    return {
        "observation.state": [f"{n}.pos" for n in j] + [f"{n}.vel" for n in j]
        + [f"palm.{p}" for p in POSE_NAMES] + [f"object.{p}" for p in POSE_NAMES],
        "observation.fingertip_force": list(episode.finger_names),
        "action": list(episode.actuator_names) + [f"base_target.{p}" for p in POSE_NAMES],
        "protocol.gravity": ["x", "y", "z"],
        "protocol.object_force": ["x", "y", "z"],
        "protocol.pin_pose": ["pinned", *POSE_NAMES],
    }


def features_of(episode: Episode) -> dict[str, dict[str, Any]]:
    """LeRobot's ``features`` of info.json for episodes laid out as ``episode`` is: dtype,
    shape and column names per feature (``fps`` is added by LeRobot's own writer per
    feature, not needed by its reader)."""
    out: dict[str, dict[str, Any]] = {
        k: {"dtype": "float64", "shape": [len(v)], "names": v}
        for k, v in _names(episode).items()}
    out["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
    out["next.success"] = {"dtype": "bool", "shape": [1], "names": None}
    out.update({k: {"dtype": t, "shape": [1], "names": None} for k, t in INDEX_FEATURES.items()})
    return out


def same_layout(a: Episode, b: Episode) -> bool:
    """Whether two episodes give frames of the same features (one LeRobot dataset holds one
    layout: the same hand's joints, actuators and fingers)."""
    return _names(a) == _names(b)


def episode_columns(episode: Episode, episode_index: int, first_index: int,
                    task_index: int) -> dict[str, np.ndarray]:
    """The frames of ``episode`` (module docstring) as one array per feature, rows = frames;
    ``first_index``: the dataset-wide ``index`` of its first frame."""
    s, n = episode.states, len(episode)
    pinned = np.isfinite(episode.pin_pose).all(axis=1)
    pin = np.where(pinned[:, None], episode.pin_pose, 0.0)
    last = np.arange(n) == n - 1
    return {
        "observation.state": np.concatenate(
            [s["hand_qpos"][:n], s["hand_qvel"][:n], s["palm_pose"][:n], s["object_pose"][:n]],
            axis=1),
        "observation.fingertip_force": np.asarray(s["fingertip_force"][:n], dtype=np.float64),
        "action": np.concatenate(
            [episode.ctrl, episode.base_target_pos, episode.base_target_quat], axis=1),
        "protocol.gravity": episode.gravity,
        "protocol.object_force": episode.object_force,
        "protocol.pin_pose": np.concatenate([pinned[:, None].astype(np.float64), pin], axis=1),
        "next.done": last,
        "next.success": last & bool(episode.success),
        "timestamp": (episode.time_s - episode.time_s[0]).astype(np.float32),
        "frame_index": np.arange(n, dtype=np.int64),
        "episode_index": np.full(n, episode_index, dtype=np.int64),
        "index": np.arange(first_index, first_index + n, dtype=np.int64),
        "task_index": np.full(n, task_index, dtype=np.int64),
    }
