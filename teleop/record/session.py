"""Reading dexaug session recordings (MCAP), including ones whose recorder was killed.

:func:`open_session` validates the whole file with one scan (:mod:`teleop.record.mcap_scan`:
complete, truncated or corrupt) and returns a :class:`Session`: metadata, channels, message
counts and time range, with the messages re-read from disk on demand.

- a **complete** file reads in full;
- a **truncated** one (the recorder was killed) reads up to its last complete chunk:
  :attr:`Session.truncated` is True, :attr:`Session.stop_offset` is the byte offset where
  reading stopped, and a ``logging`` warning says so. No exception;
- a **corrupt** one raises :class:`SessionError` naming the file, the byte offset of the record
  at fault and what was wrong. A damaged recording is never read "as far as it goes": silent
  garbage in a dataset is worse than a loud error.

The recorder (:mod:`teleop.record.recorder`) writes data-section CRCs, chunk CRCs and message indexes,
so every byte of a complete file is covered by some check.

Messages are yielded in file order, which is the order the recorder wrote them (log times per
topic non-decreasing when the caller's clock is). Payloads are decoded by topic: ``/hands`` to
:class:`teleop.messages.HandFrame`, JSON topics to dicts, anything else left as bytes.
:func:`repair_session` rewrites a truncated file as a complete, indexed one.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sim.errors import DexaugError
from teleop import messages as hand_messages
from teleop.record import schemas
from teleop.record.mcap_scan import McapCorrupt, Scan, block_messages, scan_file
from teleop.record.metadata import decode_metadata

__all__ = ["ChannelInfo", "Session", "SessionError", "SessionMessage", "open_session",
           "repair_session"]

log = logging.getLogger(__name__)


class SessionError(DexaugError):
    """A session recording cannot be read: not MCAP, damaged (the message names the byte
    offset), from a newer format, or written by something other than the session recorder."""


@dataclass(frozen=True)
class ChannelInfo:
    """A channel of the recording with its schema."""

    id: int
    topic: str
    message_encoding: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes = field(repr=False)
    metadata: dict[str, str]


@dataclass(frozen=True)
class SessionMessage:
    """One message: MCAP times in nanoseconds, raw bytes and the decoded payload."""

    topic: str
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    data: bytes = field(repr=False)
    payload: Any = field(repr=False)


class Session:
    """A readable recording: metadata, channels, counts and time range from one validating scan;
    messages are re-read from disk on each :meth:`messages` call (a session can be large).

    Attributes: ``path``; ``metadata`` (the ``dexaug.session`` record, JSON values decoded);
    ``channels`` (topic → :class:`ChannelInfo`); ``counts`` (topic → messages); ``start_time_ns``
    / ``end_time_ns`` (log times, None when empty); ``truncated`` (the recorder did not close
    the file); ``stop_offset`` (byte offset where reading stopped: the file size when complete,
    else the start of the first incomplete record); ``file_size`` (bytes); ``library`` and
    ``profile`` (the MCAP header's).
    """

    def __init__(self, path: Path, scan: Scan, file_size: int) -> None:
        self.path = path
        self._scan = scan
        self.file_size = file_size
        self.truncated = scan.truncated
        self.stop_offset = scan.stop_offset
        self.library = scan.header.library if scan.header else ""
        self.profile = scan.header.profile if scan.header else ""
        self.channels: dict[str, ChannelInfo] = {}
        self._topic_by_id: dict[int, str] = {}
        for cid, ch in scan.channels.items():
            schema = scan.schemas.get(ch.schema_id)
            self.channels[ch.topic] = ChannelInfo(
                id=cid, topic=ch.topic, message_encoding=ch.message_encoding,
                schema_name=schema.name if schema else "",
                schema_encoding=schema.encoding if schema else "",
                schema_data=schema.data if schema else b"", metadata=dict(ch.metadata))
            self._topic_by_id[cid] = ch.topic
        self.counts: dict[str, int] = {self._topic_by_id[c]: n for c, n in scan.counts.items()}
        for topic in self.channels:
            self.counts.setdefault(topic, 0)
        self.start_time_ns = scan.start_ns
        self.end_time_ns = scan.end_ns
        self.all_metadata = {name: decode_metadata(rec) for name, rec in scan.metadata.items()}
        self.metadata: dict[str, Any] = self.all_metadata.get(schemas.METADATA_NAME, {})

    def __repr__(self) -> str:
        state = f"truncated at offset {self.stop_offset}" if self.truncated else "complete"
        return (f"Session({str(self.path)!r}, {sum(self.counts.values())} messages, "
                f"{self.duration_s:.3f} s, {state})")

    @property
    def duration_s(self) -> float:
        """Seconds between the first and last message log times (0 when empty)."""
        if self.start_time_ns is None or self.end_time_ns is None:
            return 0.0
        return (self.end_time_ns - self.start_time_ns) * 1e-9

    @property
    def joint_names(self) -> list[str]:
        """The hand's joint names, the order of ``/state`` qpos (empty when not recorded)."""
        return list(self.metadata.get("joint_names", []))

    def messages(self, topics: str | Iterable[str] | None = None, *,
                 decode: bool = True) -> Iterator[SessionMessage]:
        """Messages of ``topics`` (all when None) in file order, payloads decoded by topic
        (``decode=False`` leaves ``payload`` None: faster when only times or bytes matter)."""
        wanted: set[int] | None = None
        if topics is not None:
            names = {topics} if isinstance(topics, str) else set(topics)
            wanted = {cid for cid, t in self._topic_by_id.items() if t in names}
        with open(self.path, "rb") as f:
            for block in self._scan.blocks:
                f.seek(block.offset)
                raw = f.read(block.length)
                try:
                    records = block_messages(raw, block.is_chunk)
                except McapCorrupt as exc:
                    raise SessionError(f"{self.path}: record at offset {block.offset} changed "
                                       f"since the session was opened: {exc}") from None
                for msg in records:
                    if wanted is not None and msg.channel_id not in wanted:
                        continue
                    topic = self._topic_by_id[msg.channel_id]
                    payload = self._decode(topic, msg.data, block.offset) if decode else None
                    yield SessionMessage(topic, msg.log_time, msg.publish_time, msg.sequence,
                                         msg.data, payload)

    def _decode(self, topic: str, data: bytes, offset: int) -> Any:
        channel = self.channels[topic]
        try:
            if channel.message_encoding == schemas.HANDS_MESSAGE_ENCODING:
                return hand_messages.decode(data)
            if channel.message_encoding == "json":
                return json.loads(data)
        except (hand_messages.MessageError, ValueError) as exc:
            raise SessionError(f"{self.path}: undecodable {topic} message in the chunk at offset "
                               f"{offset}: {exc}") from None
        return data

    def hands(self) -> Iterator[tuple[int, hand_messages.HandFrame]]:
        """(log time ns, HandFrame) of every ``/hands`` message."""
        for m in self.messages(schemas.TOPIC_HANDS):
            yield m.log_time_ns, m.payload

    def json_messages(self, topic: str) -> list[tuple[int, dict[str, Any]]]:
        """(log time ns, decoded JSON) of every message on a JSON topic."""
        if topic not in schemas.JSON_TOPICS:
            raise ValueError(f"{topic} is not a JSON topic (one of {sorted(schemas.JSON_TOPICS)})")
        return [(m.log_time_ns, m.payload) for m in self.messages(topic)]

    def events(self) -> list[tuple[int, dict[str, Any]]]:
        """(log time ns, event) of every ``/events`` message."""
        return self.json_messages(schemas.TOPIC_EVENTS)


def open_session(path: Path | str) -> Session:
    """Open a recording, validating it completely (see the module docstring).

    Returns a :class:`Session`; a truncated file (killed recorder) gives ``truncated=True`` and a
    warning, never an exception. Raises :class:`SessionError` naming the file and the byte offset
    when the file is not MCAP or is damaged, and when it was written by a newer dexaug format.
    """
    path = Path(path)
    try:
        f = open(path, "rb")  # noqa: SIM115  # closed below, scan needs the handle throughout
    except OSError as exc:
        raise SessionError(f"{path}: cannot open the session file: {exc.strerror}") from None
    with f:
        size = os.fstat(f.fileno()).st_size
        try:
            scan = scan_file(f, size)
        except McapCorrupt as exc:
            raise SessionError(f"{path}: corrupt MCAP session at offset {exc.offset} "
                               f"(file size {size} bytes): {exc.reason}") from None
    session = Session(path, scan, size)
    version = session.metadata.get("format_version")
    if scan.metadata and schemas.METADATA_NAME not in scan.metadata:
        log.warning("%s: no %s metadata record: not written by the dexaug recorder?", path,
                    schemas.METADATA_NAME)
    if version is not None and int(version) > schemas.FORMAT_VERSION:
        raise SessionError(f"{path}: recorded with session format {version}, this dexaug reads "
                           f"format {schemas.FORMAT_VERSION} and older; upgrade dexaug")
    if scan.truncated:
        log.warning("%s: recording truncated at byte offset %d of %d (%s); read %d messages up "
                    "to the last complete chunk", path, scan.stop_offset, size,
                    scan.truncation_reason, sum(scan.counts.values()))
    return session


def repair_session(src: Path | str, dst: Path | str) -> Session:
    """Rewrite the readable part of a (truncated) recording as a complete, indexed MCAP file at
    ``dst`` (tools that need the summary, e.g. seeking in Foxglove, then work on it). Raises
    :class:`SessionError` when ``src`` is damaged rather than truncated."""
    from mcap.writer import CompressionType, Writer

    from sim.io import atomic_path

    session = open_session(src)
    with atomic_path(dst) as tmp, open(tmp, "wb") as out:
        writer = Writer(out, compression=CompressionType.ZSTD, enable_data_crcs=True)
        writer.start(profile=session.profile, library=session.library)
        schema_ids = {}
        for sid, schema in session._scan.schemas.items():
            schema_ids[sid] = writer.register_schema(schema.name, schema.encoding, schema.data)
        channel_ids = {}
        for topic, ch in session.channels.items():
            raw = session._scan.channels[ch.id]
            channel_ids[topic] = writer.register_channel(
                topic, ch.message_encoding, schema_ids.get(raw.schema_id, 0), ch.metadata)
        for name, record in session._scan.metadata.items():
            writer.add_metadata(name, record)
        for m in session.messages(decode=False):
            writer.add_message(channel_ids[m.topic], m.log_time_ns, m.data, m.publish_time_ns,
                               m.sequence)
        writer.finish()
    return open_session(dst)
