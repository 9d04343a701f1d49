"""One episode as the LeRobot writer takes it, whatever made it: a rollout, a teleop session.

Why a type of its own: :mod:`augment.export.lerobot` writes LeRobot's layout (files, meta,
stats) and nothing about where frames come from; each source (:mod:`.lerobot_frames` for
rollouts, :mod:`.lerobot_sessions` for recorded sessions) says what its frames are by filling
a :class:`LeRobotEpisode`. The writer adds LeRobot's bookkeeping columns (``frame_index``,
``episode_index``, ``index``, ``task_index``); the source gives everything else, ``timestamp``
included (its own clock, seconds from the episode's first frame, float32 as LeRobot fixes it).

Camera images are features of ``dtype`` ``"image"`` (LeRobot's name for frames stored in the
parquet itself, not as videos): the column holds (frames, height, width, 3) RGB uint8 here and
is written as PNG (:mod:`.lerobot_images`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["IMAGE_PREFIX", "LeRobotEpisode", "image_feature", "same_layout"]

#: LeRobot's prefix of camera features (``observation.images.<camera>``)
IMAGE_PREFIX = "observation.images."


@dataclass
class LeRobotEpisode:
    """One episode's frames: ``columns`` (feature → array, rows = frames; ``timestamp`` in
    seconds from the first frame), their ``features`` (info.json's dtype, shape, names),
    the ``task`` text, the frame rate ``fps`` (frames a second, a whole number: LeRobot's
    info.json and its timestamp check take no other; sessions are resampled to one,
    :mod:`.lerobot_sessions`), the ``robot_type``, and ``meta``: the source's own
    ``dexaug/...`` columns of its meta/episodes row."""

    columns: dict[str, np.ndarray]
    features: dict[str, dict[str, Any]]
    task: str
    fps: int
    robot_type: str
    meta: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.columns["timestamp"])


def image_feature(height: int, width: int) -> dict[str, Any]:
    """The info.json entry of an RGB camera feature of ``height`` × ``width`` pixels, as
    LeRobot's own writer makes one for images kept in the parquet."""
    return {"dtype": "image", "shape": [height, width, 3], "names": ["height", "width", "channels"]}


def same_layout(a: LeRobotEpisode, b: LeRobotEpisode) -> bool:
    """Whether two episodes can share a dataset: the same features (names, shapes, dtypes)
    at the same frame rate (one LeRobot dataset has one ``features`` and one ``fps``)."""
    return a.features == b.features and a.fps == b.fps
