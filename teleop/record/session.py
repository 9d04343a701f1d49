"""Reading dexaug session recordings (MCAP), including ones whose recorder was killed.

Why our own scan instead of ``mcap.reader.make_reader``: the indexed reader needs the summary
that only a clean close writes, and the streaming reader neither reports byte offsets nor tells
a file that simply *ends early* (a killed recorder: expected, recoverable) from one that is
*damaged* (flipped bytes, garbage: must not be trusted). :func:`open_session` walks the file
record by record with mcap's own record parsers and classifies what it finds:

- **complete**: header … data end, summary, footer, closing magic; every CRC checks.
- **truncated**: the file stops early — mid-record, at a record boundary without a footer, or in
  a run of zero bytes (a file system that extended the file but lost the data). Everything up to
  the last complete chunk is read; :attr:`Session.truncated` is True, :attr:`Session.stop_offset`
  is the byte offset where reading stopped, and a ``logging`` warning says so. No exception.
- **corrupt**: a record that is all there but wrong — bad magic, unknown opcode, a length running
  past the end of a file that does have its footer, a chunk whose CRC, size, compression or time
  bounds do not check, a message index that disagrees with its chunk, a message on an unknown
  channel, a bad data-section or summary CRC. :class:`SessionError` is raised naming the file,
  the byte offset of the record at fault and what was wrong. A damaged recording is never read
  "as far as it goes": silent garbage in a dataset is worse than a loud error.

The recorder (:mod:`teleop.record.recorder`) writes data-section CRCs, chunk CRCs and message indexes,
so every byte of a complete file is covered by some check.

Messages are yielded in file order, which is the order the recorder wrote them (log times per
topic non-decreasing when the caller's clock is). Payloads are decoded by topic: ``/hands`` to
:class:`teleop.messages.HandFrame`, JSON topics to dicts, anything else left as bytes.
"""

from __future__ import annotations

import json
import logging
import os
import struct
import zlib
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    Message,
    MessageIndex,
    Metadata,
    Schema,
)
from mcap.stream_reader import get_chunk_data_stream

from sim.errors import DexaugError
from teleop import messages as hand_messages
from teleop.record import schemas

log = logging.getLogger(__name__)

MCAP_MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEADER = struct.Struct("<BQ")  # opcode, content length
_KNOWN_OPCODES = frozenset(int(op) for op in Opcode)
#: Refuse chunks claiming more than this uncompressed (a corrupt size field must not exhaust
#: memory); the recorder's chunks are a few hundred kB.
MAX_CHUNK_BYTES = 1 << 30


class SessionError(DexaugError):
    """A session recording cannot be read: not MCAP, damaged (the message names the byte
    offset), from a newer format, or written by something other than the session recorder."""


class _Short(Exception):
    """A record's content ended before its fields did."""


class _StrictBytes:
    """A byte buffer whose ``read(n)`` returns exactly n bytes or raises: mcap's parsers accept
    short reads silently, which would turn a damaged record into plausible garbage."""

    def __init__(self, data: bytes) -> None:
        self._data = memoryview(data)
        self._pos = 0

    def read(self, n: int) -> bytes:
        end = self._pos + n
        if n < 0 or end > len(self._data):
            raise _Short(f"needs {n} bytes at content offset {self._pos}, "
                         f"{len(self._data) - self._pos} left")
        out = bytes(self._data[self._pos:end])
        self._pos = end
        return out

    @property
    def remaining(self) -> int:
        return len(self._data) - self._pos


def _stream(data: bytes) -> tuple[ReadDataStream, _StrictBytes]:
    raw = _StrictBytes(data)
    return ReadDataStream(raw), raw  # type: ignore[arg-type]


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


@dataclass
class _Block:
    """Where messages live: a chunk record (offset of its record start) or a bare message."""

    offset: int
    length: int
    is_chunk: bool


