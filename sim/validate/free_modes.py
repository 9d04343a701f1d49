"""Where an underactuated finger settles when it presses: its joints' free modes.

A tendon servo that drives two joints through one tendon (the Shadow Hand's J1 + J2, one
actuator) holds only their sum; the split between them is free. A fingertip pressing an object
loads the two joints unequally (the joint farther from the fingertip has the longer lever), and
nothing but a joint limit holds the difference, so under a squeeze the split runs toward a
limit. Measured on the Shadow in the ``dgb`` protocol: a pressed middle finger's J2 went from
0.26 rad to its lower limit (0.01) while J1 curled from 0.22 to 0.45 rad, the fingertip
rolling and sliding across the surface and dragging the free object with it; with the two
joints rigidly tied (an experiment, not the benchmark's model) 14 of 40 failing screwdriver
grasps and 18 of 40 failing sugar-box grasps passed.

:func:`free_modes` finds, from the compiled model, the coupled joint pairs a single actuator
drives together with nothing else holding their difference; :func:`settled` moves a joint vector
along each such mode, the way the contacts push it, to the extension stop where the pressed
finger ends up. A closing that starts there does not reconfigure the finger on the object. A
mode pushed toward a flexion stop is left alone: that is the fingertip curling into a hook
(0.6 rad of travel, about 15 mm at the fingertip, on the 16 mm dice), a different approach
rather than the same one settled, and settling it cost the dice's passes (README "Grasps that
hold"). Units: radians (joint vectors), newton-metres (generalised forces).
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.hand.model import Hand
from sim.world.scene import Scene

__all__ = ["FreeMode", "free_modes", "settled"]

# a mode is free when no actuator moves it: singular values of the pair's moment arms below
# this share of the largest moment arm
_FREE_TOL = 1e-6
# generalised force (N·m) on a mode below which its contacts are taken not to push it
_PUSH_TOL_NM = 1e-6

#: (i, j, v): indices into the hand's joint vector and the unit direction (2,) of (q_i, q_j)
#: that no actuator drives and no constraint holds
FreeMode = tuple[int, int, np.ndarray]


def _held_joints(m: mujoco.MjModel) -> set[int]:
    """Joints an equality constraint ties to something (a joint or tendon equality, or a
    connect/weld on the joint's body): their differences are not free."""
    held: set[int] = set()
    for e in range(m.neq):
        kind, a, b = int(m.eq_type[e]), int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
        if kind == mujoco.mjtEq.mjEQ_JOINT:
            held.update(j for j in (a, b) if j >= 0)
        elif kind == mujoco.mjtEq.mjEQ_TENDON:
            for t in (a, b):
                if t >= 0:
                    adr, num = m.tendon_adr[t], m.tendon_num[t]
                    held.update(int(m.wrap_objid[w]) for w in range(adr, adr + num)
                                if m.wrap_type[w] == mujoco.mjtWrap.mjWRAP_JOINT)
        elif kind in (mujoco.mjtEq.mjEQ_CONNECT, mujoco.mjtEq.mjEQ_WELD):
            held.update(j for j in range(m.njnt) if int(m.jnt_bodyid[j]) in (a, b))
    return held


def free_modes(scene: Scene, hand: Hand, arm: np.ndarray) -> list[FreeMode]:
    """The free modes of ``hand``'s coupled joint pairs (``hand.couplings``) in ``scene``
    (with all of the hand's joints, as the lift-drop scene has them). ``arm``: the actuators'
    moment arms over the hand's joints (:func:`sim.validate.effort.finger_moment_arms`). A pair
    driven by two actuators, one that an actuator does not reach, or one tied by the model (a
    closed linkage's equality) has none."""
    m = scene.model
    held = _held_joints(m)
    scale = max(float(np.abs(arm).max(initial=0.0)), 1e-12)
    modes = []
    for i, j, _ in hand.couplings:
        if held.intersection(int(m.dof_jntid[scene.hand_dadr[k]]) for k in (i, j)):
            continue
        pair = arm[:, [i, j]]
        if (np.abs(pair) < _FREE_TOL * scale).all(axis=0).any():
            continue            # a joint no actuator reaches: not a tendon-shared pair
        _, s, vt = np.linalg.svd(pair)
        if len(s) > 1 and s[1] > _FREE_TOL * scale:
            continue            # two actuators hold the split
        modes.append((i, j, vt[-1]))
    return modes


def settled(q: np.ndarray, modes: list[FreeMode], push: np.ndarray, lower: np.ndarray,
            upper: np.ndarray) -> np.ndarray:
    """``q`` with each free mode moved the way the generalised force ``push`` (per hand joint,
    N·m: the contacts' reaction on the fingers, −Jᵀf) drives it, as far as the first joint
    limit (``lower``/``upper`` per hand joint) — where that limit is a lower one (the
    extension stop; module docstring). A mode ``push`` does not load (a finger off the object)
    stays where it is."""
    q = np.array(q, dtype=float)
    for i, j, v in modes:
        drive = float(v @ push[[i, j]])
        if abs(drive) < _PUSH_TOL_NM:
            continue
        step = np.sign(drive) * v
        stops = [(((upper[k] if s > 0 else lower[k]) - q[k]) / s, s)
                 for k, s in zip((i, j), step, strict=True) if abs(s) > 1e-12]
        travel, toward = min(stops, default=(np.inf, 0.0))
        if not np.isfinite(travel) or toward > 0:   # no stop, or a flexion stop: left alone
            continue
        q[[i, j]] += max(travel, 0.0) * step
    return q
