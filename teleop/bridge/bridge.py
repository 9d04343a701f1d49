"""The teleop bridge: one loop from tracked hands on zenoh to a simulated robot hand and back.

Why one loop: retargeting, the MuJoCo world, contacts, the state stream and the recorder must agree
on one state at one time; one thread owns the :class:`sim.world.scene.Scene` and all that touches it
(control commands are queued to it), so nothing needs a lock around MuJoCo data.

Input (``dexaug/<rig>/hands``, :mod:`teleop.keys`): wire bytes of :mod:`teleop.messages`. The
zenoh callback decodes each sample (malformed bytes and other schema versions are counted and
logged, never raised), hands the raw bytes to the recorder when recording, and keeps only the
**latest** frame: a late or dropped frame never stalls the loop, the next one supersedes it.
Replay (:mod:`teleop.record.replay`) and live ingest publish the same bytes: the bridge cannot tell.

Physics runs at the model timestep, decoupled from the input rate: the loop advances
``mj_step`` to wall-clock time (at most ``max_catchup_steps`` per tick; beyond that the lag is
dropped and counted rather than letting the loop spiral). The hand's servos are the model's at
``servo_kp_scale`` × its kp (what lift-drop validates with). In ``deterministic`` mode (tests,
offline reprocessing) every received frame is queued and processed in order with exactly
``steps_per_frame`` physics steps, so the same input gives the same trajectory bit for bit.

Recording (``start_recording``): raw ``/hands`` as received, and per published state the
``/state`` and ``/contacts`` of the step — both with the step's simulated time ``t_s``, the
``seq`` of the frame answered and one log time — and the ``/events`` with the simulated time
they happen at, so demo extraction can pair and time them on the simulation's own clock.

Faults (:mod:`teleop.bridge.faults`): a recorder write error stops the recording, the loop goes on;
the hand base moves at most ``hand_max_step_m`` per frame, entering without hand–object
contacts (:mod:`teleop.bridge.entry`); an unstable simulation (MuJoCo reset its data) is restored,
the simulated clock never going backwards; an object off the table is put back — with events.

Output: ``/state`` JSON (``seq`` of the frame answered — latency measurements match on it —,
sim time, simulated and retargeted qpos, palm and object poses, hand–object contacts, grasp cue
and assist, :mod:`teleop.bridge.grasp_assist`) at most ``state_rate_hz`` and on each new frame;
``/view`` JPEG from a head-following camera (:mod:`teleop.bridge.view`) at ``view_rate_hz`` when
GL works, rendered in its own thread from a copy of the data (:mod:`teleop.bridge.view_stream`);
``/events`` JSON; with ``live`` (``bridge --foxglove``) the same steps and view on a Foxglove
WebSocket server (:mod:`teleop.bridge.foxglove_live`). Control: queryable
``dexaug/<rig>/control/**``, JSON in, JSON out (``{"ok": false, "error": ...}`` on failure; the
commands: :mod:`teleop.bridge.control`).

World layout: the scene's table top is z = 0; the operator's tracking space (local-floor, z up)
is shifted by ``world_offset_m`` (default 0.8 m down: a table top at a standing operator's
hip height), applied to the retargeted hand base and to the head. The object rests on the table
at ``object_pos_m`` (x, y; metres) with ``object_yaw_deg``: in ``object_mode`` "demo" dropped
there, settled and held fixed, in "free" free (:mod:`teleop.bridge.object_mode`). Contact
records use the object body frame (the mesh origin) and the touching hand body's frame.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import struct
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import zenoh

from sim.hand.model import Hand
from sim.world.objects import load_object
from sim.world.scene import PhysicsOptions, Scene
from teleop import keys as zkeys
from teleop.bridge.config import BridgeConfig, check_object_mode, hand_servos, load_bridge_config
from teleop.bridge.control import BridgeControl
from teleop.bridge.faults import BridgeFaults
from teleop.bridge.foxglove_live import FoxgloveLive
from teleop.bridge.scene_contacts import contact_records, tip_finger_bodies
from teleop.bridge.view_stream import ViewStream, gl_backend, head_pose
from teleop.messages import MAGIC, SCHEMA_VERSION, HandFrame, MessageError, decode
from teleop.record.contact_record import ContactRecord
from teleop.record.recorder import RecordingFailed, SessionRecorder
from teleop.record.schemas import finite_list
from teleop.retarget.config import load_retarget_config
from teleop.retarget.retargeter import Retargeter

__all__ = ["Bridge"]

logger = logging.getLogger(__name__)
Array = np.ndarray

_WARN_EVERY = 100  # after the first few, log one bad-input warning per this many


class Bridge(BridgeFaults, BridgeControl):
    """Hands in, simulated hand + object out; see the module docstring.

    ``session``: an open zenoh session to use (the caller closes it); without one the bridge
    opens a loopback peer on ``listen_port``/``connect_ports`` and closes it in :meth:`close`.
    """

    def __init__(self, hand_name: str, object_name: str | None = None, rig: str = "local",
                 config: BridgeConfig | None = None, *, session: zenoh.Session | None = None,
                 listen_port: int | None = None, connect_ports: tuple[int, ...] = (),
                 retarget_config_path: Path | str | None = None,
                 calibration_frames: list[HandFrame] | None = None,
                 on_recording_closed: Callable[[Path], None] | None = None) -> None:
        self.config = config or load_bridge_config()
        self._on_recording_closed = on_recording_closed
        self.keys = zkeys.RigKeys(rig)
        self.hand = Hand.load(hand_name)
        self.retargeter = Retargeter(self.hand, load_retarget_config(retarget_config_path))
        if calibration_frames:
            self.retargeter.calibrate_scale(calibration_frames)
        self.object_name = object_name or self.config.object
        self.object_mode = check_object_mode(self.config.object_mode, "BridgeConfig.object_mode")
        self._init_faults()
        self._build_scene(self.object_name)

        self.counts: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._latest: tuple[HandFrame, float] | None = None
        self._queue: deque[tuple[HandFrame, float]] = deque()
        self._wake = threading.Event()
        self._init_controls()
        self._recorder: SessionRecorder | None = None
        self._recording_path: Path | None = None
        self._last_frame: HandFrame | None = None
        self._last_result: Any = None
        self._last_seq: int | None = None
        self._ever_tracked = False
        self._q_target: Array | None = None
        self._t0_wall: float | None = None
        self._steps_done = 0
        self._next_state_s = 0.0
        self._next_view_s = 0.0
        self._last_contacts: list[ContactRecord] = []
        self._thread_loop: threading.Thread | None = None
        self.loop_running = False
        self.live: FoxgloveLive | None = None   # set by whoever starts one; they close it

        self._own_session = session is None
        self.session = session or zkeys.open_session(listen_port, list(connect_ports))
        self._pub_state = self.session.declare_publisher(self.keys.state)
        self._pub_view = self.session.declare_publisher(self.keys.view)
        self._pub_events = self.session.declare_publisher(self.keys.events)
        self._sub = self.session.declare_subscriber(self.keys.hands, self._on_hands)
        self._queryable = self.session.declare_queryable(self.keys.control, self._on_query)

        self._view = ViewStream(self.config, self._on_view)
        if self.config.view_enabled and gl_backend() is not None:
            self._view.start(self.scene.model)
        elif self.config.view_enabled:
            logger.warning("no OpenGL backend: the /view stream is off")

    # ---------------------------------------------------------------------------- scene setup

    def _build_scene(self, object_name: str) -> None:
        obj = load_object(object_name)
        cfg = self.config
        floor = float(cfg.world_offset_m[2]) if cfg.floor else None   # the operator's floor
        self.scene = Scene(self.hand, obj, object_hold=True, servos=hand_servos(cfg, self.hand),
                           table=cfg.table, floor_z_m=floor, physics=PhysicsOptions(cfg.timestep_s))
        self.object_name = object_name
        self._tip_fingers = tip_finger_bodies(self.scene)
        self._object_home = self._home_pose(obj)
        self._attach_surface(obj)
        q_target = getattr(self, "_q_target", None)   # None before the first frame's target
        q = self.hand.open_pose if q_target is None else q_target
        self.scene.set_hand_joints(q)
        self.scene.set_hand_ctrl(q)
        self._park_hand()  # above the table until the first frame arrives
        self._place_object()  # after parking: the hand must not be where the object drops

    def _home_pose(self, obj: Any) -> tuple[Array, Array]:
        """The object resting on the table top at ``object_pos_m``/``object_yaw_deg``."""
        yaw = math.radians(self.config.object_yaw_deg)
        quat = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
        z = -float(obj.collision_mesh().bounds[0][2]) + 1e-3 if self.config.table else 0.3
        return np.array([*self.config.object_pos_m, z]), quat

    # ------------------------------------------------------------------------- zenoh callbacks

    def _count_bad(self, kind: str, detail: str) -> None:
        with self._lock:
            self.counts[kind] += 1
            n = self.counts[kind]
        if n <= 3 or n % _WARN_EVERY == 0:
            logger.warning("%s: skipped bad /hands message #%d (%s): %s", self.keys.hands, n,
                           kind, detail)

    def _on_hands(self, sample: zenoh.Sample) -> None:
        t_rx = time.perf_counter()
        raw = sample.payload.to_bytes()
        with self._lock:
            self.counts["received"] += 1
        if len(raw) >= 6 and raw[:4] == MAGIC and \
                struct.unpack_from("<H", raw, 4)[0] != SCHEMA_VERSION:
            self._count_bad("wrong_schema", f"schema version {struct.unpack_from('<H', raw, 4)[0]}"
                            f", expected {SCHEMA_VERSION}")
            return
        try:
            frame = decode(raw)
        except MessageError as exc:
            self._count_bad("malformed", str(exc))
            return
        self._record("write_hands", raw)
        with self._lock:
            self.counts["accepted"] += 1
            if self.config.deterministic:
                self._queue.append((frame, t_rx))
            else:
                if self._latest is not None:
                    self.counts["superseded"] += 1
                self._latest = (frame, t_rx)
        self._wake.set()

    # --------------------------------------------------------------------------------- loop

    @property
    def sim_time_s(self) -> float:
        """Simulated time of the scene, seconds (restarts at 0 when the object changes)."""
        return float(self.scene.data.time)

    @property
    def view_active(self) -> bool:
        """A ``/view`` renderer is up."""
        return self._view.active

    def _take_frame(self) -> tuple[HandFrame, float] | None:
        with self._lock:
            if self.config.deterministic:
                return self._queue.popleft() if self._queue else None
            item, self._latest = self._latest, None
            return item

    def _apply(self, frame: HandFrame) -> None:
        res = self._retarget(frame)   # with the object's surface where it is now
        self._last_result, self._last_frame, self._last_seq = res, frame, int(frame.seq)
        self._q_target = np.asarray(res.q, float)
        base = np.asarray(res.base_pos_m, float) + self.config.world_offset_m
        if not res.held:
            self._ever_tracked = True
        if self._ever_tracked:  # before the first tracked frame the hand stays parked
            self.scene.set_hand_pose(self._limit_base(base), np.asarray(res.base_quat_wxyz, float),
                                     teleport=False)
        self.scene.set_hand_ctrl(self._squeeze.ctrl(self._q_target, self._assist.level))
        with self._lock:
            self.counts["processed"] += 1
            if res.held:
                self.counts["held"] += 1

    def _physics(self, now: float, new_frame: bool) -> None:
        m, d = self.scene.model, self.scene.data
        if self.config.deterministic:
            n = self.config.steps_per_frame if new_frame else 0
        else:
            if self._t0_wall is None:
                self._t0_wall, self._steps_done = now, 0
            n = int((now - self._t0_wall) / m.opt.timestep) - self._steps_done
            if n > self.config.max_catchup_steps:
                with self._lock:
                    self.counts["physics_lag_steps"] += n - self.config.max_catchup_steps
                self._steps_done += n - self.config.max_catchup_steps
                n = self.config.max_catchup_steps
            self._steps_done += max(n, 0)
        t0_s = d.time
        for _ in range(max(n, 0)):
            mujoco.mj_step(m, d)
        if n > 0:
            self._check_physics(t0_s, n)

    def contacts(self) -> list[ContactRecord]:
        """Hand–object contacts of the current state, in world, object and hand-body frames."""
        return contact_records(self.scene, self._tip_fingers)

    def _publish_state(self, t_rx: float | None) -> None:
        sc = self.scene
        qpos = sc.data.qpos[sc.hand_qadr]
        palm_p, palm_q = sc.palm_world_pose()
        obj_p, obj_q = sc.object_pose()
        contacts = self.contacts()
        self._last_contacts = contacts
        res = self._last_result
        held = bool(res.held) if res is not None else True
        msg = {"t_s": self.sim_time_s, "seq": self._last_seq, "qpos": finite_list(qpos),
               "q_target": finite_list(self._q_target) if self._q_target is not None else None,
               "palm_pos_m": finite_list(palm_p), "palm_quat_wxyz": finite_list(palm_q),
               "object": self.object_name, "object_pos_m": finite_list(obj_p),
               "object_quat_wxyz": finite_list(obj_q), "held": held, **self.grasp_state,
               "contacts": [c.to_json() for c in contacts if c.finger is not None]}
        self._pub_state.put(json.dumps(msg).encode())
        with self._lock:
            self.counts["states"] += 1
        extra = {"q_target": msg["q_target"], "held": held, **self.grasp_state}
        if self.live is not None:   # bridge --foxglove (teleop.bridge.foxglove_live)
            self.live.publish_step(sc, contacts, t_s=self.sim_time_s, seq=self._last_seq,
                                   tracked=not held, object_name=self.object_name, extra=extra,
                                   operator=self._last_frame)
        if self._recorder is not None:  # one step, one clock: the same t_s, seq and log time
            t_ns = time.time_ns()
            self._record("write_state", qpos, palm_p, palm_q, obj_p, obj_q, t_s=self.sim_time_s,
                         seq=self._last_seq, tracked=not held, object_name=self.object_name,
                         extra=extra, log_time_ns=t_ns)
            self._record("write_contacts", contacts, t_s=self.sim_time_s, seq=self._last_seq,
                         object_name=self.object_name, log_time_ns=t_ns)

    def step_once(self, now: float | None = None) -> bool:
        """One loop tick: pending controls, the newest frame (if any), physics up to ``now``
        (wall clock, perf_counter seconds), state and view when due. True if a frame was
        processed."""
        now = time.perf_counter() if now is None else now
        self._drain_controls()
        item = self._take_frame()
        if item is not None:
            self._apply(item[0])
        self._physics(now, item is not None)
        if self.config.deterministic:
            if item is not None:
                self._publish_state(item[1])
        elif item is not None or now >= self._next_state_s:
            if now >= self._next_state_s:
                self._next_state_s = now + 1.0 / self.config.state_rate_hz
            self._publish_state(item[1] if item else None)
        if self.view_active and now >= self._next_view_s:
            self._next_view_s = now + 1.0 / self.config.view_rate_hz
            self._view.snapshot(self.scene.model, self.scene.data,
                                head_pose(self._last_frame, self.config))
        return item is not None

    def run(self, duration_s: float | None = None,
            stop_event: threading.Event | None = None) -> None:
        """Run the loop until ``duration_s`` (seconds) passed or ``stop_event`` is set."""
        t_end = None if duration_s is None else time.perf_counter() + duration_s
        self.loop_running = True
        try:
            while not (stop_event is not None and stop_event.is_set()):
                now = time.perf_counter()
                if t_end is not None and now >= t_end:
                    break
                self.step_once(now)
                if self.config.deterministic:
                    timeout = 0.02
                else:
                    next_step = (self._t0_wall or now) + (self._steps_done + 1) * \
                        self.scene.model.opt.timestep
                    timeout = max(0.0, min(next_step, self._next_state_s) - time.perf_counter())
                if self._queue and self.config.deterministic:
                    continue
                if self._wake.wait(timeout):
                    self._wake.clear()
        finally:
            self.loop_running = False
            self._drain_controls()

    def start(self) -> threading.Thread:
        """Run :meth:`run` in a background thread (stop it with :meth:`stop`)."""
        self._stop = threading.Event()
        self._thread_loop = threading.Thread(target=self.run, kwargs={"stop_event": self._stop},
                                             name="dexaug-bridge", daemon=True)
        self._thread_loop.start()
        while not self.loop_running and self._thread_loop.is_alive():
            time.sleep(0.001)
        return self._thread_loop

    def stop(self) -> None:
        if self._thread_loop is not None:
            self._stop.set()
            self._wake.set()
            self._thread_loop.join(10.0)
            self._thread_loop = None

    def close(self) -> None:
        """Stop the loop and the view, close a recording, undeclare, close an owned session."""
        self.stop()
        if self._recorder is not None:
            try:
                self._cmd_stop_recording({"reason": "bridge closed"})
            except RecordingFailed as exc:
                logger.warning("%s", exc)
        self._view.stop()
        for ent in (self._sub, self._queryable, self._pub_state, self._pub_view, self._pub_events):
            with contextlib.suppress(Exception):  # already gone with the session
                ent.undeclare()
        if self._own_session:
            self.session.close()

    def __enter__(self) -> Bridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _on_view(self, jpeg: bytes) -> None:
        """A rendered view frame (render thread): publish, count, record."""
        self._pub_view.put(jpeg)
        with self._lock:
            self.counts["views"] += 1
        self._record("write_view", jpeg)
        if self.live is not None:
            self.live.publish_view(jpeg)
