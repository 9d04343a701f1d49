"""An approach to the pregrasp: the open-to-pregrasp hand moving in along its palm normal.

Why: a policy trained on episodes should see the hand arrive, not appear at the pregrasp. The
validator starts a grasp with the palm already at its pose and the fingers at the pregrasp;
:func:`approach_path` backs the hand base off by ``distance_m`` along −frame_palm y (away from
the object: +y faces the pulps, DESIGN §3) and moves its mocap target straight back in over
``duration_s`` — fingers held at the pregrasp, gravity off as in the closing that follows —
then holds it ``settle_s`` while the weld brings the base to rest on the target. A path is
collision-free when no hand–object contact touches on the way (:func:`touching`); one that
is not (a wrap grasp's fingers cannot back out along the palm normal) is not an approach the
hand can follow, and the caller drops it. Units: metres, seconds.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.transforms import rotate
from sim.world.contacts import contacts_between
from sim.world.scene import Scene

__all__ = ["approach_path", "back_off", "touching"]


def approach_path(scene: Scene, distance_m: float, duration_s: float,
                  settle_s: float) -> np.ndarray:
    """(n, 3) per physics step the base's mocap target (metres, world), from ``distance_m``
    out along −palm y to where the placed grasp has it, then held there ``settle_s``; read
    from the scene as the validator placed the grasp."""
    dt = scene.model.opt.timestep
    target = scene.data.mocap_pos[scene.mocap_id].copy()
    _, palm_quat = scene.palm_world_pose()
    out = -rotate(palm_quat, np.array([0.0, 1.0, 0.0]))
    n_move, n_hold = max(round(duration_s / dt), 1), max(round(settle_s / dt), 0)
    share = np.minimum(np.arange(1, n_move + n_hold + 1) / n_move, 1.0)
    return target + distance_m * (1.0 - share)[:, None] * out


def back_off(scene: Scene, distance_m: float) -> None:
    """Move the placed hand (base and its mocap target) ``distance_m`` out along −palm y, at
    rest; joints and controls as they are."""
    pos, quat = scene.base_world_pose()
    _, palm_quat = scene.palm_world_pose()
    out = -rotate(palm_quat, np.array([0.0, 1.0, 0.0]))
    scene.set_hand_pose(pos + distance_m * out, quat)
    mujoco.mj_forward(scene.model, scene.data)


def touching(scene: Scene) -> bool:
    """Whether any hand–object contact of the last step touches (distance ≤ 0)."""
    con = contacts_between(scene.model, scene.data, scene.hand_geom_mask, scene.obj_geom_mask)
    return bool((con.dist <= 0.0).any())