@dataclass
class _Scan:
    header: Header | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    blocks: list[_Block] = field(default_factory=list)
    counts: Counter[int] = field(default_factory=Counter)
    start_ns: int | None = None
    end_ns: int | None = None
    truncated: bool = False
    stop_offset: int = 0
    truncation_reason: str = ""
    # per-chunk message index the chunk's content implies, checked against MessageIndex records
    pending_index: dict[int, list[tuple[int, int]]] | None = None
    pending_chunk_offset: int = 0


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

    def __init__(self, path: Path, scan: _Scan, file_size: int) -> None:
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
        self.all_metadata = {name: _decode_metadata(rec) for name, rec in scan.metadata.items()}
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
                _, length = _RECORD_HEADER.unpack_from(raw)
                content = raw[9:9 + length]
                try:
                    if block.is_chunk:
                        records = _chunk_messages(_decompress(Chunk.read(_stream(content)[0])))
                    else:
                        records = [(0, Message.read(_stream(content)[0], length))]
                except Exception as exc:
                    raise SessionError(f"{self.path}: record at offset {block.offset} changed "
                                       f"since the session was opened: {exc}") from None
                for _, msg in records:
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


def _decode_metadata(record: dict[str, str]) -> dict[str, Any]:
    json_keys = set()
    if schemas.JSON_KEYS_KEY in record:
        try:
            json_keys = set(json.loads(record[schemas.JSON_KEYS_KEY]))
        except ValueError:
            log.warning("metadata key %s is not a JSON list; values left as strings",
                        schemas.JSON_KEYS_KEY)
    out: dict[str, Any] = {}
    for key, value in record.items():
        if key == schemas.JSON_KEYS_KEY:
            continue
        if key in json_keys:
            try:
                out[key] = json.loads(value)
                continue
            except ValueError:
                log.warning("metadata %s is not valid JSON; kept as a string", key)
        out[key] = value
    return out


def _chunk_messages(data: bytes) -> list[tuple[int, Message]]:
    """The messages of an uncompressed chunk with their offsets inside it (schemas and
    channels are skipped: the scan already collected them)."""
    out = []
    pos, size = 0, len(data)
    while pos < size:
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        if opcode == Opcode.MESSAGE:
            out.append((pos, Message.read(_stream(data[pos + 9:pos + 9 + length])[0], length)))
        pos += 9 + length
    return out


class _Corrupt(Exception):
    def __init__(self, offset: int, reason: str) -> None:
        super().__init__(reason)
        self.offset = offset
        self.reason = reason


def _parse(offset: int, opcode: int, content: bytes) -> Any:
    """Parse one record's content with mcap's parser, strictly (all fields present, nothing
    left over except where the spec allows trailing fields)."""
    stream, raw = _stream(content)
    try:
        if opcode == Opcode.MESSAGE:
            return Message.read(stream, len(content))
        parser = {Opcode.HEADER: Header, Opcode.FOOTER: Footer, Opcode.SCHEMA: Schema,
                  Opcode.CHANNEL: Channel, Opcode.CHUNK: Chunk,
                  Opcode.MESSAGE_INDEX: MessageIndex, Opcode.METADATA: Metadata,
                  Opcode.DATA_END: DataEnd}.get(Opcode(opcode))
        if parser is None:
            return None  # index/summary records we do not need: skipped by length
        record = parser.read(stream)
    except (_Short, struct.error, UnicodeDecodeError, ValueError) as exc:
        raise _Corrupt(offset, f"malformed {Opcode(opcode).name} record: {exc}") from None
    if raw.remaining and opcode in (Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.FOOTER,
                                    Opcode.DATA_END):
        raise _Corrupt(offset, f"{Opcode(opcode).name} record has {raw.remaining} bytes past "
                               "its last field")
    return record


def _decompress(chunk: Chunk) -> bytes:
    """A chunk's uncompressed content, its CRC checked (mcap's own decompression)."""
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    return stream.read(size) if size else b""


