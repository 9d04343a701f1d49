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
normal force ``f_i = max(grip_safety · F·(1 + d/ρ) / (μ · n_contacts), min_grip_force_n)``
(F: the load the protocol puts on the object — the weight m·g in a lift, the largest push of
``six-dir`` or ``dgb`` —, d: centre of mass to the contacts' centroid, ρ: their spread), so the
friction of all contacts carries ``grip_safety`` times the load and its moment about the grasp.
The load, the friction and the servo stiffness are the ones of the protocol the squeeze is for
(:class:`sim.metrics.holding.HoldLoads`).
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
of length error at a fixed control). The geometric part ``J⁺ (gaps + depth)`` is solved normal
first: of the joint motions that move each contact that far along its normal, the one that
moves it least along the surface (:func:`normal_first_motion`). ``K_q⁺`` is a damped
pseudo-inverse because coupled tendon joints (one actuator for two joints) make K_q singular.
Actuator force limits saturate in the simulation, as on a real hand. Both protocols close onto
the same targets.

Last, the grip is scaled up (:func:`grip_boost`, at most ``max_grip_safety / grip_safety``) as
far as every force-limited finger servo's squeeze force ``k·M·Δq`` stays within
``servo_headroom`` of its limit: the planned grip is realised only to within a servo's
stiffness times a millimetre-scale placement error, which is most of a light object's grip.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from sim.hand.model import Hand
from sim.metrics.holding import HoldLoads, min_grip_forces_n
from sim.validate.config import GRAVITY_MPS2, CommonParams
from sim.validate.contact_forces import balanced_normal_forces
from sim.validate.effort import closest_per_body, finger_moment_arms, servo_force_limits
from sim.validate.free_modes import free_modes, settled
from sim.validate.self_clearance import clear_of_itself
from sim.world.contacts import Contacts
from sim.world.scene import Scene

__all__ = ["GraspTargets", "finger_joint_mask", "grip_boost", "grip_force_n", "holds_every_load",
           "joint_stiffness", "largest_force_n", "least_grip_total_n", "loads_in_world",
           "normal_first_motion", "servo_limits_from", "servo_stiffness_from", "squeeze_total_n",
           "targets_from_contacts", "weight_loads"]

# relative damping of the pseudo-inverses: the contact Jacobian's (m², as J Jᵀ) and the joint
# stiffness's (times its largest eigenvalue; only makes singular directions harmless)
_JAC_DAMPING_M2 = 1e-4
_STIFFNESS_DAMPING = 1e-3
# smallest lever arm (metres) credited to a grasp's friction torque: about a fingertip pad
_MIN_LEVER_M = 0.005


@dataclass(frozen=True)
class GraspTargets:
    """Joint targets derived from a grasp: where to start closing and where to squeeze to, how
    many hand bodies were near the object, the normal force (newtons) the squeeze target asks
    of each of them, and ``touch``: the grasp with each of those bodies moved onto the surface,
    no deeper (None: no body near) — the middle stage of the ``dgb`` protocol's closing
    (:mod:`sim.validate.stages`). ``pregrasp_own_split``: where the fingers' free modes were
    settled, the pregrasp with them left at the grasp's own split (None: nothing settled) —
    the alternative the ``dgb`` rehearsal tries (:mod:`sim.validate.rehearsal`)."""

    pregrasp: np.ndarray
    squeeze: np.ndarray
    n_bodies_near: int
    grip_force_n: float = 0.0
    touch: np.ndarray | None = None
    pregrasp_own_split: np.ndarray | None = None


def finger_joint_mask(hand: Hand) -> np.ndarray:
    """(nq,) bool over the hand's joints: True for a joint of some finger (the squeeze moves
    fingers only, never the wrist)."""
    finger_joints = {j for f in hand.config.fingers for j in f.joints}
    return np.array([n in finger_joints for n in hand.joint_names])


def weight_loads(mass_kg: float, com_m: np.ndarray, common: CommonParams,
                 down: np.ndarray | None = None) -> HoldLoads:
    """The one load of a lift: the weight of ``mass_kg`` pulling along ``down`` (unit, world;
    None: −z) at the centre of mass ``com_m`` (world, metres), with ``[common]`` friction."""
    down = np.array([0.0, 0.0, -1.0]) if down is None else np.asarray(down, dtype=float)
    load = np.concatenate([mass_kg * GRAVITY_MPS2 * down, np.zeros(3)])
    friction = common.contact.friction
    return HoldLoads(load[None, :], np.asarray(com_m, dtype=float), friction[0], friction[1],
                     "lift-drop")


