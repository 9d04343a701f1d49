"""Close a hand on an object: how reference grasps are built by hand, and power grasps made.

A person building a grasp places the palm and closes the fingers until they stop on the object;
this does the same in simulation (gravity off, the object pinned at its pose each step) and
returns the grasp as the hand actually ended up: joint vector and palm pose in the object frame.
The object can also be let go at some point (``release_after_s``; still without gravity), as it
is when a real hand closes around it and when the validator closes a grasp: the fingers then
push it until it rests against the palm and the other links, and the grasp is read back
relative to where it ended.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from sim.grasp import Grasp
from sim.transforms import pose_inv, pose_mul
from sim.world.scene import OBJECT_HOME, Scene


def close_on_object(scene: Scene, palm_pos: np.ndarray, palm_quat: np.ndarray,
                    q_open: np.ndarray, q_closed: np.ndarray, *, close_time_s: float = 1.0,
                    hold_time_s: float = 0.6, release_after_s: float = math.inf) -> Grasp:
    """Place frame_palm at (palm_pos, palm_quat) in the object frame with joints ``q_open``,
    ramp the controls to ``q_closed`` over ``close_time_s``, hold, relax the actuators to where
    the fingers stopped, and read the grasp back. The object is held still for the first
    ``release_after_s`` seconds and free afterwards (0: free throughout; inf: held throughout);
    the palm pose is read in the frame of the object as it ended."""
    m, d, hand = scene.model, scene.data, scene.hand
    mujoco.mj_resetData(m, d)
    home_quat = np.array([1.0, 0.0, 0.0, 0.0])
    scene.set_object_pose(OBJECT_HOME, home_quat)
    world_pos, world_quat = pose_mul(OBJECT_HOME, home_quat, palm_pos, palm_quat)
    scene.set_hand_pose(*hand.base_pose_for_palm(world_pos, world_quat, q_open))
    scene.set_hand_joints(q_open)
    gravity = m.opt.gravity.copy()
    m.opt.gravity[:] = 0.0
    ramp = max(int(close_time_s / m.opt.timestep), 1)
    pinned_steps = (round(release_after_s / m.opt.timestep) if math.isfinite(release_after_s)
                    else math.inf)
    step = 0

    def advance() -> None:
        nonlocal step
        mujoco.mj_step(m, d)
        step += 1
        if step <= pinned_steps:
            scene.set_object_pose(OBJECT_HOME, home_quat)

    for k in range(ramp + int(hold_time_s / m.opt.timestep)):
        alpha = min((k + 1) / ramp, 1.0)
        scene.set_hand_ctrl((1 - alpha) * q_open + alpha * q_closed)
        advance()
    # relax: command where the fingers stopped, so the grasp is stored touching, not squeezing
    scene.set_hand_ctrl(d.qpos[scene.hand_qadr].copy())
    for _ in range(max(int(0.2 / m.opt.timestep), 1)):
        advance()
    mujoco.mj_forward(m, d)
    m.opt.gravity[:] = gravity
    inv_p, inv_q = pose_inv(*scene.object_pose())
    palm_obj_pos, palm_obj_quat = pose_mul(inv_p, inv_q, *scene.palm_world_pose())
    return Grasp.from_arrays(palm_obj_pos, palm_obj_quat, d.qpos[scene.hand_qadr].copy())
