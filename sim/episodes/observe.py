"""What a trajectory step and the environment observe of a grasp scene.

One reading for both (:mod:`sim.episodes.rollout` records it, :mod:`sim.envs` returns it as
observations), so a policy trained in the environment sees exactly what an exported episode
holds. Units: metres, radians, newtons; quaternions wxyz (DESIGN §3).
"""

from __future__ import annotations

import numpy as np

from sim.world.contacts import contacts_between
from sim.world.scene import HAND_PREFIX, Scene

__all__ = ["STATE_KEYS", "fingertip_bodies", "fingertip_contacts", "read_state"]

#: the per-step state arrays :func:`read_state` gives (and an episode stores, one row a step)
STATE_KEYS = ("hand_qpos", "hand_qvel", "palm_pose", "object_pose", "fingertip_contact",
              "fingertip_force", "n_contacts")


def fingertip_bodies(scene: Scene) -> np.ndarray:
    """Scene body ids of the hand config's fingertip bodies, in finger order."""
    m = scene.model
    return np.array([m.body(HAND_PREFIX + f.tip_body).id for f in scene.hand.config.fingers],
                    dtype=int)


def fingertip_contacts(scene: Scene, tips: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Per fingertip body of ``tips``: whether it touches the object (a contact at distance
    ≤ 0), the total normal force of its contacts with it (newtons), and the number of touching
    hand–object contacts of the whole hand. Reads the contacts of the last ``mj_step`` or
    ``mj_forward``."""
    con = contacts_between(scene.model, scene.data, scene.hand_geom_mask, scene.obj_geom_mask,
                           with_force=True)
    touching = con.dist <= 0.0
    flags = np.zeros(len(tips), dtype=bool)
    forces = np.zeros(len(tips))
    for i, body in enumerate(tips):
        sel = con.body_a == body
        flags[i] = bool(touching[sel].any())
        forces[i] = float(con.force_n[sel].sum())
    return flags, forces, int(touching.sum())


def read_state(scene: Scene, tips: np.ndarray) -> dict[str, np.ndarray]:
    """The scene's state as :data:`STATE_KEYS`: the hand's joint positions (radians) and
    velocities (the scene's hand joints, ``Hand.joint_names`` order), frame_palm's and the
    object's world poses (position + wxyz, 7), and :func:`fingertip_contacts`."""
    d = scene.data
    palm_pos, palm_quat = scene.palm_world_pose()
    obj_pos, obj_quat = scene.object_pose()
    flags, forces, n = fingertip_contacts(scene, tips)
    return {"hand_qpos": d.qpos[scene.hand_qadr].copy(), "hand_qvel": d.qvel[scene.hand_dadr].copy(),
            "palm_pose": np.concatenate([palm_pos, palm_quat]),
            "object_pose": np.concatenate([obj_pos, obj_quat]),
            "fingertip_contact": flags, "fingertip_force": forces, "n_contacts": np.array(n)}
