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
:class:`teleop.messages.HandFrame`, JSON topics to dicts, protobuf ones (the ``foxglove.*``
channels since format 2) to dicts of the same JSON form with the schema stored in the file
(:mod:`teleop.record.protobuf_payload`), anything else left as bytes. A
``/state``, ``/contacts`` or ``/events`` payload that lacks a field its schema requires (or has
a vector of the wrong length) raises :class:`SessionError` naming the message and the field, so
consumers never meet a ``KeyError`` deep inside (``t_s`` may be absent: older recordings did not
write it). :func:`repair_session` rewrites a truncated file as a complete, indexed one;
:mod:`teleop.record.repair` (``dexaug repair``) also salvages around damage.
"""

from __future__ import annotations

import json
import logging
import os
import struct
from collections import Counter
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.opcode import Opcode
from mcap.records import Chunk, Message

from sim.errors import DexaugError
from teleop import messages as hand_messages
from teleop.record import protobuf_payload, schemas
from teleop.record.mcap_scan import McapCorrupt, Scan, decompress_chunk, record_stream, scan_file
from teleop.record.metadata import decode_metadata

__all__ = ["ChannelInfo", "Session", "SessionError", "SessionMessage", "block_messages",
           "open_session", "repair_session", "scan_found", "write_indexed_copy"]

log = logging.getLogger(__name__)

RECORD_HEADER = struct.Struct("<BQ")  # opcode, content length


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
    ``profile`` (the MCAP header's); ``truncation_reason`` (how the file ends, when truncated).
    """

    def __init__(self, path: Path, scan: Scan, file_size: int) -> None:
        self.path = path
        self._scan = scan
        self.file_size = file_size
        self.truncated = scan.truncated
        self.stop_offset = scan.stop_offset
        self.truncation_reason = scan.truncation_reason
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
        # the SDK's writer stores a channel with its first message: a topic of the layout that
        # never had one counts 0, as in files that registered every channel upfront
        for topic in [*self.channels, *(c.topic for c in schemas.CHANNELS if not c.optional)]:
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
    def cut_note(self) -> str:
        """Where a truncated file was cut and what was read before it, for messages ("" when
        complete): ``"truncated at byte 1234 of 5000 (the CHUNK record at the end is incomplete
        (100 of 300 bytes)); 5 complete records (2 chunks, 40 messages) were read before the
        cut"``."""
        if not self.truncated:
            return ""
        return (f"truncated at byte {self.stop_offset} of {self.file_size} "
                f"({self.truncation_reason}); {scan_found(self._scan)} were read before the cut")

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
        index: Counter[str] = Counter()
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
                    index[topic] += 1
                    payload = None
                    if decode:
                        payload = self._decode(topic, msg.data, block.offset)
                        self._check_fields(topic, payload, index[topic], msg.log_time)
                    yield SessionMessage(topic, msg.log_time, msg.publish_time, msg.sequence,
                                         msg.data, payload)

    def _decode(self, topic: str, data: bytes, offset: int) -> Any:
        channel = self.channels[topic]
        try:
            if channel.message_encoding == schemas.HANDS_MESSAGE_ENCODING:
                return hand_messages.decode(data)
            if channel.message_encoding == "json":
                return json.loads(data)
            if channel.message_encoding == "protobuf" and channel.schema_encoding == "protobuf":
                return protobuf_payload.to_json_form(protobuf_payload.decode(
                    channel.schema_name, channel.schema_data, data))
        except (hand_messages.MessageError, ValueError) as exc:
            raise SessionError(f"{self.path}: undecodable {topic} message in the chunk at offset "
                               f"{offset}: {exc}") from None
        return data

    def _check_fields(self, topic: str, payload: Any, number: int, log_time_ns: int) -> None:
        """Raise :class:`SessionError` when a payload of one of our schemas lacks what its
        schema requires (module docstring); ``number`` counts the topic's messages from 1."""
        schema = _REQUIRED_SCHEMAS.get(topic)
        if schema is None:
            return
        problem = _schema_problem(schema, payload, "")
        if problem is not None:
            at_s = (log_time_ns - (self.start_time_ns or log_time_ns)) * 1e-9
            raise SessionError(f"{self.path}: {topic} message {number} (at {at_s:.3f} s) "
                               f"{problem} (schema {schema.get('title', topic)})")

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


def block_messages(raw: bytes, is_chunk: bool) -> list[Message]:
    """The messages of one :class:`Block` from its record bytes (header included), in file
    order. Raises :class:`McapCorrupt` (offset 0: the caller knows the block's) when the bytes
    no longer parse."""
    _, length = RECORD_HEADER.unpack_from(raw)
    content = raw[9:9 + length]
    try:
        if is_chunk:
            records = _chunk_messages(decompress_chunk(Chunk.read(record_stream(content)[0])))
        else:
            records = [(0, Message.read(record_stream(content)[0], length))]
    except Exception as exc:
        raise McapCorrupt(0, str(exc)) from None
    return [msg for _, msg in records]


def _chunk_messages(data: bytes) -> list[tuple[int, Message]]:
    """The messages of an uncompressed chunk with their offsets inside it (schemas and
    channels are skipped: the scan already collected them)."""
    out = []
    pos, size = 0, len(data)
    while pos < size:
        opcode, length = RECORD_HEADER.unpack_from(data, pos)
        if opcode == Opcode.MESSAGE:
            out.append((pos, Message.read(record_stream(data[pos + 9:pos + 9 + length])[0], length)))
        pos += 9 + length
    return out



