"""The hand enters the scene without sweeping through it: hand–object contacts stay off until
the hand is where the operator's is and clear of the object.

Why: the hand waits at its park pose (:mod:`teleop.bridge.faults`) until the first tracked
frame, and by then the operator's hand may be anywhere — half a metre away, on the far side of
the object. The base glides there at ``hand_max_step_m`` per frame (a jump of that size in one
step upsets MuJoCo), and the straight glide went through the object: knocked over in free mode,
the hand thrown about by the held object in demo mode. Of the two ways out — a path around the
object (a planner for any object and any hand pose, while the operator keeps moving) or a
collision-free glide — this is the second. While the hand *enters*, the object's geoms collide
only with what it rests on (:class:`ContactSwitch`: their contype/conaffinity switched to a
collision bit of their own that only the table and floor also carry), so the hand passes
through it and the object stays where it lies. Contacts come back once

1. the mocap target is the operator's base (no longer clamped by ``hand_max_step_m``),
2. the simulated base is within ``entry_arrive_m`` (metres) and ``entry_arrive_deg``
   (degrees) of it (the weld has caught up), and
3. no hand geom penetrates the object: a collision pass over a scratch copy of the state with
   the object's contacts on (:meth:`ContactSwitch.hand_in_object`), so switching them on never
   starts inside the object, where the solver would throw hand or object out violently. While
   the operator keeps the hand in the object, contacts stay off.

An entry starts when the hand is parked (the scene built: startup, ``choose_object``; or
restored after an instability), when the object is placed again — ``reset_object``,
``set_object_mode``, ``set_object_rest``, back from off the table
(:meth:`teleop.bridge.control.BridgeControl._place_object`) — into the hand (contacts are off
while it is placed; a hand touching it no deeper than :data:`PLACED_OVERLAP_M` keeps its
contacts at once), and after a **tracking gap**: a tracked frame more than
``entry_gap_s`` after the previous tracked one on the sender's clock (``device_time_s``; or the
clock went backwards: a restarted sender), with the operator's base then more than
``hand_max_step_m`` from the hand's target. The sender's clock counts the frames that never
came (a headset that lost the hand sends none, or untracked ones) and the held ones alike, and
a deterministic replay sees the gaps the live session saw. A gap after which the operator's
hand is within one step needs no entry — the hand is already there, and a grasp held through a
dropout is kept (contacts off would drop a free object). A gap up to ``entry_gap_s`` is a
dropout: the clamp catches up with contacts on, counted as a jump (:mod:`teleop.bridge.faults`).

``counts["hand_entries"]`` counts the entries that ended (contacts on again), each logged.
Cost: while no entry runs, one clock comparison a tracked frame; while one runs, the pose check
a tick and the collision pass (tens of µs) only once the pose has arrived.

:class:`BridgeEntry` is a mixin of :class:`teleop.bridge.bridge.Bridge` (through
:class:`teleop.bridge.faults.BridgeFaults`); the attributes annotated on it are the bridge's.
"""

from __future__ import annotations

import logging
import math
import threading
import weakref
from collections import Counter
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from sim.world.contacts import contacts_between
from sim.world.scene import Scene
from teleop.bridge.config import BridgeConfig

__all__ = ["PLACED_OVERLAP_M", "BridgeEntry", "ContactSwitch"]

#: After the object is placed again, a hand at most this deep in it (metres) keeps its contacts:
#: a light touch (a pre-grasp, fingers on the surface) the solver resolves in a step, without
#: throwing anything; deeper overlap (the object placed into a closed hand) makes the hand enter.
PLACED_OVERLAP_M = 0.003

logger = logging.getLogger(__name__)
Array = np.ndarray

_MAX_BIT = 31   # contype/conaffinity are int32: bits 0..30 are usable


def _collide(m: mujoco.MjModel, a: int, b: Array) -> Array:
    """MuJoCo's contype/conaffinity filter between geom ``a`` and each of geoms ``b``."""
    return ((m.geom_contype[a] & m.geom_conaffinity[b]) | (m.geom_contype[b]
                                                           & m.geom_conaffinity[a])) != 0


class ContactSwitch:
    """Switches one scene's hand–object contacts off and on, the object keeping its others.

    A collision bit no geom uses is added to the geoms the object collides with, except the
    hand's (the table, the floor); switched off, the object's geoms carry that bit alone. The
    original bits are kept here, so a switch belongs to its scene for that scene's lifetime."""

    def __init__(self, scene: Scene) -> None:
        m = scene.model
        used = int(np.bitwise_or.reduce(m.geom_contype | m.geom_conaffinity, initial=0))
        free = [b for b in range(_MAX_BIT) if not used >> b & 1]
        if not free:
            raise RuntimeError("every collision bit of the scene's geoms is in use: none is "
                               "left to switch the hand's contacts off")
        self.scene = scene
        self._bit = 1 << free[0]
        bits = m.geom_contype | m.geom_conaffinity
        self._obj = np.flatnonzero(scene.obj_geom_mask & (bits != 0))
        self._contype = m.geom_contype[self._obj].copy()
        self._conaffinity = m.geom_conaffinity[self._obj].copy()
        rest = np.flatnonzero(~scene.hand_geom_mask & ~scene.obj_geom_mask)
        supports = [g for g in rest if _collide(m, int(g), self._obj).any()]
        m.geom_contype[supports] |= self._bit       # no one else has the bit: unchanged with on
        m.geom_conaffinity[supports] |= self._bit
        self.off = False
        self._scratch: mujoco.MjData | None = None

    def switch_off(self) -> None:
        m = self.scene.model
        m.geom_contype[self._obj] = self._bit
        m.geom_conaffinity[self._obj] = self._bit
        self.off = True

    def switch_on(self) -> None:
        m = self.scene.model
        m.geom_contype[self._obj] = self._contype
        m.geom_conaffinity[self._obj] = self._conaffinity
        self.off = False

    def hand_in_object(self, depth_m: float = 0.0) -> bool:
        """A hand geom penetrates the object (deeper than ``depth_m``, metres) in the scene's
        current positions, with contacts on (computed on a scratch copy: the live data and the
        switch stay as they are)."""
        sc = self.scene
        m = sc.model
        if self._scratch is None:
            self._scratch = mujoco.MjData(m)
        s = self._scratch
        s.qpos[:], s.mocap_pos[:], s.mocap_quat[:] = sc.data.qpos, sc.data.mocap_pos, sc.data.mocap_quat
        off = self.off
        self.switch_on()
        try:
            mujoco.mj_kinematics(m, s)
            mujoco.mj_collision(m, s)
        finally:
            if off:
                self.switch_off()
        c = contacts_between(m, s, sc.hand_geom_mask, sc.obj_geom_mask)
        return bool(len(c)) and float(c.dist.min()) < -depth_m


