"""A grasp dataset's grasps rolled out as episodes, one at a time, for the LeRobot export.

Why a generator: :func:`augment.export.lerobot.write_lerobot` turns each episode into frames
as it comes, so an export of thousands of grasps holds one episode's MuJoCo record at a time,
not all of them. Each object's grasps are rolled out by a validator of that object and the
dataset's hand (:func:`sim.episodes.rollout.rollout`: the validator's own lift-drop run), so
an episode's success is the validator's verdict on that grasp.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

from augment.dataset import ObjectTable
from augment.grasp_table import grasps_of
from sim.episodes.episode import Episode
from sim.episodes.rollout import rollout
from sim.hand.model import Hand
from sim.validate.validator import Validator
from sim.world.objects import load_object

__all__ = ["count_grasps", "rollouts"]


def count_grasps(tables: Mapping[str, ObjectTable]) -> int:
    """How many rollouts :func:`rollouts` gives for ``tables`` (for a progress bar)."""
    return sum(len(t) for t in tables.values())


def rollouts(tables: Mapping[str, ObjectTable], hand: Hand, *, approach_m: float = 0.0,
             camera: tuple[int, int] | None = None) -> Iterator[Episode]:
    """Every grasp of every table rolled out, table by table, in row order (``grasp_index``:
    the row in its table); ``approach_m``: as :func:`sim.episodes.rollout.rollout`;
    ``camera``: (height, width) of an image of every state row (``camera_every=1``: a
    LeRobot camera has an image on every frame, :mod:`augment.export.lerobot_frames`)."""
    for name, table in tables.items():
        validator = Validator(hand, load_object(name))
        for i, grasp in enumerate(grasps_of(table)):
            yield rollout(validator, grasp, index=i, approach_m=approach_m, camera=camera)