def _scan_chunk(scan: _Scan, offset: int, chunk: Chunk) -> None:
    if chunk.compression not in ("", "zstd", "lz4"):
        raise _Corrupt(offset, f"chunk compression {chunk.compression!r} is not zstd/lz4/none")
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise _Corrupt(offset, f"chunk claims {chunk.uncompressed_size} uncompressed bytes")
    try:
        data = _decompress(chunk)
    except Exception as exc:  # zstd/lz4 errors, CRC mismatch: all mean damaged chunk data
        raise _Corrupt(offset, f"chunk data does not decompress or check: {exc}") from None
    if len(data) != chunk.uncompressed_size:
        raise _Corrupt(offset, f"chunk decompresses to {len(data)} bytes, its header says "
                               f"{chunk.uncompressed_size}")
    index: dict[int, list[tuple[int, int]]] = {}
    pos = 0
    while pos < len(data):
        if len(data) - pos < 9:
            raise _Corrupt(offset, f"chunk content ends inside a record header (content offset "
                                   f"{pos})")
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        end = pos + 9 + length
        if end > len(data):
            raise _Corrupt(offset, f"record at chunk content offset {pos} runs past the chunk")
        rec = _parse(offset, opcode, data[pos + 9:end]) if opcode in _KNOWN_OPCODES else None
        if isinstance(rec, Schema):
            _add_schema(scan, offset, rec)
        elif isinstance(rec, Channel):
            _add_channel(scan, offset, rec)
        elif isinstance(rec, Message):
            if not chunk.message_start_time <= rec.log_time <= chunk.message_end_time:
                raise _Corrupt(offset, f"message log time {rec.log_time} ns outside the chunk's "
                                       f"[{chunk.message_start_time}, {chunk.message_end_time}]")
            _count_message(scan, offset, rec)
            index.setdefault(rec.channel_id, []).append((rec.log_time, pos))
        else:
            raise _Corrupt(offset, f"unexpected record opcode {opcode:#04x} inside a chunk")
        pos = end
    scan.pending_index = index
    scan.pending_chunk_offset = offset


def _add_schema(scan: _Scan, offset: int, schema: Schema) -> None:
    old = scan.schemas.get(schema.id)
    if old is not None and old != schema:
        raise _Corrupt(offset, f"schema id {schema.id} redefined differently")
    scan.schemas[schema.id] = schema


def _add_channel(scan: _Scan, offset: int, channel: Channel) -> None:
    if channel.schema_id and channel.schema_id not in scan.schemas:
        raise _Corrupt(offset, f"channel {channel.topic!r} uses unknown schema id "
                               f"{channel.schema_id}")
    old = scan.channels.get(channel.id)
    if old is not None and old != channel:
        raise _Corrupt(offset, f"channel id {channel.id} redefined differently")
    scan.channels[channel.id] = channel


def _count_message(scan: _Scan, offset: int, msg: Message) -> None:
    if msg.channel_id not in scan.channels:
        raise _Corrupt(offset, f"message on unknown channel id {msg.channel_id}")
    scan.counts[msg.channel_id] += 1
    t = msg.log_time
    scan.start_ns = t if scan.start_ns is None else min(scan.start_ns, t)
    scan.end_ns = t if scan.end_ns is None else max(scan.end_ns, t)


def _check_message_index(scan: _Scan, offset: int, index: MessageIndex) -> None:
    if scan.pending_index is None:
        raise _Corrupt(offset, "message index without a preceding chunk")
    expected = scan.pending_index.get(index.channel_id)
    if expected is None or sorted(expected) != sorted(index.records):
        raise _Corrupt(offset, f"message index for channel {index.channel_id} disagrees with "
                               f"the chunk at offset {scan.pending_chunk_offset}")


def _ends_like_closed(f: IO[bytes], size: int) -> bool:
    """Does the file end with the closing magic (only a clean close writes it; a killed
    recorder's file ends in chunk data)? Then anything that looks like an early end — a record
    running past the end, no footer — is damage, not truncation."""
    if size < 16:
        return False
    f.seek(size - 8)
    return f.read(8) == MCAP_MAGIC


def _all_zero(f: IO[bytes], start: int, size: int) -> bool:
    f.seek(start)
    while start < size:
        block = f.read(min(1 << 20, size - start))
        if block.count(0) != len(block):
            return False
        start += len(block)
    return True