def loads_in_world(loads: HoldLoads, scene: Scene) -> HoldLoads:
    """``loads`` (object frame, as :func:`sim.validate.loads.hold_loads` gives them) turned
    into the world frame of the object as ``scene`` holds it, about its simulated centre of
    mass (what the squeeze presses on)."""
    rot = scene.data.xmat[scene.obj_body].reshape(3, 3)
    w = np.asarray(loads.loads, dtype=float).reshape(-1, 6)
    world = np.hstack([w[:, :3] @ rot.T, w[:, 3:] @ rot.T])
    return HoldLoads(world, scene.data.xipos[scene.obj_body].copy(), loads.mu,
                     loads.mu_torsion_m, loads.protocol)


def largest_force_n(loads: HoldLoads) -> float:
    """The largest force (newtons) among ``loads``: what a squeeze sized by the rule carries."""
    return float(np.linalg.norm(np.asarray(loads.loads, dtype=float).reshape(-1, 6)[:, :3],
                                axis=1).max())


def grip_force_n(points: np.ndarray, loads: HoldLoads, common: CommonParams) -> float:
    """Desired normal force (newtons) per grasping contact, for contacts at ``points`` (n, 3).

    Friction must carry the load F (the weight in a lift, the largest push of a push test) and
    its moment about the grasp: with the centre of mass a distance d from the contacts'
    centroid and the contacts spread ρ (RMS) around it, friction forces hold a torque of about
    μ·Σf·ρ, so Σf ≥ F·(1 + d/ρ)/μ covers both (conservatively, as if they added). Scaled by
    ``grip_safety``, split over the n contacts, never less than ``min_grip_force_n``.
    """
    total_n = squeeze_total_n(points, loads, common.grip_safety)
    return max(total_n / len(points), common.min_grip_force_n)


def squeeze_total_n(points: np.ndarray, loads: HoldLoads, grip_safety: float) -> float:
    """The squeeze's total normal force (newtons) before the per-contact floor:
    ``grip_safety · F·(1 + d/ρ) / μ`` for contacts at ``points`` (n, 3), F the largest force
    among ``loads`` (same frame as the points, centre of mass ``loads.com_m``);
    :func:`grip_force_n` has the reasoning."""
    centroid = points.mean(axis=0)
    spread_m = max(float(np.sqrt(((points - centroid) ** 2).sum(axis=1).mean())), _MIN_LEVER_M)
    offset_m = float(np.linalg.norm(np.asarray(loads.com_m, dtype=float) - centroid))
    return grip_safety * largest_force_n(loads) * (1.0 + offset_m / spread_m) / loads.mu


def least_grip_total_n(points: np.ndarray, normals_in: np.ndarray, loads: HoldLoads,
                       grip_safety: float) -> float:
    """``grip_safety`` times the least total normal force (newtons) with which contacts at
    ``points`` (n, 3) pressing along ``normals_in`` (n, 3, into the object) hold each of
    ``loads`` (same frame) with its sliding and torsional friction — the largest of those over
    the loads these contacts can hold at all; ``inf`` when they can hold none of them however
    hard they press (a load they cannot hold fails the test whatever the squeeze: the squeeze
    is sized for the others).

    Why, beside :func:`squeeze_total_n`: that rule sizes the squeeze from the contacts' spread
    ρ, but only a spread across the load's moment arm helps. Opposed contacts on a thin wall
    (a bowl's rim) are spread along the wall, and the moment of a centre of mass 6 cm away must
    come from a couple of contact forces a few millimetres apart; the linear programme of
    :func:`sim.metrics.holding.min_grip_force_n` knows that, the rule does not.
    """
    finite = [x for x in _least_grip_per_load(points, normals_in, loads) if np.isfinite(x)]
    return grip_safety * max(finite) if finite else float("inf")


def _least_grip_per_load(points: np.ndarray, normals_in: np.ndarray,
                         loads: HoldLoads) -> list[float]:
    """Per load of ``loads``, the least total normal force (newtons; inf: none holds it) with
    which contacts at ``points`` pressing along ``normals_in`` hold it
    (:func:`sim.metrics.holding.min_grip_forces_n`, with ``loads``' friction)."""
    return min_grip_forces_n(points, normals_in, loads.com_m, loads.loads, loads.mu,
                             loads.mu_torsion_m).tolist()


