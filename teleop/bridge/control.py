"""The bridge's control side: ``dexaug/<rig>/control/**`` queries and the commands they run.

Why commands are queued: one thread (the loop's) owns the MuJoCo scene and the recorder, so a
query from the zenoh thread becomes a :class:`_Pending` command that the loop runs between two
steps (:meth:`BridgeControl._drain_controls`); when no loop runs, the caller's thread runs it.
JSON in, JSON out: ``{"ok": true, ...}`` or ``{"ok": false, "error": ...}``, never an
exception. ``status`` is answered from the zenoh thread and never waits for the loop.

Commands (:data:`COMMANDS`): ``start_recording`` (``name``: a file name in
``recordings_dir``; in-process callers only: ``path``, ``overwrite``),
``stop_recording`` (``reason``), ``choose_object`` (``object``), ``reset_object``,
``set_object_mode`` (``object_mode`` "demo" or "free": the object is put back on its spot in
that mode, :mod:`teleop.bridge.object_mode`), ``set_object_rest`` (``rest``: an index into the
object's stable resting poses, best first, :func:`teleop.bridge.object_mode.scene_rest_poses`;
optional ``yaw_deg`` about the table normal, default the current one: the object is put back
on its spot lying that way, in the current mode), ``next_object_rest`` (the next resting pose,
after the last the first; the page's button), ``mark_grasp`` (extra keys go into the event),
``status``. ``choose_object`` takes the same optional ``rest`` and ``yaw_deg`` for the new
object; without them the new object stands upright at the config's ``object_yaw_deg``.
The first use of an object's resting poses computes them (about a second per object, in the
loop thread), later ones read them from the cache. A recording's metadata names the
``object_mode``, the ``table`` (:func:`teleop.bridge.object_mode.table_record`) and the
``object_rest`` (:class:`teleop.bridge.object_mode.RestChoice`) it started with, and every
placement event (``object_changed``, ``object_reset``; after a mode change with the
``previous`` mode, after a resting-pose change with ``previous_rest``) names the mode and the
resting pose from then on and how the drop went, so the mode of every step is known. Events go out
on ``/events`` and,
when recording, to the session's ``/events`` with the simulated time of the step they happen
at (``t_s``, seconds; a ``grasp_mark`` also names the ``seq`` of the last frame answered), the
clock demo extraction matches them on.

Trust: a query on the zenoh queryable is untrusted (any process that reaches the rig's peer,
and the headset page's forwarded requests). :func:`remote_args` checks its arguments before it is
queued: a recording is chosen by ``name`` only (sanitised to a plain file name, ``.mcap``
added, created inside ``recordings_dir`` and never over an existing file: a ``_2``, ``_3``…
suffix is added), ``path`` and ``overwrite`` are refused, ``choose_object`` takes an id of
the installed catalogue (a primitive or a YCB folder), never a file, and a resting pose is an
integer ``rest`` and a finite ``yaw_deg``, nothing else (the index's range is checked against
the object's poses before anything moves). Sizes are bounded (issue #56): a payload over
:data:`MAX_CONTROL_PAYLOAD_BYTES`, a mark of more than :data:`MAX_MARK_KEYS` keys, a command
beyond :data:`MAX_PENDING_CONTROLS` waiting: refused with the value and range. In-process Python calls of
:meth:`BridgeControl.control` (the CLI's ``--record PATH``, re-recording) are trusted.

A failed ``choose_object`` changes nothing: the new scene is built first, and on failure the
previous scene (and ``/view``, never stopped) stays.

:class:`BridgeControl` is a mixin of :class:`teleop.bridge.bridge.Bridge`: the state it reads
and changes is the bridge's (the attributes annotated on the class).
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import zenoh

from sim.hand.model import Hand
from sim.world.objects import one_line
from sim.world.scene import Scene
from teleop import keys as zkeys
from teleop.bridge.config import BridgeConfig, check_object_mode
from teleop.bridge.object_mode import (
    Placement,
    place_object,
    rest_home,
    rest_request,
    scene_rest_poses,
    table_record,
)
from teleop.bridge.remote_args import calibration_seconds, recording_file, remote_args
from teleop.bridge.status import BridgeStatus
from teleop.bridge.view_stream import ViewStream
from teleop.messages import HandFrame
from teleop.record.contact_record import ContactRecord
from teleop.record.recorder import SessionRecorder
from teleop.record.session_file import RecordingFailed
from teleop.retarget.retargeter import Retargeter

__all__ = ["COMMANDS", "MAX_CONTROL_PAYLOAD_BYTES", "MAX_MARK_KEYS", "MAX_PENDING_CONTROLS",
           "BridgeControl"]

logger = logging.getLogger(__name__)


Array = np.ndarray

#: the bridge's control commands: the rig's common ones and the object mode switch
COMMANDS: tuple[str, ...] = zkeys.CONTROL_COMMANDS
#: the largest control payload (bytes of JSON) a remote caller may send: every command's
#: arguments fit in a few hundred bytes, and ``mark_grasp`` copies its extra keys into an event
#: that is published and recorded, so a bigger one would only grow every recording (issue #56)
MAX_CONTROL_PAYLOAD_BYTES = 16 * 1024
#: the most extra keys a remote ``mark_grasp`` may put into its event (a note, a label, ...)
MAX_MARK_KEYS = 32
#: the most remote commands waiting for the loop thread: each waits 10 s at most, so more would
#: queue work the loop cannot reach before its callers give up
MAX_PENDING_CONTROLS = 32
#: the bridge attributes a scene build sets: saved before ``choose_object`` builds, restored
#: when the build fails
_SCENE_STATE = ("scene", "object_name", "_tip_fingers", "_object_home", "placement", "object_rest",
                "object_rest_yaw_deg", "_surface")


class _Pending:
    """A control command waiting for the loop thread."""

    def __init__(self, command: str, args: dict[str, Any]) -> None:
        self.command, self.args = command, args
        self.done = threading.Event()
        self.result: dict[str, Any] = {}



class _Refused(ValueError):
    """A remote control refused before it is parsed (its message is the whole reply)."""


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
    #: the resting pose the object is placed in (None: upright, the home pose) and its yaw
    #: (degrees; None: the config's object_yaw_deg); class defaults until a command sets them
    object_rest: int | None = None
    object_rest_yaw_deg: float | None = None
    counts: Counter[str]
    loop_running: bool
    _lock: threading.Lock
    if TYPE_CHECKING:   # the host's read-only property (Bridge.sim_time_s), typed for this mixin
        @property
        def sim_time_s(self) -> float: ...
    if TYPE_CHECKING:   # the host's read-only property (Bridge.view_active), typed for this mixin
        @property
        def view_active(self) -> bool: ...
    _wake: threading.Event
    _queue: deque[tuple[HandFrame, float]]
    _latest: tuple[HandFrame, float] | None
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
    _begin_entry: Callable[[str], None]
    _entry_after_placement: Callable[[], None]
    _build_scene: Callable[[str], None]
    _notify: Callable[[str, dict[str, Any]], None]

    def _init_controls(self) -> None:
        self._controls = queue.Queue()

    def _on_query(self, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        command = key.rsplit("/", 1)[-1]
        result: Mapping[str, Any]   # the status, a command's result or an error, as JSON
        try:
            raw = query.payload.to_bytes() if query.payload is not None else b""
            if len(raw) > MAX_CONTROL_PAYLOAD_BYTES:   # refused unparsed: its size is the fault
                raise _Refused(f"{command}: a payload of {len(raw)} bytes is refused: allowed 0 "
                               f"to {MAX_CONTROL_PAYLOAD_BYTES} bytes")
            args = json.loads(raw or b"{}")
            if not isinstance(args, dict):
                raise ValueError("the payload must be a JSON object")
            if command == "status":
                result = self.status()
            elif command not in COMMANDS:
                result = {"ok": False, "error": f"unknown command {command!r}; one of "
                                                 f"{list(COMMANDS)}"}
            else:
                result = self.control(command, args, timeout_s=10.0, trusted=False)
        except _Refused as exc:   # the text, not the exception: a kept record holds the query
            result = {"ok": False, "error": str(exc)}
            logger.warning("refused remote control: %s", result["error"])
        except Exception as exc:
            result = {"ok": False, "error": f"{type(exc).__name__}: {one_line(str(exc))}"}
        query.reply(query.key_expr, json.dumps(result).encode())

    def control(self, command: str, args: dict[str, Any] | None = None, *,
                timeout_s: float = 10.0, trusted: bool = True) -> dict[str, Any]:
        """Run a control command in the loop thread (or here when no loop runs) and return its
        JSON-able result. ``trusted``: this process's own code, which may pass a recording
        ``path``/``overwrite`` or an object file; the zenoh queryable passes False and its
        arguments go through :func:`remote_args` first (module docstring)."""
        args = dict(args or {})
        if not trusted:
            try:
                args = remote_args(command, args)
                extra = len(args) if command == "mark_grasp" else 0
                if extra > MAX_MARK_KEYS:
                    raise ValueError(f"mark_grasp: {extra} extra keys are refused: allowed 0 "
                                     f"to {MAX_MARK_KEYS} keys")
                if self.loop_running and self._controls.qsize() >= MAX_PENDING_CONTROLS:
                    raise ValueError(f"{command}: {self._controls.qsize()} controls already "
                                     f"wait for the loop: allowed 0 to {MAX_PENDING_CONTROLS}")
            except ValueError as exc:
                why = str(exc)   # not the exception: a kept log record would hold the query
                logger.warning("refused remote control %s: %s", command, why)
                return {"ok": False, "error": why}
        pending = _Pending(command, args)
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
            logger.warning("control %s failed: %s", p.command, one_line(str(exc)))
            p.result = {"ok": False, "error": f"{type(exc).__name__}: {one_line(str(exc))}"}
        p.done.set()

    def _event(self, event_type: str, payload: dict[str, Any] | None = None) -> None:
        """Publish and record an event through the bridge's guarded path (a write error stops
        the recording, never the command: :mod:`teleop.bridge.faults`)."""
        self._notify(event_type, payload or {})

    def _cmd_start_recording(self, args: dict[str, Any]) -> dict[str, Any]:
        if self._recorder is not None:
            raise RuntimeError(f"already recording to {self._recording_path}")
        if "path" in args:   # in-process callers only (remote_args refuses it)
            path = Path(args["path"])
        else:
            name = args.get("name") or (f"{self.keys.rig}_{time.strftime('%Y%m%d_%H%M%S')}"
                                        f"_{time.time_ns() % 1_000_000:06d}")
            path = recording_file(self.config.recordings_dir, str(name))
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {"hand": self.hand.name, "object": self.object_name,
                "joint_names": list(self.hand.joint_names),
                "fingers": list(self.hand.finger_names), "rig": self.keys.rig,
                "world_offset_m": list(map(float, self.config.world_offset_m)),
                "deterministic": self.config.deterministic, "object_mode": self.object_mode,
                "table": table_record(self.scene),
                "object_rest": self.placement.rest.to_json() if self.placement.rest else None}
        self._recorder = SessionRecorder(path, metadata=meta, overwrite=bool(args.get("overwrite")))
        self._recording_path = path
        logger.info("recording to %s", path)
        return {"path": str(path)}

    def _cmd_stop_recording(self, args: dict[str, Any]) -> dict[str, Any]:
        rec, path = self._recorder, self._recording_path
        if rec is None:
            raise RuntimeError("not recording")
        self._recorder, self._recording_path = None, None
        try:
            rec.close(reason=str(args.get("reason", "stop_recording")))
        except RecordingFailed as exc:
            logger.warning("recording %s failed while closing: %s", path, exc)
            self._notify("recording_failed", {"path": str(path), "reason": str(exc)})
            raise
        if self._on_recording_closed is not None and path is not None:
            try:
                self._on_recording_closed(path)
            except Exception:   # a hook must never take the bridge down
                logger.exception("recording-closed hook failed for %s", path)
        return {"path": str(path), "written": dict(rec.stats.written)}

    def _cmd_choose_object(self, args: dict[str, Any]) -> dict[str, Any]:
        name = str(args["object"])
        rest, yaw = rest_request("choose_object", args)
        saved = {k: getattr(self, k) for k in _SCENE_STATE if hasattr(self, k)}
        try:   # a rest index the new object lacks fails its placement: the old scene stays
            self.object_rest, self.object_rest_yaw_deg = rest, yaw
            self._build_scene(name)
        except Exception:
            for k, v in saved.items():   # the previous scene stays, and /view never stopped
                setattr(self, k, v)
            raise
        self._t0_wall, self._steps_done = None, 0
        if self.view_active:   # it rendered the previous model until now
            self._view.stop()
            self._view.start(self.scene.model)
        self._event("object_changed", {"object": name, **self.placement.to_json()})
        return {"object": name}

    def _place_object(self) -> Placement:
        """The object on its spot in the chosen resting pose for the current mode (demo:
        dropped, settled, held). Hand–object contacts are off while it is placed (the hand may
        be where it lands); then the hand enters again (:mod:`teleop.bridge.entry`) only if it
        is deep inside the object: a hand at the pre-grasp, touching it, goes on grasping."""
        self._begin_entry("the object was placed again")
        yaw = self.config.object_yaw_deg if self.object_rest is None or \
            self.object_rest_yaw_deg is None else self.object_rest_yaw_deg
        home, rest = rest_home(self.scene, self._object_home, self.object_rest, yaw)
        self.placement = place_object(self.scene, home, self.object_mode, self.config, rest)
        self._entry_after_placement()
        return self.placement

    def _cmd_set_object_rest(self, args: dict[str, Any]) -> dict[str, Any]:
        rest, yaw = rest_request("set_object_rest", args)
        poses = scene_rest_poses(self.scene)
        index = poses.check_index(rest, "set_object_rest: rest")
        return self._rest_to(index, self.object_rest_yaw_deg if yaw is None else yaw, len(poses))

    def _cmd_next_object_rest(self, args: dict[str, Any]) -> dict[str, Any]:
        poses = scene_rest_poses(self.scene)
        index = 0 if self.object_rest is None else (self.object_rest + 1) % len(poses)
        return self._rest_to(index, self.object_rest_yaw_deg, len(poses))

    def _rest_to(self, index: int, yaw_deg: float | None, n_poses: int) -> dict[str, Any]:
        """Re-place the object in resting pose ``index`` at ``yaw_deg`` (None: the config's),
        with an ``object_reset`` event naming the ``previous_rest``."""
        previous = self.placement.rest.to_json() if self.placement.rest is not None else None
        self.object_rest, self.object_rest_yaw_deg = index, yaw_deg
        placement = self._place_object()
        self._event("object_reset", {"object": self.object_name, "previous_rest": previous,
                                     **placement.to_json()})
        return {"object_rest": placement.to_json()["object_rest"], "rest_poses": n_poses}

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

    def _cmd_recalibrate_scale(self, args: dict[str, Any]) -> dict[str, Any]:
        """Measure the operator's hand scale again over the next seconds of tracking (the
        current scale stays in use until then)."""
        duration = calibration_seconds(args)
        self.retargeter.recalibrate(duration)
        return {"duration_s": duration if duration is not None
                else self.retargeter.config.calibration_s}

    def _cmd_mark_grasp(self, args: dict[str, Any]) -> dict[str, Any]:
        fingers = sorted({c.finger for c in self._last_contacts if c.finger})
        payload = {"object": self.object_name, "seq": self._last_seq, "fingers": fingers,
                   **{k: v for k, v in args.items() if k not in ("object", "seq")}}
        self._event("grasp_mark", payload)
        return {"fingers": fingers}

    def wait_idle(self, timeout_s: float = 10.0, *, received: int | None = None) -> bool:
        """Wait until ``received`` /hands samples arrived (if given) and every accepted frame was
        processed or superseded (tests, offline reprocessing). False on timeout."""
        t_end = time.perf_counter() + timeout_s
        while time.perf_counter() < t_end:
            with self._lock:
                c = self.counts
                arrived = received is None or c["received"] >= received
                done = c["accepted"] == c["processed"] + c["superseded"]
                if arrived and done and not self._queue and self._latest is None:
                    return True
            time.sleep(0.002)
        return False

    def status(self) -> BridgeStatus:
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
                "object_held": self.scene.object_held, "object_rest": self.object_rest,
                "object_rest_yaw_deg": self.object_rest_yaw_deg}