def _scan_file(f: IO[bytes], size: int) -> _Scan:
    scan = _Scan()
    f.seek(0)
    magic = f.read(8)
    if magic != MCAP_MAGIC:
        what = "empty file (0 bytes)" if size == 0 else f"magic {magic!r}"
        raise _Corrupt(0, f"not an MCAP file: {what}, expected {MCAP_MAGIC!r}")
    complete = _ends_like_closed(f, size)
    crc = zlib.crc32(MCAP_MAGIC)
    offset = 8
    in_summary = False
    summary_start = 0
    summary_crc = 0
    f.seek(offset)

    def truncate(reason: str) -> _Scan:
        scan.truncated = True
        scan.stop_offset = offset
        scan.truncation_reason = reason
        return scan

    while True:
        if offset == size:
            if complete:
                raise _Corrupt(offset, "no footer before the end of the file")
            return truncate("the file ends without a footer (the recorder did not close it)")
        head = f.read(9)
        if len(head) < 9:
            if complete:
                raise _Corrupt(offset, "record header runs past the end of the file")
            return truncate(f"the file ends inside a record header ({len(head)} of 9 bytes)")
        opcode, length = _RECORD_HEADER.unpack(head)
        if opcode == 0 and length == 0 and not complete and _all_zero(f, offset, size):
            return truncate(f"the last {size - offset} bytes are zeros (data never written)")
        if opcode not in _KNOWN_OPCODES:
            raise _Corrupt(offset, f"unknown record opcode {opcode:#04x}")
        if offset == 8 and opcode != Opcode.HEADER:
            raise _Corrupt(offset, f"first record is {Opcode(opcode).name}, expected HEADER")
        if length > size - offset - 9:
            if complete:
                raise _Corrupt(offset, f"{Opcode(opcode).name} record claims {length} bytes, "
                                       f"past the end of the file ({size} bytes)")
            return truncate(f"the {Opcode(opcode).name} record at the end is incomplete "
                            f"({size - offset - 9} of {length} bytes)")
        content = f.read(length)
        rec = _parse(offset, opcode, content)
        if opcode == Opcode.HEADER and offset != 8:
            raise _Corrupt(offset, "a second HEADER record")
        if opcode == Opcode.FOOTER:
            footer: Footer = rec
            if footer.summary_start not in (0, summary_start) or not in_summary:
                raise _Corrupt(offset, f"footer's summary start {footer.summary_start} does not "
                                       f"match the data end (summary at {summary_start})")
            summary_crc = zlib.crc32(head + content[:16], summary_crc)
            if footer.summary_crc and footer.summary_crc != summary_crc:
                raise _Corrupt(offset, f"summary CRC mismatch: footer says "
                                       f"{footer.summary_crc:#010x}, bytes give "
                                       f"{summary_crc:#010x} (summary at offset {summary_start})")
            end = offset + 9 + length
            f.seek(end)
            if f.read(8) != MCAP_MAGIC or end + 8 != size:
                raise _Corrupt(end, "footer not followed by the closing magic at the end of the "
                                    "file")
            scan.stop_offset = size
            return scan
        if in_summary:
            summary_crc = zlib.crc32(content, zlib.crc32(head, summary_crc))
        elif opcode == Opcode.DATA_END:
            data_end: DataEnd = rec
            if data_end.data_section_crc and data_end.data_section_crc != crc:
                raise _Corrupt(offset, f"data section CRC mismatch (bytes 0 to {offset}): the "
                                       f"file says {data_end.data_section_crc:#010x}, its bytes "
                                       f"give {crc:#010x}")
            in_summary = True
            summary_start = offset + 9 + length
        else:
            crc = zlib.crc32(content, zlib.crc32(head, crc))
            if isinstance(rec, Chunk):
                _scan_chunk(scan, offset, rec)
                scan.blocks.append(_Block(offset, 9 + length, is_chunk=True))
            elif isinstance(rec, MessageIndex):
                _check_message_index(scan, offset, rec)
            elif isinstance(rec, Header):
                scan.header = rec
            elif isinstance(rec, Schema):
                _add_schema(scan, offset, rec)
            elif isinstance(rec, Channel):
                _add_channel(scan, offset, rec)
            elif isinstance(rec, Message):
                _count_message(scan, offset, rec)
                scan.blocks.append(_Block(offset, 9 + length, is_chunk=False))
            elif isinstance(rec, Metadata):
                scan.metadata[rec.name] = dict(rec.metadata)
            if not isinstance(rec, Chunk | MessageIndex):
                scan.pending_index = None
        offset += 9 + length


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
            scan = _scan_file(f, size)
        except _Corrupt as exc:
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