def holds_every_load(near: Contacts, loads: HoldLoads) -> bool:
    """Whether the hand bodies of ``near`` (each by its closest contact) can hold every one of
    ``loads`` with some normal forces inside the friction cones of ``loads``
    (:func:`sim.metrics.holding.min_grip_force_n` finite for each); False with no body.

    Why: the ``dgb`` squeeze presses only the grasp's contacts (the bodies within 5 mm), since
    pulling spare links onto the free object is drift the benchmark counts. But where those
    contacts cannot hold some push at all — a bowl's rim pinched between thumb and fingertips
    holds no push along the rim's own plane — the links 5–10 mm off are what can, and the
    squeeze presses them too (five demos, ``dgb``: 570 → 590 of 998 passes, the bowl 73 → 92
    of 198; README "Grasps that hold")."""
    idx = closest_per_body(near)
    if not len(idx):
        return False
    return bool(np.isfinite(_least_grip_per_load(near.points_a[idx], near.normal[idx],
                                                 loads)).all())


def _servo_arm(scene: Scene, finger_mask: np.ndarray,
               act_stiffness: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The hand actuators' moment arms over the finger joints (:func:`finger_moment_arms`) and
    each actuator's position stiffness k (see :func:`joint_stiffness`)."""
    m, acts = scene.model, scene.hand_act
    k = (np.where(scene.position_servos(), np.maximum(-m.actuator_biasprm[acts, 1], 0.0), 0.0)
         if act_stiffness is None else np.asarray(act_stiffness, dtype=float))
    return finger_moment_arms(scene, finger_mask), k


def joint_stiffness(scene: Scene, finger_mask: np.ndarray,
                    act_stiffness: np.ndarray | None = None) -> np.ndarray:
    """Joint-space stiffness (nq × nq over the hand's joints; N·m/rad for hinges) of the
    hand's finger servos at the current state: ``K_q = Mᵀ diag(k) M``.

    M is the actuator moment matrix (∂ actuator length / ∂ q, gear included) of the hand's
    actuators and k each actuator's position stiffness at a fixed control: ``−biasprm[1]``
    for a fixed-gain, affine-bias actuator (a position servo: kp), 0 for anything else (a
    motor holds no position). Rows and columns outside the finger joints (``finger_mask``,
    :func:`finger_joint_mask`) are zero, since the squeeze moves fingers only.
    ``act_stiffness`` (per ``scene.hand_act``) replaces k where the squeeze is for servos of
    another scene with the same actuators (the ``dgb`` protocol's kp 5 on every servo). Needs
    ``mj_forward`` (or ``mj_fwdPosition``) to have run.
    """
    arm, k = _servo_arm(scene, finger_mask, act_stiffness)
    return arm.T @ (k[:, None] * arm)


def _same_named(source: Scene, scene: Scene, values: np.ndarray, missing: float) -> np.ndarray:
    """``values`` (per hand actuator of ``source``) re-ordered onto ``scene``'s hand actuators
    by actuator name; ``missing`` where ``source`` has no actuator of that name."""
    names = [source.model.actuator(int(a)).name for a in source.hand_act]
    by_name = dict(zip(names, np.asarray(values, dtype=float).tolist(), strict=True))
    return np.array([by_name.get(scene.model.actuator(int(a)).name, missing)
                     for a in scene.hand_act])


def servo_stiffness_from(source: Scene, scene: Scene) -> np.ndarray:
    """Per hand actuator of ``scene``, the position stiffness (kp) its same-named actuator has
    in ``source``'s compiled model (0 where ``source`` has none: the wrist of the benchmark's
    floating palm) — for a squeeze derived in ``scene`` and simulated in ``source``."""
    m = source.model
    kp = np.where(source.position_servos(),
                  np.maximum(-m.actuator_biasprm[source.hand_act, 1], 0.0), 0.0)
    return _same_named(source, scene, kp, 0.0)


def servo_limits_from(source: Scene, scene: Scene) -> np.ndarray:
    """Per hand actuator of ``scene``, the force limit of its same-named actuator in
    ``source`` (:func:`servo_force_limits`; ``inf`` where ``source`` has none)."""
    return _same_named(source, scene, servo_force_limits(source), np.inf)


def grip_boost(servo_forces: np.ndarray, limits: np.ndarray, common: CommonParams) -> float:
    """How much to scale a squeeze's grip up (1 to ``max_grip_safety / grip_safety``): as far
    as every servo's squeeze force (``servo_forces``, per hand actuator, in the units of its
    ``limits``) stays within ``servo_headroom`` of its limit.

    Why: a grip of ``grip_safety`` times the least that holds the load is realised only
    approximately — a position servo presses by its stiffness times a millimetre-scale
    placement error, about as much as the whole grip of a 70 g screwdriver — so light grasps
    want more margin, while a larger margin for every grasp saturates the servos of heavy ones
    (grip_safety 3: sugar-box failures with a servo at its limit 3 → 32 of 55). Measured in the
    README ("Grasps that hold"). Servos without a force limit have no headroom to measure, so a
    hand with none (the Menagerie Allegro and LEAP) keeps ``grip_safety`` (boosted to the cap,
    the LEAP's fingertip grasps of the nine calibration objects fell from 157 to 131 of 360).
    """
    limits = np.asarray(limits, dtype=float)
    limited = np.isfinite(limits)
    if not limited.any() or common.grip_safety <= 0.0:   # no headroom known; no grip to scale
        return 1.0
    most = common.max_grip_safety / common.grip_safety
    use = np.abs(np.asarray(servo_forces, dtype=float)[limited]) / limits[limited]
    worst = float(use.max())
    if worst <= 0.0:
        return most
    return float(np.clip(common.servo_headroom / worst, 1.0, most))


def _stiffness_pinv(stiffness: np.ndarray) -> np.ndarray:
    """Damped pseudo-inverse s / (s² + λ²) per eigenvalue s of a symmetric stiffness: ≈ 1/s
    where the servos are stiff, → 0 (not 1/λ) along directions no actuator resists, such as
    the difference of two tendon-coupled joints."""
    s, v = np.linalg.eigh(stiffness)
    lam = _STIFFNESS_DAMPING * max(float(s.max(initial=0.0)), 1e-12)
    return (v * (s / (s * s + lam * lam))) @ v.T


def _damped_pinv(jac: np.ndarray) -> np.ndarray:
    """Damped least-squares inverse ``Jᵀ (J Jᵀ + λ² I)⁻¹`` of a contact Jacobian (rows in
    metres per radian; λ² = ``_JAC_DAMPING_M2``)."""
    return jac.T @ np.linalg.solve(jac @ jac.T + _JAC_DAMPING_M2 * np.eye(len(jac)),
                                   np.eye(len(jac)))


def normal_first_motion(jac_normal: np.ndarray, jac_surface: np.ndarray,
                        along_m: np.ndarray) -> np.ndarray:
    """Joint motion (radians, one per Jacobian column) that moves contact i ``along_m[i]``
    (metres) along its normal and, within that, as little along the surface as the joints
    allow: the damped least-squares solution for the normal rows ``jac_normal`` (n × nq), then
    the surface rows ``jac_surface`` (each contact's 3 Jacobian rows with the normal projected
    out, 3n × nq) driven to zero in that task's null space (two-level task priority).

    Why: the least-norm motion along the normals alone slides the contacts along the surface as
    well, wherever the finger's arc is not normal to it, and a finger that reaches the object
    still dragging along it pulls the object with friction — on the free object of the ``dgb``
    protocol, the squeeze turned a 16 mm cube or a screwdriver handle before any push.
    Measured in the README ("Grasps that hold"): lift-drop and ``dgb`` passes on five demos
    rose with it (817 → 837 and 516 → 541 of 998)."""
    pinv = _damped_pinv(jac_normal)
    first = pinv @ along_m
    null = np.eye(jac_normal.shape[1]) - pinv @ jac_normal
    surface = jac_surface @ null
    return first + null @ (_damped_pinv(surface) @ (-jac_surface @ first))


def targets_from_contacts(scene: Scene, hand: Hand, q: np.ndarray, near: Contacts,
                          common: CommonParams, finger_mask: np.ndarray,
                          loads: HoldLoads,
                          act_stiffness: np.ndarray | None = None,
                          act_limits: np.ndarray | None = None,
                          settle_modes: bool = False,
                          self_clear: bool = False) -> GraspTargets:
    """Pregrasp and squeeze joint vectors of the grasp placed in ``scene`` at joints ``q``,
    from its hand–object contacts and near misses ``near`` (distances in metres).

    Per hand body the closest point is moved along its normal (by distance − backoff for the
    pregrasp, by the distance for ``touch``, distance + squeeze depth for the squeeze; the
    squeeze's motion normal first, :func:`normal_first_motion` — the pregrasp's stays the
    least-norm one: solved normal first too, with the ``dgb`` middle stage of README "Grasps
    that hold", it cost 570 → 551 ``dgb`` passes on five demos). The squeeze then adds the servo
    deflection ``K_q⁺ Jᵀ f`` that presses each of those points into the object with the grip
    force f (module docstring): the larger of :func:`grip_force_n`'s rule and the least grip
    that holds ``loads`` at these contacts (:func:`least_grip_total_n`), split over them.
    ``loads`` (world frame, about the object's centre of mass): what the protocol asks the
    grasp to hold (:func:`weight_loads`, :func:`loads_in_world`).
    The grip is then scaled up by :func:`grip_boost` as far as the servos' squeeze forces
    ``k·M·Δq`` stay within ``servo_headroom`` of their limits (``act_limits``, per hand
    actuator; default the scene's own forceranges).
    ``act_stiffness``: see :func:`joint_stiffness`. ``settle_modes`` (the ``dgb`` protocol's
    ``[dgb] settle_free_modes``): the pregrasp's tendon-shared joint pairs are started where
    these contacts will press them (:func:`sim.validate.free_modes.settled`; the servo's sum
    and the other targets unchanged). ``self_clear`` (the ``dgb`` protocol, which refuses a
    pregrasp whose links are 1 cm into each other): the pregrasp puts the hand's links no
    deeper into each other than the grasp has them
    (:func:`sim.validate.self_clearance.clear_of_itself`). No body near the object gives
    ``n_bodies_near = 0`` and ``q`` for both targets.
    """
    m, d = scene.model, scene.data
    rows, surface_rows, gap_list, closest, normals = [], [], [], [], []
    jacp = np.zeros((3, m.nv))
    points = near.points_a
    for i in closest_per_body(near):
        mujoco.mj_jac(m, d, jacp, None, points[i], int(near.body_a[i]))
        n = near.normal[i]
        rows.append(n @ jacp[:, scene.hand_dadr])
        surface_rows.append((np.eye(3) - np.outer(n, n)) @ jacp[:, scene.hand_dadr])
        gap_list.append(near.dist[i])
        closest.append(points[i])
        normals.append(near.normal[i])
    if not rows:
        return GraspTargets(q, q, 0)
    jac = np.array(rows) * finger_mask
    gaps = np.array(gap_list)
    pinv = _damped_pinv(jac)
    pre = hand.clip(q + pinv @ (gaps - common.pregrasp_backoff_m))
    force_n = grip_force_n(np.array(closest), loads, common)
    least_n = least_grip_total_n(np.array(closest), np.array(normals), loads, common.grip_safety)
    if np.isfinite(least_n):
        force_n = max(force_n, least_n / len(rows))
    if common.squeeze_forces == "balanced":
        forces = balanced_normal_forces(np.array(closest), np.array(normals),
                                        d.xipos[scene.obj_body], force_n * len(rows))
    else:
        forces = np.full(len(rows), force_n)
    # joint torques that press every contact with its force (normals point into the object),
    # and the servo deflection that produces them
    arm, k = _servo_arm(scene, finger_mask, act_stiffness)
    deflection = _stiffness_pinv(arm.T @ (k[:, None] * arm)) @ (jac.T @ forces)
    limits = servo_force_limits(scene) if act_limits is None else act_limits
    boost = grip_boost(k * (arm @ deflection), limits, common)
    onto = normal_first_motion(jac, np.vstack(surface_rows) * finger_mask,
                               gaps + common.squeeze_depth_m)
    squeeze = hand.clip(q + onto + boost * deflection)
    modes = free_modes(scene, hand, arm) if settle_modes else []
    push = -(jac.T @ forces)   # the contacts' reaction on the fingers drives the free modes

    def settle(p: np.ndarray) -> np.ndarray:
        return settled(p, modes, push, hand.lower, hand.upper) if modes else p

    def kept_clear(settle: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        return clear_of_itself(scene, q, pre, settle) if self_clear else settle(pre)

    own_split = kept_clear(lambda p: p) if modes else None
    return GraspTargets(kept_clear(settle), squeeze, len(rows), boost * force_n,
                        hand.clip(q + pinv @ gaps), own_split)
