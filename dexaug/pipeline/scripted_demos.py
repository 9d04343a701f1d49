"""Which grasps a scripted demonstration should perform (``make demo``, demo sessions).

Why here (the application layer): finding them takes FSG and the validator, and the scripted
demonstrator that performs them (:mod:`teleop.synthetic.scripted`) is teleop; neither package
imports the other.
"""

from __future__ import annotations

import logging

from augment.autows.build import build_workspace
from augment.object_cloud import object_cloud
from dexaug.pipeline.run import generate_grasps
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.batch import validate_many
from sim.world.objects import load_object

__all__ = ["demonstrable_grasps"]

log = logging.getLogger(__name__)


def demonstrable_grasps(hand: Hand, object_name: str, n: int, *, seed: int = 0,
                        workers: int = 2, time_budget_s: float = 60.0) -> list[Grasp]:
    """Grasps worth demonstrating on ``object_name`` resting on the table: FSG's proposals on
    the hand's manual workspace (table mode, link penetration check; ``n`` asked for) that pass
    the MuJoCo lift-drop test, best FSG ε first. What the scripted demonstrator performs."""
    res = generate_grasps(hand, object_cloud(load_object(object_name)), build_workspace(hand), n=n,
                   table=True, link_penetration=True, seed=seed, workers=workers,
                   time_budget_s=time_budget_s)
    results = validate_many(hand.name, object_name, [g.grasp for g in res.grasps],
                            workers=workers)
    passing = [g.grasp for g, r in zip(res.grasps, results, strict=True) if r.passed]
    log.info("%s: %d FSG proposals, %d pass lift-drop", object_name, len(res.grasps),
             len(passing))
    return passing
