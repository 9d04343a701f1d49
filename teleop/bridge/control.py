"""The bridge's control side: ``dexaug/<rig>/control/**`` queries and the commands they run.

Why commands are queued: one thread (the loop's) owns the MuJoCo scene and the recorder, so a
query from the zenoh thread becomes a :class:`_Pending` command that the loop runs between two
steps (:meth:`BridgeControl._drain_controls`); when no loop runs, the caller's thread runs it.
JSON in, JSON out: ``{"ok": true, ...}`` or ``{"ok": false, "error": ...}``, never an
exception. ``status`` is answered from the zenoh thread and never waits for the loop.

Commands (:data:`COMMANDS`): ``start_recording`` (``path``, ``overwrite``),
``stop_recording`` (``reason``), ``choose_object`` (``object``), ``reset_object``,
``set_object_mode`` (``object_mode`` "demo" or "free": the object is put back on its spot in
that mode, :mod:`teleop.bridge.object_mode`), ``mark_grasp`` (extra keys go into the event),
``status``. A recording's metadata names the ``object_mode`` and the ``table``
(:func:`teleop.bridge.object_mode.table_record`) it started with, and every placement event
(``object_changed``, ``object_reset``; after a mode change with the ``previous`` mode) names
the mode from then on and how the drop went, so the mode of every step is known. Events go out
on ``/events`` and,
when recording, to the session's ``/events`` with the simulated time of the step they happen
at (``t_s``, seconds; a ``grasp_mark`` also names the ``seq`` of the last frame answered), the
clock demo extraction matches them on.

:class:`BridgeControl` is a mixin of :class:`teleop.bridge.bridge.Bridge`: the state it reads
and changes is the bridge's (the attributes annotated on the class).
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from sim.hand.model import Hand
from sim.world.scene import Scene
from teleop import keys as zkeys
from teleop.bridge.config import BridgeConfig, check_object_mode
from teleop.bridge.object_mode import Placement, place_object, table_record
from teleop.bridge.view_stream import ViewStream
from teleop.record.contact_record import ContactRecord
from teleop.record.recorder import SessionRecorder
from teleop.retarget.retargeter import Retargeter

__all__ = ["COMMANDS", "BridgeControl"]

logger = logging.getLogger(__name__)
Array = np.ndarray

#: the bridge's control commands: the rig's common ones and the object mode switch
COMMANDS: tuple[str, ...] = zkeys.CONTROL_COMMANDS


class _Pending:
    """A control command waiting for the loop thread."""

    def __init__(self, command: str, args: dict[str, Any]) -> None:
        self.command, self.args = command, args
        self.done = threading.Event()
        self.result: dict[str, Any] = {}



class BridgeControl:
    """Control queries and commands of the bridge (module docstring)."""

    config: BridgeConfig
    keys: zkeys.RigKeys
    hand: Hand
    retargeter: Retargeter
    scene: Scene
    object_name: str
    object_mode: str
    placement: Placement
    counts: Counter[str]
    loop_running: bool
    _lock: threading.Lock
    _wake: threading.Event
    _controls: queue.Queue[_Pending]
    _recorder: SessionRecorder | None
    _recording_path: Path | None
    _on_recording_closed: Callable[[Path], None] | None
    _pub_events: zenoh.Publisher
    _view: ViewStream
    _object_home: tuple[Array, Array]
    _last_contacts: list[ContactRecord]
    _last_seq: int | None
    _t0_wall: float | None
    _steps_done: int
    sim_time_s: float
    view_active: bool
    _build_scene: Callable[[str], None]

    def _init_controls(self) -> None:
        self._controls = queue.Queue()

    def _on_query(self, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        command = key.rsplit("/", 1)[-1]
        try:
            payload = query.payload
            args = json.loads(payload.to_bytes() or b"{}") if payload is not None else {}
            if not isinstance(args, dict):
                raise ValueError("the payload must be a JSON object")
            if command == "status":
                result = self.status()
            elif command not in COMMANDS:
                result = {"ok": False, "error": f"unknown command {command!r}; one of "
                                                 f"{list(COMMANDS)}"}
            else:
                result = self.control(command, args, timeout_s=10.0)
        except Exception as exc:
            result = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        query.reply(query.key_expr, json.dumps(result).encode())

    def control(self, command: str, args: dict[str, Any] | None = None, *,
                timeout_s: float = 10.0) -> dict[str, Any]:
        """Run a control command in the loop thread (or here when no loop runs) and return its
        JSON-able result."""
        pending = _Pending(command, dict(args or {}))
        if not self.loop_running:
            self._execute(pending)
            return pending.result
        self._controls.put(pending)
        self._wake.set()
        if not pending.done.wait(timeout_s):
            return {"ok": False, "error": f"{command}: the bridge loop did not answer in "
                                          f"{timeout_s} s"}
        return pending.result

    def _drain_controls(self) -> None:
        while True:
            try:
                pending = self._controls.get_nowait()
            except queue.Empty:
                return
            self._execute(pending)

    def _execute(self, p: _Pending) -> None:
        try:
            handler = getattr(self, f"_cmd_{p.command}")
            p.result = {"ok": True, **handler(p.args)}
        except Exception as exc:
            logger.warning("control %s failed: %s", p.command, exc)
            p.result = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        p.done.set()

    def _event(self, event_type: str, payload: dict[str, Any] | None = None) -> None:
        msg = {"type": event_type, "t_s": self.sim_time_s, **(payload or {})}
        self._pub_events.put(json.dumps(msg).encode())
        if self._recorder is not None:
            self._recorder.write_event(event_type, payload, t_s=self.sim_time_s)

    def _cmd_start_recording(self, args: dict[str, Any]) -> dict[str, Any]:
        if self._recorder is not None:
            raise RuntimeError(f"already recording to {self._recording_path}")
        path = Path(args["path"]) if "path" in args else (
            self.config.recordings_dir / f"{self.keys.rig}_{time.strftime('%Y%m%d_%H%M%S')}"
                                         f"_{time.time_ns() % 1_000_000:06d}.mcap")
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"hand": self.hand.name, "object": self.object_name,
                "joint_names": list(self.hand.joint_names),
                "fingers": list(self.hand.finger_names), "rig": self.keys.rig,
                "world_offset_m": list(map(float, self.config.world_offset_m)),
                "deterministic": self.config.deterministic, "object_mode": self.object_mode,
                "table": table_record(self.scene)}
        self._recorder = SessionRecorder(path, metadata=meta, overwrite=bool(args.get("overwrite")))
        self._recording_path = path
        logger.info("recording to %s", path)
        return {"path": str(path)}

    def _cmd_stop_recording(self, args: dict[str, Any]) -> dict[str, Any]:
        rec, path = self._recorder, self._recording_path
        if rec is None:
            raise RuntimeError("not recording")
        self._recorder = None
        rec.close(reason=str(args.get("reason", "stop_recording")))
        self._recording_path = None
        if self._on_recording_closed is not None and path is not None:
            try:
                self._on_recording_closed(path)
            except Exception:   # a hook must never take the bridge down
                logger.exception("recording-closed hook failed for %s", path)
        return {"path": str(path), "written": dict(rec.stats.written)}

    def _cmd_choose_object(self, args: dict[str, Any]) -> dict[str, Any]:
        name = str(args["object"])
        was_view = self.view_active
        if was_view:
            self._view.stop()
        self._build_scene(name)
        self._t0_wall, self._steps_done = None, 0
        if was_view:
            self._view.start(self.scene.model)
        self._event("object_changed", {"object": name, **self.placement.to_json()})
        return {"object": name}

    def _place_object(self) -> Placement:
        """The object at its home pose for the current mode (demo: dropped, settled, held)."""
        self.placement = place_object(self.scene, self._object_home, self.object_mode, self.config)
        return self.placement

    def _cmd_reset_object(self, args: dict[str, Any]) -> dict[str, Any]:
        placement = self._place_object()
        self._event("object_reset", {"object": self.object_name, **placement.to_json()})
        return {"object": self.object_name}

    def _cmd_set_object_mode(self, args: dict[str, Any]) -> dict[str, Any]:
        mode = check_object_mode(args.get("object_mode"), "set_object_mode: object_mode")
        previous = self.object_mode
        if mode == previous:
            return {"object_mode": mode, "changed": False}
        self.object_mode = mode
        placement = self._place_object()
        self._event("object_reset", {"object": self.object_name, "previous": previous,
                                     **placement.to_json()})
        return {"object_mode": mode, "changed": True}

    def _cmd_mark_grasp(self, args: dict[str, Any]) -> dict[str, Any]:
        fingers = sorted({c.finger for c in self._last_contacts if c.finger})
        payload = {"object": self.object_name, "seq": self._last_seq, "fingers": fingers,
                   **{k: v for k, v in args.items() if k not in ("object", "seq")}}
        self._event("grasp_mark", payload)
        return {"fingers": fingers}

    def status(self) -> dict[str, Any]:
        """Counters and settings (answered from the zenoh thread: never waits for the loop)."""
        with self._lock:
            counts = dict(self.counts)
        return {"ok": True, "rig": self.keys.rig, "hand": self.hand.name,
                "object": self.object_name, "counts": counts,
                "held": dict(self.retargeter.held_counts),
                "recording": str(self._recording_path) if self._recording_path else None,
                "last_seq": self._last_seq, "sim_time_s": self.sim_time_s,
                "view": self.view_active, "loop_running": self.loop_running,
                "deterministic": self.config.deterministic, "object_mode": self.object_mode,
                "object_held": self.scene.object_held}

