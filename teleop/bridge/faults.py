"""The bridge survives its faults: a failing recorder, a hand-base jump, an unstable simulation.

Why one place: each fault used to end the session silently — a full disk killed the loop
thread (the process stayed up, answering ``loop_running: false``), a wrist jump of metres made
MuJoCo reset its data (the object at the origin, the simulated clock back at 0 in the
recording) — and each needs the same three answers: keep the loop going, say what happened
(an ``/events`` message, a log line), count it (``status`` ``counts``).

- **Recorder errors.** Every write to the session goes through :meth:`BridgeFaults._record`.
  An error (a full disk: ENOSPC, EFBIG past ``RLIMIT_FSIZE``, any OSError —
  :class:`teleop.record.recorder.RecordingFailed`, the file then readable up to its last
  complete chunk — or a recorder bug) stops that recording: ``recording_failed`` (``path``,
  ``reason``) on ``/events``, a warning, ``counts["recording_failed"]``; the loop goes on. The
  recording-closed hook is not called: a failed recording is not a finished one.
- **Hand-base jumps.** The mocap target moves at most ``hand_max_step_m`` (metres per
  processed frame) from where it is toward the retargeted base, along the line — clamped, not
  held: a one-frame glitch moves the hand at most that far and back, a real relocation
  (tracking regained elsewhere) is caught up at that speed, and a non-finite base is held.
  ``counts["hand_base_limited"]`` per limited frame, one warning per episode and then at most
  one every :data:`REPORT_EVERY_S` — except while the hand enters (from the park pose before
  the first tracked frame and after a restore, or after a tracking gap): that glide is no jump,
  and it passes through the object with hand–object contacts off (:mod:`teleop.bridge.entry`).
- **Instability.** Each MuJoCo step checks qpos, qvel and qacc; a NaN, Inf or |x| > 1e10 raises
  a warning counter (mjWARN_BADQPOS/BADQVEL/BADQACC) and resets the data. After each batch of
  steps the bridge compares the clock with the steps taken and reads those counters (a few
  µs a batch, against ~70 µs a step); on either the scene is restored: the clock where the
  steps would have brought it (the recorded ``t_s`` never goes backwards), the hand parked
  open above the table (its last pose may be what failed, or inside the object), the object
  placed on its spot for the current mode (:meth:`_place_object`); ``scene_restored``
  (``reason``, ``object``, the placement) on ``/events`` (and in the recording where its
  format lists the type, :data:`teleop.record.schemas.EVENT_TYPES`),
  ``counts["scene_restored"]``, a warning as above. The next frames glide the hand back at
  ``hand_max_step_m`` (an entry).
- **The object off the table** (free mode): it lands on the floor and is placed again after a
  while (:mod:`teleop.bridge.object_watch`).

An episode, for the warnings: one recording, or the time outside recordings.
:class:`BridgeFaults` is a mixin of :class:`teleop.bridge.bridge.Bridge` (the attributes
annotated on the class are the bridge's).
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import zenoh

from sim.hand.model import Hand
from sim.world.scene import Scene
from teleop.bridge.config import BridgeConfig
from teleop.bridge.entry import BridgeEntry
from teleop.bridge.object_mode import Placement
from teleop.bridge.object_watch import ObjectWatch
from teleop.bridge.surface_feed import SurfaceFeed
from teleop.record.recorder import RecordingFailed, SessionRecorder
from teleop.record.schemas import EVENT_TYPES

__all__ = ["REPORT_EVERY_S", "BridgeFaults", "EpisodeWarning"]

logger = logging.getLogger(__name__)
Array = np.ndarray

#: a fault that repeats is logged again at most this often (seconds, wall clock)
REPORT_EVERY_S = 10.0
#: where the hand waits, from the object's spot on the table (metres): clear of its drop
PARK_OFFSET_M = np.array([-0.2, 0.0, 0.3])
_BAD_STATE = {int(mujoco.mjtWarning.mjWARN_BADQPOS): "position",
              int(mujoco.mjtWarning.mjWARN_BADQVEL): "velocity",
              int(mujoco.mjtWarning.mjWARN_BADQACC): "acceleration"}
_QPOS, _QVEL, _QACC = _BAD_STATE


class EpisodeWarning:
    """A warning that may repeat every frame: logged the first time in an episode (module
    docstring), then at most once per ``interval_s`` with how many times it happened since."""

    def __init__(self, interval_s: float = REPORT_EVERY_S) -> None:
        self.interval_s = interval_s
        self._episode: object = object()   # matches no episode: the first one always logs
        self._t_mono = 0.0
        self._n = 0

    def warn(self, episode: object, msg: str, *args: Any) -> None:
        self._n += 1
        now = time.monotonic()
        if episode is self._episode and now - self._t_mono < self.interval_s:
            return
        logger.warning(msg + (f" [{self._n}× since the last report]" if self._n > 1 else ""), *args)
        self._episode, self._t_mono, self._n = episode, now, 0


class BridgeFaults(BridgeEntry, ObjectWatch, SurfaceFeed):
    """Fault handling of the bridge (module docstring)."""

    config: BridgeConfig
    hand: Hand
    scene: Scene
    object_name: str
    object_mode: str
    counts: Counter[str]
    _lock: threading.Lock
    if TYPE_CHECKING:   # the host's read-only property (Bridge.sim_time_s), typed for this mixin
        @property
        def sim_time_s(self) -> float: ...
    _recorder: SessionRecorder | None
    _recording_path: Path | None
    _pub_events: zenoh.Publisher
    _place_object: Callable[[], Placement]

    def _init_faults(self) -> None:
        self._init_entry()
        self._init_object_watch()
        self._base_warning = EpisodeWarning()
        self._restore_warning = EpisodeWarning()

    # ------------------------------------------------------------------------------ recording

    def _record(self, write: str, *args: Any, **kwargs: Any) -> None:
        """``SessionRecorder.<write>(*args, **kwargs)`` when recording; an error stops the
        recording (module docstring). Any thread."""
        rec = self._recorder
        if rec is None:
            return
        try:
            getattr(rec, write)(*args, **kwargs)
        except Exception as exc:
            self._recording_failed(rec, exc)

    def _recording_failed(self, rec: SessionRecorder, exc: Exception) -> None:
        with self._lock:
            if self._recorder is not rec:   # stopped meanwhile, or another thread was first
                return
            path, self._recorder, self._recording_path = self._recording_path, None, None
            self.counts["recording_failed"] += 1
        reason = str(exc) if isinstance(exc, RecordingFailed) else f"{type(exc).__name__}: {exc}"
        try:
            rec.close(reason=f"failed: {reason}")     # a no-op after a write error
        except RecordingFailed as then:
            reason = f"{reason}; then {then}"
        logger.warning("recording %s stopped (%s); the bridge goes on without recording", path,
                       reason)
        self._notify("recording_failed", {"path": str(path), "reason": reason})

    def _notify(self, event_type: str, payload: dict[str, Any]) -> None:
        """``event_type`` on ``/events`` at the current simulated time and, when recording, in
        the session if its format has that event type."""
        t_s = self.sim_time_s
        self._pub_events.put(json.dumps({"type": event_type, "t_s": t_s, **payload}).encode())
        if event_type in EVENT_TYPES:
            self._record("write_event", event_type, payload, t_s=t_s)

    # ------------------------------------------------------------------------------ hand base

    def _park_hand(self) -> None:
        """The hand's base at rest at its park pose, above and behind the object's spot; it
        enters from there (:mod:`teleop.bridge.entry`)."""
        park = np.array([*self.config.object_pos_m, 0.0]) + PARK_OFFSET_M
        self.scene.set_hand_pose(park, np.array([1.0, 0.0, 0.0, 0.0]), teleport=True)
        self._at_target = False
        self._begin_entry("from the park pose")

    def _limit_base(self, base_m: Array) -> Array:
        """``base_m`` (world, metres), or the point ``hand_max_step_m`` from the current mocap
        target toward it (the current target when ``base_m`` is not finite). A tracked frame
        after a gap may begin an entry (:mod:`teleop.bridge.entry`)."""
        now = self.scene.data.mocap_pos[self.scene.mocap_id]
        step_m, limit_m = math.dist(base_m, now), self.config.hand_max_step_m
        self._at_target = step_m <= limit_m
        self._watch_gap(far=not self._at_target)
        if self._at_target:
            return base_m
        limited = now + (base_m - now) * (limit_m / step_m) if math.isfinite(step_m) else now.copy()
        if self._entering:
            return limited
        with self._lock:
            self.counts["hand_base_limited"] += 1
        self._base_warning.warn(self._recorder, "hand base: a jump of %.3g m in one frame moved "
                                "%.3g m (bridge.hand_max_step_m)", step_m, limit_m)
        return limited

    # ------------------------------------------------------------------------------ stability

    def _check_physics(self, t0_s: float, steps: int) -> None:
        """After ``steps`` physics steps from simulated time ``t0_s``: restore the scene when
        MuJoCo found a bad state (module docstring), else watch the object and the entry."""
        d = self.scene.data
        dt = self.scene.model.opt.timestep
        t_s = t0_s + steps * dt
        w = d.warning
        if abs(d.time - t_s) < 0.5 * dt and not (w[_QPOS].number or w[_QVEL].number
                                                 or w[_QACC].number):
            self._watch_object()
            self._end_entry_when_clear()
            return
        self._restore_scene(self._instability(t0_s, steps), t_s)

    def _instability(self, t0_s: float, steps: int) -> str:
        """What MuJoCo found, in words."""
        m, d = self.scene.model, self.scene.data
        for kind, what in _BAD_STATE.items():
            if d.warning[kind].number:
                dof = int(d.warning[kind].lastinfo)
                joint = m.joint(int(m.dof_jntid[dof])).name if 0 <= dof < m.nv else "?"
                return (f"MuJoCo found a bad {what} (NaN, Inf or huge) at DOF {dof} ({joint}) "
                        "and reset the simulation")
        return f"the simulated clock went from {t0_s:.4f} s to {d.time:.4f} s in {steps} steps"

    def _restore_scene(self, reason: str, t_s: float) -> None:
        """The scene at simulated time ``t_s``: hand parked open, object placed again."""
        sc = self.scene
        mujoco.mj_resetData(sc.model, sc.data)   # also clears the warning counters
        sc.data.time = t_s
        sc.set_hand_joints(self.hand.open_pose)
        sc.set_hand_ctrl(self.hand.open_pose)
        self._park_hand()
        placement = self._place_object()
        with self._lock:
            self.counts["scene_restored"] += 1
        self._restore_warning.warn(self._recorder, "unstable simulation at t = %.3f s: %s; the "
                                   "scene is restored (hand parked, %s placed again)", t_s,
                                   reason, self.object_name)
        self._notify("scene_restored", {"reason": reason, "object": self.object_name,
                                        **placement.to_json()})