def _angle_deg(q1: Array, q2: Array) -> float:
    """The rotation between two unit quaternions (wxyz), degrees."""
    dot = abs(float(np.dot(q1, q2)) / (float(np.linalg.norm(q1)) * float(np.linalg.norm(q2))))
    return math.degrees(2.0 * math.acos(min(1.0, dot)))


class BridgeEntry:
    """The hand's entry (module docstring)."""

    config: BridgeConfig
    scene: Scene
    counts: Counter[str]
    if TYPE_CHECKING:   # the host's read-only property (Bridge.sim_time_s), typed for this mixin
        @property
        def sim_time_s(self) -> float: ...
    _lock: threading.Lock
    _last_result: Any
    _last_frame: Any

    def _init_entry(self) -> None:
        self._switches: weakref.WeakKeyDictionary[Scene, ContactSwitch] = \
            weakref.WeakKeyDictionary()
        self._entering = False        # hand–object contacts are off until the hand has entered
        self._entry_reason = ""
        self._entry_t0_s = 0.0
        self._at_target = False       # the mocap target is the operator's base (not clamped)
        self._last_tracked_s: float | None = None   # sender's clock of the last tracked frame

    def _contact_switch(self) -> ContactSwitch:
        switch = self._switches.get(self.scene)
        if switch is None:   # the scene's first use: its geoms still have their own bits
            switch = self._switches[self.scene] = ContactSwitch(self.scene)
        return switch

    def _begin_entry(self, reason: str) -> None:
        """Hand–object contacts off until the hand has entered (module docstring)."""
        self._contact_switch().switch_off()
        if not self._entering:
            self._entry_t0_s = self.sim_time_s
        self._entering, self._entry_reason = True, reason
        logger.debug("hand entry (%s): hand–object contacts off", reason)

    def _watch_gap(self, far: bool) -> None:
        """On a tracked frame (the bridge's last one): begin an entry after a tracking gap when
        the operator's base is ``far`` (over one ``hand_max_step_m``) from the hand's target."""
        res, frame = self._last_result, self._last_frame
        if res is None or res.held:
            return
        t_s, last_s = float(frame.device_time_s), self._last_tracked_s
        self._last_tracked_s = t_s
        if last_s is None or self._entering or not far or 0.0 <= t_s - last_s <= self.config.entry_gap_s:
            return
        gap = (f"a tracking gap of {t_s - last_s:.3f} s" if t_s > last_s else
               f"the sender's clock went back {last_s - t_s:.3f} s")
        logger.info("%s, the operator's hand elsewhere: the hand enters again with hand–object "
                    "contacts off (bridge.entry_gap_s = %g s)", gap, self.config.entry_gap_s)
        self._begin_entry(gap)

    def _entry_after_placement(self) -> None:
        """Right after the object was placed again (contacts off for it): contacts on at once
        when the hand is at the operator's pose and no deeper than :data:`PLACED_OVERLAP_M` in
        the object — a hand at the pre-grasp, touching the object, goes on grasping; deeper, the
        hand enters as after a gap."""
        switch = self._contact_switch()
        if self._entering and self._at_target and not switch.hand_in_object(PLACED_OVERLAP_M):
            switch.switch_on()
            self._entering = False
            logger.info("object placed again with the hand clear of it: hand–object contacts on")

    def _end_entry_when_clear(self) -> None:
        """After physics steps: contacts on again once the hand has arrived at the operator's
        pose and is clear of the object (module docstring)."""
        if not (self._entering and self._at_target):
            return
        sc, cfg = self.scene, self.config
        d, a = sc.data, sc.base_qadr
        if math.dist(d.qpos[a:a + 3], d.mocap_pos[sc.mocap_id]) > cfg.entry_arrive_m or \
                _angle_deg(d.qpos[a + 3:a + 7], d.mocap_quat[sc.mocap_id]) > cfg.entry_arrive_deg:
            return
        switch = self._contact_switch()
        if switch.hand_in_object():
            return
        switch.switch_on()
        self._entering = False
        with self._lock:
            self.counts["hand_entries"] += 1
        logger.info("hand entered (%s): hand–object contacts on again after %.3f s (simulated)",
                    self._entry_reason, self.sim_time_s - self._entry_t0_s)
