"""Can the hand's actuators hold the load at a grasp's contacts? The least worst actuator effort.

:func:`sim.metrics.holding.min_actuator_efforts` is a linear programme over the contact forces;
this builds its actuator model from the validator's scene at the placed grasp: one contact per
hand body near the object (its closest point and normal, as the squeeze targets use), the
contact Jacobians over the finger joints, and the actuators' moment arms M (``τ = Mᵀ u``), so
that the actuator forces that press contact i with force f are ``u = (Mᵀ)⁺ J_iᵀ f``
(pseudo-inverse: one tendon actuator drives two coupled joints), bounded by each actuator's
``forcerange``. The wrist and arm carry the rest of the load through the mount, so only finger
joints count. The answer is a capability bound — servos do not share forces optimally — so a
grasp above 1 cannot hold the load with these actuators however it squeezes, and one below 1
may still slip.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.metrics.holding import HoldLoads, min_actuator_efforts
from sim.world.contacts import Contacts
from sim.world.scene import Scene

__all__ = ["actuator_effort", "closest_per_body", "finger_moment_arms", "servo_force_limits"]


def closest_per_body(near: Contacts) -> np.ndarray:
    """Indices into ``near`` of each hand body's closest contact (by signed distance), in
    order of body id."""
    return np.array([np.flatnonzero(near.body_a == b)[np.argmin(near.dist[near.body_a == b])]
                     for b in np.unique(near.body_a)], dtype=int)


def finger_moment_arms(scene: Scene, finger_mask: np.ndarray) -> np.ndarray:
    """The hand actuators' moment arms M (∂ actuator length / ∂ q, gear included; n_act × the
    hand's dofs in ``scene``) over the finger joints, zero outside ``finger_mask`` (per kept
    hand joint). Needs ``mj_forward`` (or ``mj_fwdPosition``) to have run."""
    m, d = scene.model, scene.data
    moment = np.zeros((m.nu, m.nv))
    mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr,
                            d.moment_colind)
    return moment[np.ix_(scene.hand_act, scene.hand_dadr)] * finger_mask


def servo_force_limits(scene: Scene) -> np.ndarray:
    """Per hand actuator of ``scene``, its force limit (the upper ``forcerange``; N or N·m),
    ``inf`` where the actuator is not force-limited."""
    m, acts = scene.model, scene.hand_act
    return np.where(m.actuator_forcelimited[acts].astype(bool), m.actuator_forcerange[acts, 1],
                    np.inf)


def actuator_effort(scene: Scene, near: Contacts, finger_mask: np.ndarray, hold: HoldLoads) -> float:
    """Over ``hold``'s loads, the largest least worst actuator effort (fraction of the force
    limit) of the grasp placed in ``scene`` with hand–object contacts and near misses ``near``
    (``finger_mask`` over the hand's joints, :func:`sim.validate.targets.finger_joint_mask`);
    ``inf`` when no body is near or some load cannot be held by friction. Loads are taken in the
    object frame, which the validator's scene keeps aligned with the world."""
    m, d = scene.model, scene.data
    # the scene may lack some of the hand's joints (the benchmark's floating palm has no wrist)
    finger_mask = np.asarray(finger_mask, dtype=bool)[scene.hand_joint_kept]
    idx = closest_per_body(near)
    if not len(idx):
        return float("inf")
    acts = scene.hand_act
    arm = finger_moment_arms(scene, finger_mask)
    to_effort = np.linalg.pinv(arm.T, rcond=1e-6)
    points = near.points_a[idx]
    jacp = np.zeros((3, m.nv))
    per = np.zeros((len(acts), len(idx), 3))
    for c, i in enumerate(idx):
        mujoco.mj_jac(m, d, jacp, None, points[c], int(near.body_a[i]))
        per[:, c, :] = to_effort @ (jacp[:, scene.hand_dadr] * finger_mask).T
    limit = servo_force_limits(scene)
    com = d.xipos[scene.obj_body]
    efforts = min_actuator_efforts(points, near.normal[idx], com, hold.loads, hold.mu, per, limit,
                                   hold.mu_torsion_m)
    return float(np.max(efforts, initial=0.0))
