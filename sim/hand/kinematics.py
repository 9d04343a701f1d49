"""Batched forward kinematics of a fixed-base MuJoCo tree, in NumPy.

AutoWS evaluates thousands of joint vectors at once; looping ``mj_kinematics`` per vector costs
a Python round trip each, so this module replays MuJoCo's own body-chain formula (body offset,
then each hinge about its anchor / each slide along its axis, relative to ``qpos0``) on whole
batches. It matches ``mj_kinematics`` to floating-point rounding (tested to 1e-9 m).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from sim.errors import ConfigError
from sim.transforms import axis_angle_to_quat, quat_mul, quat_normalize, rotate


@dataclass(frozen=True)
class _JointStep:
    qadr: int
    hinge: bool
    axis: np.ndarray
    anchor: np.ndarray
    qpos0: float


class TreeKinematics:
    """Body poses of a model whose joints are all hinges or slides (a hand on a fixed base)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        allowed = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        for j in range(model.njnt):
            if int(model.jnt_type[j]) not in allowed:
                raise ConfigError(f"joint {model.joint(j).name!r} is a free or ball joint; "
                                  "hand models must have a fixed base and hinge/slide joints")
        self.nbody = model.nbody
        self.nq = model.nq
        self.parent = model.body_parentid.copy()
        self.body_pos = model.body_pos.copy()
        self.body_quat = model.body_quat.copy()
        self.steps: list[list[_JointStep]] = []
        for b in range(model.nbody):
            adr, num = model.body_jntadr[b], model.body_jntnum[b]
            self.steps.append([
                _JointStep(qadr=int(model.jnt_qposadr[j]),
                           hinge=int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE),
                           axis=model.jnt_axis[j].copy(), anchor=model.jnt_pos[j].copy(),
                           qpos0=float(model.qpos0[model.jnt_qposadr[j]]))
                for j in range(adr, adr + num)])

    def body_poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (B, nbody, 3) metres and quaternions wxyz (B, nbody, 4) of every body in
        the model's world frame, for joint vectors q (B, nq) radians/metres."""
        batch = q.shape[0]
        pos = np.zeros((batch, self.nbody, 3))
        quat = np.zeros((batch, self.nbody, 4))
        quat[:, 0, 0] = 1.0
        for b in range(1, self.nbody):
            pos[:, b], quat[:, b] = self._child_pose(b, pos[:, self.parent[b]],
                                                     quat[:, self.parent[b]], q)
        return pos, quat

    def body_pose(self, q: np.ndarray, body: int) -> tuple[np.ndarray, np.ndarray]:
        """One body's position (B, 3) metres and quaternion wxyz (B, 4), the same numbers as
        :meth:`body_poses` gives for it, from its chain of ancestors alone (placing a hand at
        a palm pose needs the palm, a few bodies from the root, not all of them)."""
        chain = []
        while body > 0:
            chain.append(body)
            body = int(self.parent[body])
        pos = np.zeros((q.shape[0], 3))
        quat = np.zeros((q.shape[0], 4))
        quat[:, 0] = 1.0
        for b in reversed(chain):
            pos, quat = self._child_pose(b, pos, quat, q)
        return pos, quat

    def _child_pose(self, b: int, parent_pos: np.ndarray, parent_quat: np.ndarray,
                    q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body ``b``'s world pose from its parent's: body offset, then each of its joints."""
        xpos = parent_pos + rotate(parent_quat, self.body_pos[b])
        xquat = quat_mul(parent_quat, self.body_quat[b])
        for step in self.steps[b]:
            angle = q[:, step.qadr] - step.qpos0
            if step.hinge:
                xanchor = xpos + rotate(xquat, step.anchor)
                xquat = quat_mul(xquat, axis_angle_to_quat(step.axis, angle))
                xpos = xanchor - rotate(xquat, step.anchor)
            else:
                xpos = xpos + rotate(xquat, step.axis) * angle[:, None]
        return xpos, quat_normalize(xquat)
