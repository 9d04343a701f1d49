"""A rollout as LeRobot frames: the features, their names, and one episode's columns.

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

A rollout rendered with a camera (``rollout(..., camera=(h, w))``) adds
``observation.images.<camera>``: the frame showing state row t, for every frame t; its
images must cover every state row (``camera_every=1``): a LeRobot image feature has a value
on every frame, and an image repeated or left out would be one the simulation never showed.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from augment.export.lerobot_episode import IMAGE_PREFIX, LeRobotEpisode, image_feature
from sim.episodes.episode import Episode

__all__ = ["CAMERA_FEATURE", "POSE_NAMES", "episode_columns", "features_of", "fps_of",
           "from_rollout", "task_text"]

#: the feature a rollout's rendered frames go to (its camera: the scene's overview camera)
CAMERA_FEATURE = IMAGE_PREFIX + "overview"
#: the seven numbers of a pose: position (metres, world) and orientation (wxyz)
POSE_NAMES = ("x", "y", "z", "qw", "qx", "qy", "qz")


def fps_of(timestep_s: float) -> int:
    """Frames per second of an episode recorded every ``timestep_s`` (LeRobot's ``fps`` is an
    integer: a timestep whose inverse is not one is refused rather than rounded silently)."""
    fps = round(1.0 / timestep_s)
    if fps < 1 or abs(fps * timestep_s - 1.0) > 1e-9:
        raise ValueError(f"a control step of {timestep_s} s is no whole number of frames a second")
    return fps


def task_text(object_name: str, hand: str) -> str:
    """The task in words, as LeRobot stores it per episode (object names as dexaug has them,
    ``004_sugar_box`` → ``sugar box``); rollouts and sessions of one object and hand share it."""
    obj = object_name.split("_", 1)[-1] if object_name[:3].isdigit() else object_name
    return f"grasp and lift the {obj.replace('_', ' ')} with the {hand.replace('_', ' ')}"


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
    """LeRobot's ``features`` of info.json for rollouts laid out as ``episode`` is: dtype,
    shape and column names per feature (``fps`` is added by LeRobot's own writer per
    feature, not needed by its reader; the writer adds its bookkeeping features)."""
    out: dict[str, dict[str, Any]] = {
        k: {"dtype": "float64", "shape": [len(v)], "names": v}
        for k, v in _names(episode).items()}
    out["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
    out["next.success"] = {"dtype": "bool", "shape": [1], "names": None}
    if len(episode.frames):
        out[CAMERA_FEATURE] = image_feature(*episode.frames.shape[1:3])
    return out


def _images(episode: Episode) -> np.ndarray:
    """The rendered frame of each of the episode's frames (module docstring)."""
    n = len(episode)
    rows = np.asarray(episode.frame_rows)
    if len(rows) < n or not np.array_equal(rows[:n], np.arange(n)):
        raise ValueError(f"the rollout of grasp {episode.grasp_index} has images of "
                         f"{len(rows)} of its {n + 1} state rows: a LeRobot camera needs every "
                         "frame's (rollout(..., camera_every=1))")
    return episode.frames[:n]


def from_rollout(episode: Episode) -> LeRobotEpisode:
    """A successful rollout as the LeRobot writer's episode: its frames (module docstring),
    its task, its rate, and its ``dexaug/...`` columns (object, hand, protocol, grasp row,
    approach, the validator's summary, the initial MuJoCo state the replay starts from)."""
    columns = episode_columns(episode)
    if len(episode.frames):
        columns[CAMERA_FEATURE] = _images(episode)
    meta = {"dexaug/object": episode.object, "dexaug/hand": episode.hand,
            "dexaug/protocol": episode.protocol, "dexaug/grasp_index": episode.grasp_index,
            "dexaug/approach_m": episode.approach_m,
            "dexaug/result": json.dumps(episode.result, default=_plain),
            "dexaug/initial_state": episode.initial_state.tolist(),
            "dexaug/initial_gravity": episode.initial_gravity.tolist()}
    return LeRobotEpisode(columns, features_of(episode), task_text(episode.object, episode.hand),
                          fps_of(episode.timestep_s), episode.hand, meta)


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


def episode_columns(episode: Episode) -> dict[str, np.ndarray]:
    """The frames of ``episode`` (module docstring) as one array per feature, rows = frames
    (without images and LeRobot's bookkeeping columns, which the writer adds)."""
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
    }
