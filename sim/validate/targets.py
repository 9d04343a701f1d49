"""Pregrasp and squeeze joint targets of a placed grasp, derived from its near contacts.

From a grasp (palm pose in the object frame + joint vector) the validator derives a pregrasp and
a squeeze target itself: it finds the hand bodies near the object, and moves their closest
points back along the contact normals (pregrasp) or onto the object surface (squeeze) with
damped least squares on the contact Jacobians, so it works for any hand without per-hand closing
rules.

The squeeze is sized by force, not by depth. A position servo presses only as hard as its target
lies beyond where the finger stops, so a fixed depth gives a force that depends on the hand's
gains (the Menagerie Shadow Hand's ≈ 1 N·m/rad servos give ≈ 1 N per fingertip for 8 mm, too
little to lift a sugar box with a fingertip grasp), and a fixed larger depth crushes light objects
out of a pinch. Each grasping contact i (one per hand body near the object) is given a desired
normal force ``f_i = max(grip_safety · m·g·(1 + d/ρ) / (μ · n_contacts), min_grip_force_n)``
(d: centre of mass to the contacts' centroid, ρ: the contacts' spread), so that the friction of
all contacts carries ``grip_safety`` times the object's weight and its moment about the grasp.
That rule of thumb credits every contact with a lever ρ against the weight's moment, which
contacts on a thin wall do not have: a bowl pinched at its rim (thumb inside, fingers outside,
6 cm from the centre of mass) can hold its moment only through a couple of contact forces at a
small offset (straight across a 4 mm wall, 6 cm from the centre of mass: 2.3 times the rule's
force; tests/test_least_grip_squeeze.py). So the total is raised, where needed, to
``grip_safety`` times the *least* total normal force with which these contacts (one per hand
body, the simulation's friction and torsional friction) can hold the weight at all
(:func:`sim.metrics.holding.min_grip_force_n`, :func:`least_grip_total_n`); contacts that cannot
hold it however they press keep the rule's force. The target is

    q_squeeze = q + J⁺ (gaps + squeeze_depth_m) + K_q⁺ Jᵀ f

where J holds the contact-normal rows of the finger Jacobians and ``K_q = Mᵀ diag(k) M`` is the
joint-space stiffness of the hand's servos, from the actuator moment matrix M and each
actuator's position stiffness k (``−biasprm[1]`` of an affine-bias actuator: the force per unit
of length error at a fixed control). ``K_q⁺`` is a damped pseudo-inverse because coupled tendon
joints (one actuator for two joints) make K_q singular. Actuator force limits saturate in the
simulation, as on a real hand. Both protocols close onto the same targets.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from sim.hand.model import Hand
from sim.metrics.holding import min_grip_force_n
from sim.validate.config import GRAVITY_MPS2, CommonParams
from sim.validate.contact_forces import balanced_normal_forces
from sim.validate.effort import closest_per_body
from sim.world.contacts import Contacts
from sim.world.scene import Scene

__all__ = ["GraspTargets", "finger_joint_mask", "grip_force_n", "joint_stiffness",
           "least_grip_total_n", "squeeze_total_n", "targets_from_contacts"]

# relative damping of the pseudo-inverses: the contact Jacobian's (m², as J Jᵀ) and the joint
# stiffness's (times its largest eigenvalue; only makes singular directions harmless)
_JAC_DAMPING_M2 = 1e-4
_STIFFNESS_DAMPING = 1e-3
# smallest lever arm (metres) credited to a grasp's friction torque: about a fingertip pad
_MIN_LEVER_M = 0.005


@dataclass(frozen=True)
class GraspTargets:
    """Joint targets derived from a grasp: where to start closing and where to squeeze to, how
    many hand bodies were near the object, and the normal force (newtons) the squeeze target
    asks of each of them."""

    pregrasp: np.ndarray
    squeeze: np.ndarray
    n_bodies_near: int
    grip_force_n: float = 0.0


def finger_joint_mask(hand: Hand) -> np.ndarray:
    """(nq,) bool over the hand's joints: True for a joint of some finger (the squeeze moves
    fingers only, never the wrist)."""
    finger_joints = {j for f in hand.config.fingers for j in f.joints}
    return np.array([n in finger_joints for n in hand.joint_names])


def grip_force_n(scene: Scene, points: np.ndarray, common: CommonParams) -> float:
    """Desired normal force (newtons) per grasping contact, for contacts at ``points`` (n, 3).

    Friction must carry the object's weight W and its moment about the grasp: with the
    centre of mass a distance d from the contacts' centroid and the contacts spread ρ (RMS)
    around it, friction forces hold a torque of about μ·Σf·ρ, so Σf ≥ W·(1 + d/ρ)/μ covers
    both (conservatively, as if they added). Scaled by ``grip_safety``, split over the n
    contacts, never less than ``min_grip_force_n``.
    """
    total_n = squeeze_total_n(points, scene.data.xipos[scene.obj_body], scene.obj_mass_kg, common)
    return max(total_n / len(points), common.min_grip_force_n)


def squeeze_total_n(points: np.ndarray, com_m: np.ndarray, mass_kg: float,
                    common: CommonParams) -> float:
    """The squeeze's total normal force (newtons) before the per-contact floor:
    ``grip_safety · m·g·(1 + d/ρ) / μ`` for contacts at ``points`` (n, 3) around a centre of
    mass at ``com_m`` (same frame, metres); :func:`grip_force_n` has the reasoning."""
    centroid = points.mean(axis=0)
    spread_m = max(float(np.sqrt(((points - centroid) ** 2).sum(axis=1).mean())), _MIN_LEVER_M)
    offset_m = float(np.linalg.norm(np.asarray(com_m, dtype=float) - centroid))
    return (common.grip_safety * mass_kg * GRAVITY_MPS2 * (1.0 + offset_m / spread_m)
            / common.contact.friction[0])


def least_grip_total_n(points: np.ndarray, normals_in: np.ndarray, com_m: np.ndarray,
                       mass_kg: float, common: CommonParams,
                       down: np.ndarray | None = None) -> float:
    """``grip_safety`` times the least total normal force (newtons) with which contacts at
    ``points`` (n, 3) pressing along ``normals_in`` (n, 3, into the object) hold the object's
    weight pulling along ``down`` (unit, same frame; None: −z) with the configured sliding and
    torsional friction; ``inf`` when they cannot hold it however hard they press.

    Why, beside :func:`squeeze_total_n`: that rule sizes the squeeze from the contacts' spread
    ρ, but only a spread across the weight's moment arm helps. Opposed contacts on a thin wall
    (a bowl's rim) are spread along the wall, and the moment of a centre of mass 6 cm away must
    come from a couple of contact forces a few millimetres apart; the linear programme of
    :func:`sim.metrics.holding.min_grip_force_n` knows that, the rule does not.
    """
    down = np.array([0.0, 0.0, -1.0]) if down is None else np.asarray(down, dtype=float)
    weight = mass_kg * GRAVITY_MPS2 * down
    load = np.concatenate([weight, np.zeros(3)])
    friction = common.contact.friction
    least = min_grip_force_n(points, normals_in, com_m, load, friction[0], friction[1])
    return common.grip_safety * least


def joint_stiffness(scene: Scene, finger_mask: np.ndarray) -> np.ndarray:
    """Joint-space stiffness (nq × nq over the hand's joints; N·m/rad for hinges) of the
    hand's finger servos at the current state: ``K_q = Mᵀ diag(k) M``.

    M is the actuator moment matrix (∂ actuator length / ∂ q, gear included) of the hand's
    actuators and k each actuator's position stiffness at a fixed control: ``−biasprm[1]``
    for a fixed-gain, affine-bias actuator (a position servo: kp), 0 for anything else (a
    motor holds no position). Rows and columns outside the finger joints (``finger_mask``,
    :func:`finger_joint_mask`) are zero, since the squeeze moves fingers only. Needs
    ``mj_forward`` (or ``mj_fwdPosition``) to have run.
    """
    m, d = scene.model, scene.data
    moment = np.zeros((m.nu, m.nv))
    mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr,
                            d.moment_colind)
    acts = scene.hand_act
    k = np.where(scene.position_servos(), np.maximum(-m.actuator_biasprm[acts, 1], 0.0), 0.0)
    arm = moment[np.ix_(acts, scene.hand_dadr)] * finger_mask
    return arm.T @ (k[:, None] * arm)


def _stiffness_pinv(stiffness: np.ndarray) -> np.ndarray:
    """Damped pseudo-inverse s / (s² + λ²) per eigenvalue s of a symmetric stiffness: ≈ 1/s
    where the servos are stiff, → 0 (not 1/λ) along directions no actuator resists, such as
    the difference of two tendon-coupled joints."""
    s, v = np.linalg.eigh(stiffness)
    lam = _STIFFNESS_DAMPING * max(float(s.max(initial=0.0)), 1e-12)
    return (v * (s / (s * s + lam * lam))) @ v.T


def targets_from_contacts(scene: Scene, hand: Hand, q: np.ndarray, near: Contacts,
                          common: CommonParams, finger_mask: np.ndarray,
                          down: np.ndarray | None = None) -> GraspTargets:
    """Pregrasp and squeeze joint vectors of the grasp placed in ``scene`` at joints ``q``,
    from its hand–object contacts and near misses ``near`` (distances in metres).

    Per hand body the closest point is moved along its normal (by distance − backoff for the
    pregrasp, distance + squeeze depth for the squeeze). The squeeze then adds the servo
    deflection ``K_q⁺ Jᵀ f`` that presses each of those points into the object with the grip
    force f (module docstring): the larger of :func:`grip_force_n`'s rule and the least grip
    that holds the weight pulling along ``down`` (world, unit; None: −z) at these contacts
    (:func:`least_grip_total_n`), split over them. No body near the object gives
    ``n_bodies_near = 0`` and ``q`` for both targets.
    """
    m, d = scene.model, scene.data
    rows, gaps, closest, normals = [], [], [], []
    jacp = np.zeros((3, m.nv))
    points = near.points_a
    for i in closest_per_body(near):
        mujoco.mj_jac(m, d, jacp, None, points[i], int(near.body_a[i]))
        rows.append(near.normal[i] @ jacp[:, scene.hand_dadr])
        gaps.append(near.dist[i])
        closest.append(points[i])
        normals.append(near.normal[i])
    if not rows:
        return GraspTargets(q, q, 0)
    jac = np.array(rows) * finger_mask
    gaps = np.array(gaps)
    solve = np.linalg.solve(jac @ jac.T + _JAC_DAMPING_M2 * np.eye(len(rows)),
                            np.eye(len(rows)))
    pinv = jac.T @ solve
    pre = hand.clip(q + pinv @ (gaps - common.pregrasp_backoff_m))
    force_n = grip_force_n(scene, np.array(closest), common)
    least_n = least_grip_total_n(np.array(closest), np.array(normals), d.xipos[scene.obj_body],
                                 scene.obj_mass_kg, common, down)
    if np.isfinite(least_n):
        force_n = max(force_n, least_n / len(rows))
    if common.squeeze_forces == "balanced":
        forces = balanced_normal_forces(np.array(closest), np.array(normals),
                                        d.xipos[scene.obj_body], force_n * len(rows))
    else:
        forces = np.full(len(rows), force_n)
    # joint torques that press every contact with its force (normals point into the object),
    # and the servo deflection that produces them
    torque = jac.T @ forces
    deflection = _stiffness_pinv(joint_stiffness(scene, finger_mask)) @ torque
    squeeze = hand.clip(q + pinv @ (gaps + common.squeeze_depth_m) + deflection)
    return GraspTargets(pre, squeeze, len(rows), force_n)
