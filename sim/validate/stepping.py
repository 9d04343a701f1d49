"""Stepping a validation scene and measuring how far the object moved in the palm.

The closing sequence and both protocols share these: :func:`run_for` steps a stretch of
simulation (ramping the hand's controls, optionally pinning the object), and :func:`drift`
compares the object's pose in the palm frame with a reference taken after closing — the
quantity every protocol limit is stated in. Units: seconds, metres, radians.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.transforms import pose_inv, pose_mul, quat_angle
from sim.world.scene import Scene

__all__ = ["drift", "relative_object_pose", "run_for"]


def relative_object_pose(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """The object's pose (position metres, quaternion wxyz) in the palm frame."""
    palm_pos, palm_quat = scene.palm_world_pose()
    obj_pos, obj_quat = scene.object_pose()
    inv_p, inv_q = pose_inv(palm_pos, palm_quat)
    return pose_mul(inv_p, inv_q, obj_pos, obj_quat)


def drift(scene: Scene, ref_pos: np.ndarray, ref_quat: np.ndarray) -> tuple[float, float]:
    """(displacement metres, rotation radians) of the object in the palm frame from the
    reference pose (``ref_pos``, ``ref_quat`` wxyz, palm frame)."""
    pos, quat = relative_object_pose(scene)
    return float(np.linalg.norm(pos - ref_pos)), float(quat_angle(quat, ref_quat))


def run_for(scene: Scene, seconds: float, ctrl_from: np.ndarray | None = None,
            ctrl_to: np.ndarray | None = None, *,
            pin: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Step ``seconds`` of simulation, ramping hand controls linearly when given; with
    ``pin`` (position, wxyz) the object is held at that pose after every step."""
    m, d = scene.model, scene.data
    steps = max(round(seconds / m.opt.timestep), 0)
    if ctrl_from is None and pin is None:
        if steps:
            mujoco.mj_step(m, d, nstep=steps)
        return
    for k in range(steps):
        if ctrl_from is not None and ctrl_to is not None:
            alpha = (k + 1) / steps
            d.ctrl[scene.hand_act] = (1 - alpha) * ctrl_from + alpha * ctrl_to
        mujoco.mj_step(m, d)
        if pin is not None:
            scene.set_object_pose(*pin)
