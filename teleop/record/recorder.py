"""Recording a teleop session to one MCAP file, crash-safe.

Why MCAP and this layout: one self-describing file per session (every channel has a registered
schema, see :mod:`teleop.record.schemas`) that replay, demo extraction and Foxglove all read; raw input
(``/hands``) is kept bit-exact so a replay reproduces the session, and the simulation outputs
(``/state``, ``/contacts``) are kept so demo extraction does not need to re-simulate.

Writer: the official ``foxglove-sdk``'s MCAP writer (``foxglove.open_mcap`` on a context of the
recorder's own), so the ``foxglove.*`` channels carry the SDK's schemas and encoding; it writes
through :class:`~teleop.record.session_file.SessionFile`, which keeps the guarantees below.
Its chunk-size trigger is off and every chunk is ended by :meth:`SessionRecorder.flush`'s policy
(the SDK's ``flush`` ends the chunk, writes its message indexes and flushes). While a chunk is
open the SDK streams its compressed bytes behind a chunk header whose length is still unset;
such a tail reads as truncated (:mod:`teleop.record.mcap_scan`), so the guarantees are those of
a writer that buffers the chunk in memory. The SDK stores a channel (and its schema) with the
channel's first message; the session reader counts a topic of the layout that never had a
message as 0.

File policy: the recorder writes **in place** at ``path`` (no ``.part`` + rename). MCAP is
append-only, so the file on disk is always a valid MCAP prefix; a killed recorder leaves a file
that :func:`teleop.record.session.open_session` reads up to its last complete chunk (reporting
``truncated=True``) and that Foxglove opens as an unindexed file. Writing in place means the
session is where the operator expects it even after a crash; a ``.part`` name would add a
recovery step and no safety. An existing file is never overwritten unless ``overwrite=True``.
:func:`teleop.record.session.repair_session` rewrites a truncated file with a summary when a tool needs
the index.

Flush policy (what a crash can lose): messages accumulate in an in-memory chunk; the chunk is
compressed and written with its message index, and handed to the OS (Python's buffers
flushed), as soon as any of these holds —

- ``flush_interval_s`` (default 0.5 s) of wall-clock time has passed since the chunk's first
  message, or its messages span that much log time;
- the chunk holds ``chunk_size`` bytes (default 256 KiB uncompressed);
- an event was written (events are rare and the most valuable records of a session);
- :meth:`SessionRecorder.flush` or :meth:`SessionRecorder.close` is called.

So a killed process (SIGKILL, a crash) loses at most the unflushed chunk: ≤ ``flush_interval_s``
of data. Data handed to the OS survives the process; surviving a power cut also needs ``fsync``
(``fsync=True`` syncs after every chunk; off by default because a sync can stall the bridge loop
for tens of milliseconds on slow disks; :meth:`close` always syncs). The checks run when a
message is written, so a loop that stops writing should call :meth:`flush`.

Write errors (a full disk, any OSError): the recording stops, cut back to its last complete
chunk (:mod:`teleop.record.session_file`); that write, every later one and :meth:`close` raise
:class:`~teleop.record.session_file.RecordingFailed`.

Timestamps: every ``write_*`` takes ``log_time_ns`` (nanoseconds; default ``time.time_ns()``,
Unix epoch, which Foxglove displays as dates). The JSON payloads' ``t_s`` is the caller's clock
of the record — the bridge passes its simulated time, the same for the ``/state``,
``/contacts`` and ``/events`` of one step, and ``/state`` and ``/contacts`` also share the
step's ``seq`` — and defaults to seconds since the recorder opened. The recorder is thread-safe (one lock):
zenoh callbacks may write ``/hands`` while the bridge loop writes the rest.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import foxglove as fx
from foxglove import messages as fm
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

from teleop import messages as hand_messages
from teleop.record import foxglove, schemas
from teleop.record.contact_record import ContactRecord, contacts_payload
from teleop.record.foxglove import FrameTransform
from teleop.record.metadata import encode_metadata, session_metadata
from teleop.record.session import SessionError
from teleop.record.session_file import RecordingFailed, SessionFile

__all__ = ["RecorderStats", "RecordingFailed", "SessionRecorder"]

log = logging.getLogger(__name__)

_COMPRESSION = {"zstd": MCAPCompression.Zstd, "lz4": MCAPCompression.Lz4, "none": None}
#: Bytes a message adds to a chunk besides its data (record header + MCAP message fields).
_MESSAGE_OVERHEAD = 9 + 22
#: Event types only the recorder writes (at open and at close).
_RECORDER_EVENTS = frozenset({"recording_started", "recording_stopped"})


def _not_an_mcap_io_error(record: logging.LogRecord) -> bool:
    """The SDK logs an MCAP sink's write error met inside ``log`` (multi-line, with a Python
    traceback); the recorders are this process's MCAP sinks and each raises the same error as
    one line (:class:`RecordingFailed`), so that duplicate is dropped."""
    return not record.getMessage().startswith("error logging message: McapError(Io(")


logging.getLogger("foxglove.log_sink_set").addFilter(_not_an_mcap_io_error)


@dataclass
class RecorderStats:
    """Counters of a recording. ``written``: messages per topic handed to the recorder;
    ``flushed``: of those, the ones written to the file (what a crash now would keep);
    ``chunks``: chunks written; ``bytes_on_disk``: file size so far; ``flush_time_s``: total
    seconds spent compressing and writing chunks."""

    written: Counter[str] = field(default_factory=Counter)
    flushed: Counter[str] = field(default_factory=Counter)
    chunks: int = 0
    bytes_on_disk: int = 0
    flush_time_s: float = 0.0


class SessionRecorder:
    """Write one teleop session to ``path`` (a ``.mcap`` file); use as a context manager.

    metadata: session facts stored in the ``dexaug.session`` metadata record — by convention
    ``hand`` (hand config name), ``object`` (initial object name), ``joint_names`` (the order of
    ``/state`` qpos; checked against every qpos), ``fingers`` (finger names, for marker colours),
    ``rig``, ``config_hashes``; any JSON-serialisable values. The recorder adds
    ``format_version``, software versions, ``created_utc``, ``start_time_ns`` and ``clock``.
    chunk_size: bytes of uncompressed messages after which a chunk is written.
    compression: "zstd" (default: best ratio), "lz4" (faster) or "none".
    record_view: register ``/view`` and keep the JPEGs given to :meth:`write_view` (off by
    default: images dominate the file size).
    flush_interval_s: the longest a message waits in memory (see the module docstring).
    fsync: sync the file to disk after every chunk (power-cut safety, at a latency cost).
    overwrite: replace an existing file instead of raising :class:`SessionError`.
    auto_tf: :meth:`write_state` also writes ``/tf`` (world→palm, world→object).
    contact_markers: :meth:`write_contacts` also writes the ``contacts`` entity on ``/markers``.
    """

    def __init__(self, path: Path | str, *, metadata: Mapping[str, Any],
                 chunk_size: int = 256 * 1024, compression: str = "zstd",
                 record_view: bool = False, flush_interval_s: float = 0.5,
                 fsync: bool = False, overwrite: bool = False, auto_tf: bool = True,
                 contact_markers: bool = True, start_time_ns: int | None = None) -> None:
        if compression not in _COMPRESSION:
            raise ValueError(f"compression must be one of {sorted(_COMPRESSION)}, got "
                             f"{compression!r}")
        if chunk_size <= 0 or not flush_interval_s > 0:
            raise ValueError(f"chunk_size (bytes) and flush_interval_s (seconds) must be > 0, "
                             f"got {chunk_size} and {flush_interval_s}")
        self.path = Path(path)
        self.chunk_size = int(chunk_size)
        self.flush_interval_s = float(flush_interval_s)
        self._flush_interval_ns = int(flush_interval_s * 1e9)
        self.record_view = bool(record_view)
        self.fsync = bool(fsync)
        self.auto_tf = bool(auto_tf)
        self.contact_markers = bool(contact_markers)
        # recorder's own clock (Unix epoch) unless the caller brings one (replay, tests)
        self._own_clock = start_time_ns is None
        self.start_time_ns = time.time_ns() if start_time_ns is None else int(start_time_ns)
        self._last_log_ns = self.start_time_ns
        self.stats = RecorderStats()
        self.metadata = session_metadata(metadata, start_time_ns=self.start_time_ns,
                                         own_clock=self._own_clock)
        joint_names = self.metadata.get("joint_names")
        if joint_names is not None and (not isinstance(joint_names, list | tuple) or
                                        not all(isinstance(n, str) for n in joint_names)):
            raise ValueError("metadata['joint_names'] must be a list of joint name strings")
        self.joint_names: tuple[str, ...] | None = (tuple(joint_names) if joint_names is not None
                                                    else None)
        self.fingers: tuple[str, ...] = tuple(self.metadata.get("fingers", ()))
        self.current_object: str | None = self.metadata.get("object")
        metadata_record = encode_metadata(self.metadata)  # fails before the file exists
        self._lock = threading.RLock()
        self._closed = False
        self._pending_topics: Counter[str] = Counter()
        self._pending_bytes = 0
        self._chunk_open_mono = 0.0
        self._chunk_first_log_ns = 0

        self._out = SessionFile(self.path, overwrite=overwrite)
        # Chunk boundaries are ours (size and time): the SDK's size trigger is off, so every
        # chunk goes through flush(); its zstd runs in this thread (no compression threads)
        options = MCAPWriteOptions(compression=_COMPRESSION[compression], profile="",
                                   chunk_size=None, compression_threads=0)
        self._context = fx.Context()   # the recorder's own: no other sink sees its channels
        self._channels: dict[str, fx.Channel] = {}
        try:
            with self._out.guard():
                self._writer = fx.open_mcap(self._out, context=self._context,
                                            writer_options=options)
                for spec in schemas.CHANNELS:
                    if not spec.optional or (spec.topic == schemas.TOPIC_VIEW and self.record_view):
                        self._channels[spec.topic] = foxglove.sdk_channel(spec, self._context)
                self._writer.write_metadata(schemas.METADATA_NAME, metadata_record)
                self._out.flush()
            self._out.mark_good()
            self._write_event_unchecked("recording_started", {"path": str(self.path)},
                                        None, self.start_time_ns)
        except RecordingFailed:   # nothing recorded yet: leave no stub behind
            self._out.discard()
            raise SessionError(f"{self.path}: cannot write the recording: "
                               f"{self._out.reason}") from None
        log.info("recording %s (chunks ≤ %d B or %.2f s, %s)", self.path, self.chunk_size,
                 self.flush_interval_s, compression)

    # --- core -------------------------------------------------------------------------------------

    def _now(self, log_time_ns: int | None) -> int:
        if log_time_ns is None:
            return time.time_ns()
        t = int(log_time_ns)
        if not 0 <= t < 2**64:
            raise ValueError(f"log_time_ns must be in [0, 2**64) nanoseconds, got {log_time_ns}")
        return t

    def _t_s(self, t_s: float | None, log_time_ns: int) -> float:
        return (log_time_ns - self.start_time_ns) * 1e-9 if t_s is None else float(t_s)

    def _add(self, topic: str, data: bytes, log_time_ns: int) -> None:
        """Append one message (lock held by the caller) and apply the flush policy."""
        if self._out.failure:
            raise RecordingFailed(self._out.failure)
        if self._closed:
            raise SessionError(f"{self.path}: the recorder is closed")
        if not self._pending_topics:
            self._chunk_open_mono = time.monotonic()
            self._chunk_first_log_ns = log_time_ns
        with self._out.guard():   # the SDK may write compressed bytes of the open chunk now
            self._channels[topic].log(data, log_time=log_time_ns)
        self._pending_topics[topic] += 1
        self._pending_bytes += len(data) + _MESSAGE_OVERHEAD
        self.stats.written[topic] += 1
        self._last_log_ns = max(self._last_log_ns, log_time_ns)
        if (self._pending_bytes >= self.chunk_size
                or time.monotonic() - self._chunk_open_mono >= self.flush_interval_s
                or abs(log_time_ns - self._chunk_first_log_ns) >= self._flush_interval_ns):
            self._flush_locked()

    def _flush_locked(self) -> None:
        if not self._pending_topics:
            return
        t0 = time.perf_counter()
        with self._out.guard():
            self._writer.flush()  # ends the chunk, writes its message indexes, flushes
            if self.fsync:
                os.fsync(self._out.stream.fileno())
        self.stats.flush_time_s += time.perf_counter() - t0
        self.stats.chunks += 1
        self.stats.flushed.update(self._pending_topics)
        self.stats.bytes_on_disk = self._out.mark_good()
        self._pending_topics.clear()
        self._pending_bytes = 0

    def flush(self) -> None:
        """Write the chunk in progress now (a loop that goes idle calls this)."""
        with self._lock:
            if not self.closed:
                self._flush_locked()

    # --- channels ---------------------------------------------------------------------------------

    def write_hands(self, frame: hand_messages.HandFrame | bytes,
                    log_time_ns: int | None = None) -> None:
        """Raw input on ``/hands``: a :class:`HandFrame` (encoded, hence validated) or its wire
        bytes as received (decoded once to validate, then stored unchanged)."""
        if isinstance(frame, bytes | bytearray | memoryview):
            data = bytes(frame)
            hand_messages.decode(data)
        else:
            data = hand_messages.encode(frame)
        with self._lock:
            self._add(schemas.TOPIC_HANDS, data, self._now(log_time_ns))

    def write_state(self, qpos: Any, palm_pos_m: Any, palm_quat_wxyz: Any, object_pos_m: Any,
                    object_quat_wxyz: Any, *, t_s: float | None = None, seq: int | None = None,
                    tracked: bool = True, object_name: str | None = None,
                    extra: Mapping[str, Any] | None = None,
                    log_time_ns: int | None = None) -> None:
        """The bridge state on ``/state``: hand qpos (radians, order of ``joint_names``), palm
        and object poses in the world (metres, quaternions wxyz). With ``auto_tf`` the same
        poses go to ``/tf`` as world→palm and world→object."""
        with self._lock:
            t = self._now(log_time_ns)
            payload = schemas.state_payload(
                qpos, palm_pos_m, palm_quat_wxyz, object_pos_m, object_quat_wxyz,
                t_s=self._t_s(t_s, t), seq=seq, tracked=tracked,
                object_name=object_name if object_name is not None else self.current_object,
                extra=extra, joint_names=self.joint_names)
            self._add(schemas.TOPIC_STATE, schemas.dumps(payload), t)
            if self.auto_tf:
                self._add(schemas.TOPIC_TF, foxglove.frame_transforms(
                    [FrameTransform(schemas.FRAME_WORLD, schemas.FRAME_PALM, palm_pos_m,
                                    palm_quat_wxyz),
                     FrameTransform(schemas.FRAME_WORLD, schemas.FRAME_OBJECT, object_pos_m,
                                    object_quat_wxyz)], t).encode(), t)

    def write_contacts(self, contacts: Sequence[ContactRecord], *, t_s: float | None = None,
                       seq: int | None = None, object_name: str | None = None,
                       log_time_ns: int | None = None) -> None:
        """Hand–object contacts on ``/contacts`` (possibly none: an empty list records "no
        contact" explicitly); with ``contact_markers`` also the ``contacts`` entity on
        ``/markers`` (spheres coloured by finger, normal arrows scaled by force). ``t_s`` and
        ``seq`` are those of the ``/state`` of the same step: demo extraction pairs the two on
        them (module docstring)."""
        with self._lock:
            t = self._now(log_time_ns)
            payload = contacts_payload(
                contacts, t_s=self._t_s(t_s, t), seq=seq,
                object_name=object_name if object_name is not None else self.current_object)
            self._add(schemas.TOPIC_CONTACTS, schemas.dumps(payload), t)
            if self.contact_markers:
                entity = foxglove.contact_entity(contacts, t, fingers=self.fingers)
                self._add(schemas.TOPIC_MARKERS, foxglove.scene_update([entity]).encode(), t)

    def write_event(self, event_type: str, payload: Mapping[str, Any] | None = None, *,
                    t_s: float | None = None, log_time_ns: int | None = None) -> None:
        """An operator event on ``/events`` (``grasp_mark``, ``object_changed`` with payload
        ``{"object": name}``, ``object_reset``); written and flushed at once. The start/stop
        events are the recorder's own. ``object_changed`` also updates the object name that
        later ``/state`` and ``/contacts`` messages carry."""
        if event_type in _RECORDER_EVENTS:
            raise ValueError(f"{event_type!r} is written by the recorder itself (at open/close)")
        if event_type not in schemas.EVENT_TYPES:
            raise ValueError(f"unknown event type {event_type!r}; one of "
                             f"{[e for e in schemas.EVENT_TYPES if e not in _RECORDER_EVENTS]}")
        with self._lock:
            self._write_event_unchecked(event_type, payload, t_s, self._now(log_time_ns))
            if event_type == "object_changed" and payload and "object" in payload:
                self.current_object = str(payload["object"])

    def _write_event_unchecked(self, event_type: str, payload: Mapping[str, Any] | None,
                               t_s: float | None, t: int) -> None:
        body = {"type": event_type, "t_s": self._t_s(t_s, t),
                "payload": dict(payload) if payload else {}}
        self._add(schemas.TOPIC_EVENTS, schemas.dumps(body), t)
        self._flush_locked()

    def write_tf(self, transforms: Sequence[FrameTransform], log_time_ns: int | None = None
                 ) -> None:
        """Extra transforms on ``/tf`` (e.g. every hand body in the world, for a hand model in
        Foxglove), as ``foxglove.FrameTransforms``."""
        with self._lock:
            t = self._now(log_time_ns)
            self._add(schemas.TOPIC_TF, foxglove.frame_transforms(transforms, t).encode(), t)

    def write_markers(self, scene_update: fm.SceneUpdate, log_time_ns: int | None = None
                      ) -> None:
        """A ``foxglove.SceneUpdate`` on ``/markers`` (build it with :mod:`teleop.record.foxglove`:
        :func:`~teleop.record.foxglove.scene_update`, :func:`~teleop.record.foxglove.model` for the
        object mesh, :func:`~teleop.record.foxglove.hand_skeleton_entity` for the operator's
        hand)."""
        if not isinstance(scene_update, fm.SceneUpdate):
            raise ValueError("scene_update must be a foxglove.messages.SceneUpdate; see "
                             "teleop.record.foxglove.scene_update")
        with self._lock:
            self._add(schemas.TOPIC_MARKERS, scene_update.encode(), self._now(log_time_ns))

    def write_view(self, jpeg: bytes, log_time_ns: int | None = None, *,
                   frame_id: str = "view") -> bool:
        """A headset view frame on ``/view`` (JPEG bytes, ``foxglove.CompressedImage``). Returns
        False, writing nothing, when the recorder was opened with ``record_view=False``."""
        if not self.record_view:
            return False
        if not bytes(jpeg[:2]) == b"\xff\xd8":
            raise ValueError("write_view expects JPEG bytes (they start with FF D8)")
        with self._lock:
            t = self._now(log_time_ns)
            self._add(schemas.TOPIC_VIEW,
                      foxglove.compressed_image(bytes(jpeg), t, frame_id=frame_id).encode(), t)
        return True

    # --- lifecycle --------------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        return self._closed or self._out.failure is not None

    def close(self, *, reason: str = "closed") -> None:
        """Write ``recording_stopped``, the last chunk, the summary and footer; sync and close
        the file. Idempotent (a failed recording is closed already: nothing to do); raises
        :class:`RecordingFailed` when these last writes fail."""
        with self._lock:
            if self._closed or self._out.failure:
                return
            try:
                t = time.time_ns() if self._own_clock else self._last_log_ns
                self._write_event_unchecked("recording_stopped", {"reason": reason}, None, t)
                with self._out.guard():
                    self._writer.close()   # the last chunk, summary and footer; flushed
                    os.fsync(self._out.stream.fileno())
                self.stats.bytes_on_disk = self._out.stream.tell()
            finally:
                self._closed = True
                self._out.stream.close()
        log.info("recorded %s: %d messages, %d chunks, %d bytes", self.path,
                 sum(self.stats.written.values()), self.stats.chunks, self.stats.bytes_on_disk)

    def __enter__(self) -> SessionRecorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: object) -> None:
        self.close(reason="closed" if exc is None else f"exception: {type(exc).__name__}: {exc}")