def scan_found(scan: Scan) -> str:
    """What a scan read, for messages: ``"12 complete records (3 chunks, 250 messages)"``."""
    def count(n: int, noun: str) -> str:
        return f"{n} {noun}" + ("" if n == 1 else "s")

    chunks = sum(b.is_chunk for b in scan.blocks)
    return (f"{count(scan.records, 'complete record')} ({count(chunks, 'chunk')}, "
            f"{count(sum(scan.counts.values()), 'message')})")


#: The payload schemas checked on decoding (ours; Foxglove's require nothing).
_REQUIRED_SCHEMAS: dict[str, dict[str, Any]] = {
    schemas.TOPIC_STATE: schemas.STATE_SCHEMA, schemas.TOPIC_CONTACTS: schemas.CONTACTS_SCHEMA,
    schemas.TOPIC_EVENTS: schemas.EVENT_SCHEMA}
#: Required by the schemas but absent from recordings made before they were written.
_OPTIONAL_IN_OLD_FILES = frozenset({"t_s"})


def _schema_problem(schema: dict[str, Any], value: Any, where: str) -> str | None:
    """What ``value`` lacks of ``schema`` (required keys, array lengths, recursively through
    objects and array items), or None. The subset of JSON Schema our schemas use."""
    kind = schema.get("type")
    if value is None:
        return None if isinstance(kind, list) and "null" in kind else f"has {where!r} = null"
    if kind == "object":
        if not isinstance(value, dict):
            return f"has {where or 'a payload'} that is {type(value).__name__}, not an object"
        for key in schema.get("required", ()):
            if key not in value and key not in _OPTIONAL_IN_OLD_FILES:
                return f"has no {where + key!r} field"
        for key, sub in schema.get("properties", {}).items():
            if key in value:
                problem = _schema_problem(sub, value[key], f"{where}{key}")
                if problem is not None:
                    return problem
    elif kind == "array":
        if not isinstance(value, list):
            return f"has {where!r} that is {type(value).__name__}, not a list"
        lo, hi = schema.get("minItems", 0), schema.get("maxItems", len(value))
        if not lo <= len(value) <= hi:
            want = lo if lo == hi else f"{lo} to {hi}"
            return f"has {where!r} with {len(value)} values, expected {want}"
        items = schema.get("items", {})
        if items.get("type") == "object":
            for i, item in enumerate(value):
                problem = _schema_problem(items, item, f"{where}[{i}].")
                if problem is not None:
                    return problem
    return None


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
        log.warning("%s: recording truncated at byte offset %d of %d (%s); read %s up to the "
                    "cut", path, scan.stop_offset, size, scan.truncation_reason, scan_found(scan))
    return session


def write_indexed_copy(out: Path, src: Path, scan: Scan,
                       extra_metadata: Mapping[str, Mapping[str, str]] | None = None
                       ) -> Counter[str]:
    """Write what ``scan`` found in ``src`` — header, schemas, channels, metadata records (plus
    ``extra_metadata``) and every message of its blocks, in file order — to ``out`` as a
    closed, indexed MCAP file; returns the messages written per topic. Raises
    :class:`SessionError` when a block no longer reads as scanned."""
    from mcap.writer import CompressionType, Writer

    written: Counter[str] = Counter()
    with open(src, "rb") as f_in, open(out, "wb") as f_out:
        writer = Writer(f_out, compression=CompressionType.ZSTD, enable_data_crcs=True)
        header = scan.header
        writer.start(profile=header.profile if header else "",
                     library=header.library if header else "dexaug")
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data)
                      for sid, s in scan.schemas.items()}
        channel_ids = {cid: writer.register_channel(c.topic, c.message_encoding,
                                                    schema_ids.get(c.schema_id, 0),
                                                    dict(c.metadata))
                       for cid, c in scan.channels.items()}
        for name, record in {**scan.metadata, **(extra_metadata or {})}.items():
            writer.add_metadata(name, dict(record))
        for block in scan.blocks:
            f_in.seek(block.offset)
            try:
                messages = block_messages(f_in.read(block.length), block.is_chunk)
            except McapCorrupt as exc:
                raise SessionError(f"{src}: the record at byte {block.offset} changed since it "
                                   f"was read: {exc.reason}") from None
            for msg in messages:
                writer.add_message(channel_ids[msg.channel_id], msg.log_time, msg.data,
                                   msg.publish_time, msg.sequence)
                written[scan.channels[msg.channel_id].topic] += 1
        writer.finish()
    return written


def repair_session(src: Path | str, dst: Path | str) -> Session:
    """Rewrite a truncated recording as a complete, indexed MCAP file at ``dst`` (tools that
    need the summary, e.g. seeking in Foxglove, then work on it) and open it. Raises
    :class:`SessionError` when ``src`` is damaged rather than truncated: salvaging around
    damage is :func:`teleop.record.repair.repair` (``dexaug repair``)."""
    from sim.io import atomic_path

    session = open_session(src)
    with atomic_path(dst) as tmp:
        write_indexed_copy(tmp, session.path, session._scan)
    return open_session(dst)
