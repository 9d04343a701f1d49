"""Hand-only grasps made for an object as it lies on the table, one set per resting pose.

Why: the paper's hand–arm experiment (§5.3) carries one set of hand-only grasps to every
placement and drops those that put the hand in the table. Grasps made for the object upright
then rarely fit an object lying on its side (a can rests on its side in 83 % of drops), and
those that do were validated with gravity along the object's −z, not along the way it really
hangs from a hand that lifts it off the table. Here each resting pose
(:mod:`sim.world.resting`) gets its own grasps: the same workspace (the demonstration's, or
the hand's manual one) and FSG in table mode with the plane that pose rests on (object frame:
normal −``down``, through the object's lowest point, raised by the margin the arm's IK keeps
the hand off the table), then lift-drop with gravity along that pose's ``down``; the passing
ones go to the arm.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from augment.autows.build import build_workspace
from augment.autows.seed import DemoSeed
from augment.fsg.table import TablePlane
from augment.object_cloud import object_cloud
from dexaug.pipeline.run import demo_fingers, generate_grasps
from sim.arm.ik import IKSettings
from sim.demo import Demo
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.world.objects import ObjectAsset
from sim.world.resting import RestPose

__all__ = ["RestGrasps", "rest_table_plane"]

log = logging.getLogger(__name__)


def rest_table_plane(points_obj: np.ndarray, pose: RestPose, raise_m: float = 0.0) -> TablePlane:
    """The table under the object resting in ``pose``, in the object frame: normal −``down``,
    through the lowest of ``points_obj`` (N,3, m) along it, raised by ``raise_m``."""
    up = -np.asarray(pose.down, float)
    up /= np.linalg.norm(up)
    return TablePlane(up, float((np.asarray(points_obj, float) @ up).min()) + raise_m)


@dataclass
class RestGrasps:
    """A :data:`sim.arm.evaluate.GraspSource` that makes ``n`` grasps per resting pose with
    ``demo``'s workspace (None: the hand's manual one) and keeps those that pass lift-drop
    hanging as that pose hangs. ``made`` records, per resting pose index, how many FSG found
    and how many passed; a pose asked for again (another arm, another run) gets the same set.
    ``progress(stage, done, total)`` follows FSG and the validation of each pose."""

    hand: Hand
    obj: ObjectAsset
    demo: Demo | None
    n: int
    seed: int = 0
    workers: int = 1
    time_budget_s: float = 120.0
    progress: Callable[[str, int, int], None] | None = None
    made: dict[int, dict[str, int]] = field(default_factory=dict)
    _made_grasps: dict[int, list[Grasp]] = field(default_factory=dict, repr=False)

    def __call__(self, rest_index: int, pose: RestPose) -> list[Grasp]:
        if rest_index not in self._made_grasps:
            self._made_grasps[rest_index] = self._make(rest_index, pose)
        return self._made_grasps[rest_index]

    def _make(self, rest_index: int, pose: RestPose) -> list[Grasp]:
        tick = self.progress or (lambda stage, done, total: None)
        cloud = object_cloud(self.obj)
        plane = rest_table_plane(np.asarray(cloud.points), pose,
                                 raise_m=IKSettings().hand_min_distance_m)
        ws = build_workspace(self.hand, demo=DemoSeed.from_demo(self.demo) if self.demo else None)
        res = generate_grasps(self.hand, cloud, ws, n=self.n, table=plane,
                              finger_names=demo_fingers(self.demo) if self.demo else None,
                              seed=self.seed + rest_index, workers=self.workers,
                              time_budget_s=self.time_budget_s,
                              progress=lambda k: tick(f"resting pose {rest_index}: FSG", k, self.n))
        grasps = [g.grasp for g in res.grasps]
        tick(f"resting pose {rest_index}: FSG", self.n, self.n)
        stage = f"resting pose {rest_index}: lift-drop hanging"
        verdicts = validate_many(self.hand.name, self.obj.name, grasps, "lift-drop",
                                 workers=self.workers, gravity_dir=pose.down,
                                 progress=lambda k: tick(stage, k, len(grasps)))
        kept = [g for g, v in zip(grasps, verdicts, strict=True) if v.passed]
        self.made[rest_index] = {"generated": len(grasps), "passed": len(kept)}
        log.info("%s resting pose %d (down %s): %d of %d grasps made for it hold hanging so",
                 self.obj.name, rest_index, np.round(pose.down, 3).tolist(), len(kept),
                 len(grasps))
        return kept
