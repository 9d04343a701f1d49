"""A pregrasp that does not put the hand's links into each other.

The validator backs a grasp's contacts off straight along their normals to make its pregrasp,
and a finger moved back past its neighbour ends up inside it. The ``dgb`` protocol refuses a
pregrasp whose links are 1 cm into each other, so its ``dexaug`` pregrasp is kept no deeper
into itself than the grasp. Units: metres, radians.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from sim.world.contacts import contacts_between
from sim.world.scene import Scene

__all__ = ["clear_of_itself", "self_penetration_m"]

# a pregrasp may put the hand's links into each other this much deeper (metres) than the grasp
# has them, and its back-off is tried at these shares of the full one before none
_SELF_TOLERANCE_M = 0.001
_BACKOFF_SHARES = (1.0, 0.5, 0.25)


def self_penetration_m(scene: Scene, q: np.ndarray) -> float:
    """Deepest hand–hand penetration (metres, 0 when none) with the hand at joints ``q``."""
    scene.set_hand_joints(q)
    mujoco.mj_fwdPosition(scene.model, scene.data)
    return contacts_between(scene.model, scene.data, scene.hand_geom_mask,
                            scene.hand_geom_mask).max_penetration_m


def clear_of_itself(scene: Scene, q: np.ndarray, pre: np.ndarray,
                    settle: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """The pregrasp ``pre`` of the grasp at ``q``, settled by ``settle``, unless that puts the
    hand's links into each other deeper (by ``_SELF_TOLERANCE_M``) than the grasp has them:
    then the same without the settling, then with the back-off along the normals halved, down
    to none. Why: the back-off moves each contact straight back, and a finger moved back past
    its neighbour ends up inside it (on the authors' five-finger sugar box, 6 of 200 grasps
    whose own fingers overlap by 0–5 mm got pregrasps 10–14 mm into each other, which
    the benchmark's 1 cm penetration check refuses). Leaves ``scene`` at ``q``."""
    allowed_m = self_penetration_m(scene, q) + _SELF_TOLERANCE_M
    out = q
    for share in _BACKOFF_SHARES:
        back = q + share * (pre - q)
        candidates = (settle(back), back)
        fits = [c for c in candidates if self_penetration_m(scene, c) <= allowed_m]
        if fits:
            out = fits[0]
            break
    scene.set_hand_joints(q)
    mujoco.mj_fwdPosition(scene.model, scene.data)
    return out
