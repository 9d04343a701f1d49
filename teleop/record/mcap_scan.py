"""The validating MCAP scan under :mod:`teleop.record.session`: record by record, offsets kept.

Why our own scan instead of ``mcap.reader.make_reader``: the indexed reader needs the summary
that only a clean close writes, and the streaming reader neither reports byte offsets nor tells
a file that simply *ends early* (a killed recorder: expected, recoverable) from one that is
*damaged* (flipped bytes, garbage: must not be trusted). :func:`scan_file` walks the file
record by record with mcap's own record parsers and classifies what it finds:

- **complete**: header … data end, summary, footer, closing magic; every CRC checks.
- **truncated**: the file stops early — mid-record, at a record boundary without a footer, or in
  a run of zero bytes (a file system that extended the file but lost the data). Everything up to
  the last complete chunk is kept; :attr:`Scan.truncated` is True and :attr:`Scan.stop_offset`
  is the byte offset where reading stopped. No exception.
- **corrupt**: a record that is all there but wrong — bad magic, unknown opcode, a length running
  past the end of a file that does have its footer, a chunk whose CRC, size, compression or time
  bounds do not check, a message index that disagrees with its chunk, a message on an unknown
  channel, a bad data-section or summary CRC. :class:`McapCorrupt` is raised with the byte
  offset of the record at fault and what was wrong (the session reader names the file).

The scan keeps where the messages live (:class:`Block`: a chunk or a bare message record), so
:func:`block_messages` can re-read them later without scanning again. Only the MCAP layer is
here; what the channels mean is :mod:`teleop.record.schemas`'.
"""

from __future__ import annotations

import struct
import zlib
from collections import Counter
from dataclasses import dataclass, field
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

__all__ = ["MAX_CHUNK_BYTES", "MCAP_MAGIC", "Block", "McapCorrupt", "Scan", "block_messages",
           "scan_file"]

MCAP_MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEADER = struct.Struct("<BQ")  # opcode, content length
_KNOWN_OPCODES = frozenset(int(op) for op in Opcode)
#: Refuse chunks claiming more than this uncompressed (a corrupt size field must not exhaust
#: memory); the recorder's chunks are a few hundred kB.
MAX_CHUNK_BYTES = 1 << 30


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


class McapCorrupt(Exception):
    """A damaged record: ``offset`` (bytes) of the record at fault and the ``reason``."""

    def __init__(self, offset: int, reason: str) -> None:
        super().__init__(reason)
        self.offset = offset
        self.reason = reason


@dataclass
class Block:
    """Where messages live: a chunk record (offset of its record start) or a bare message."""

    offset: int
    length: int
    is_chunk: bool


@dataclass
class Scan:
    """What one pass over the file found: header, schemas, channels, metadata records, the
    message blocks, message counts per channel id, the log-time range (ns) and how it ended."""

    header: Header | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    blocks: list[Block] = field(default_factory=list)
    counts: Counter[int] = field(default_factory=Counter)
    start_ns: int | None = None
    end_ns: int | None = None
    truncated: bool = False
    stop_offset: int = 0
    truncation_reason: str = ""
    # per-chunk message index the chunk's content implies, checked against MessageIndex records
    pending_index: dict[int, list[tuple[int, int]]] | None = None
    pending_chunk_offset: int = 0


def block_messages(raw: bytes, is_chunk: bool) -> list[Message]:
    """The messages of one :class:`Block` from its record bytes (header included), in file
    order. Raises :class:`McapCorrupt` (offset 0: the caller knows the block's) when the bytes
    no longer parse."""
    _, length = _RECORD_HEADER.unpack_from(raw)
    content = raw[9:9 + length]
    try:
        if is_chunk:
            records = _chunk_messages(_decompress(Chunk.read(_stream(content)[0])))
        else:
            records = [(0, Message.read(_stream(content)[0], length))]
    except Exception as exc:
        raise McapCorrupt(0, str(exc)) from None
    return [msg for _, msg in records]


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
        raise McapCorrupt(offset, f"malformed {Opcode(opcode).name} record: {exc}") from None
    if raw.remaining and opcode in (Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.FOOTER,
                                    Opcode.DATA_END):
        raise McapCorrupt(offset, f"{Opcode(opcode).name} record has {raw.remaining} bytes past "
                               "its last field")
    return record


def _decompress(chunk: Chunk) -> bytes:
    """A chunk's uncompressed content, its CRC checked (mcap's own decompression)."""
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    return stream.read(size) if size else b""


def _scan_chunk(scan: Scan, offset: int, chunk: Chunk) -> None:
    if chunk.compression not in ("", "zstd", "lz4"):
        raise McapCorrupt(offset, f"chunk compression {chunk.compression!r} is not zstd/lz4/none")
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise McapCorrupt(offset, f"chunk claims {chunk.uncompressed_size} uncompressed bytes")
    try:
        data = _decompress(chunk)
    except Exception as exc:  # zstd/lz4 errors, CRC mismatch: all mean damaged chunk data
        raise McapCorrupt(offset, f"chunk data does not decompress or check: {exc}") from None
    if len(data) != chunk.uncompressed_size:
        raise McapCorrupt(offset, f"chunk decompresses to {len(data)} bytes, its header says "
                               f"{chunk.uncompressed_size}")
    index: dict[int, list[tuple[int, int]]] = {}
    pos = 0
    while pos < len(data):
        if len(data) - pos < 9:
            raise McapCorrupt(offset, f"chunk content ends inside a record header (content offset "
                                   f"{pos})")
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        end = pos + 9 + length
        if end > len(data):
            raise McapCorrupt(offset, f"record at chunk content offset {pos} runs past the chunk")
        rec = _parse(offset, opcode, data[pos + 9:end]) if opcode in _KNOWN_OPCODES else None
        if isinstance(rec, Schema):
            _add_schema(scan, offset, rec)
        elif isinstance(rec, Channel):
            _add_channel(scan, offset, rec)
        elif isinstance(rec, Message):
            if not chunk.message_start_time <= rec.log_time <= chunk.message_end_time:
                raise McapCorrupt(offset, f"message log time {rec.log_time} ns outside the chunk's "
                                       f"[{chunk.message_start_time}, {chunk.message_end_time}]")
            _count_message(scan, offset, rec)
            index.setdefault(rec.channel_id, []).append((rec.log_time, pos))
        else:
            raise McapCorrupt(offset, f"unexpected record opcode {opcode:#04x} inside a chunk")
        pos = end
    scan.pending_index = index
    scan.pending_chunk_offset = offset


def _add_schema(scan: Scan, offset: int, schema: Schema) -> None:
    old = scan.schemas.get(schema.id)
    if old is not None and old != schema:
        raise McapCorrupt(offset, f"schema id {schema.id} redefined differently")
    scan.schemas[schema.id] = schema


def _add_channel(scan: Scan, offset: int, channel: Channel) -> None:
    if channel.schema_id and channel.schema_id not in scan.schemas:
        raise McapCorrupt(offset, f"channel {channel.topic!r} uses unknown schema id "
                               f"{channel.schema_id}")
    old = scan.channels.get(channel.id)
    if old is not None and old != channel:
        raise McapCorrupt(offset, f"channel id {channel.id} redefined differently")
    scan.channels[channel.id] = channel


def _count_message(scan: Scan, offset: int, msg: Message) -> None:
    if msg.channel_id not in scan.channels:
        raise McapCorrupt(offset, f"message on unknown channel id {msg.channel_id}")
    scan.counts[msg.channel_id] += 1
    t = msg.log_time
    scan.start_ns = t if scan.start_ns is None else min(scan.start_ns, t)
    scan.end_ns = t if scan.end_ns is None else max(scan.end_ns, t)


def _check_message_index(scan: Scan, offset: int, index: MessageIndex) -> None:
    if scan.pending_index is None:
        raise McapCorrupt(offset, "message index without a preceding chunk")
    expected = scan.pending_index.get(index.channel_id)
    if expected is None or sorted(expected) != sorted(index.records):
        raise McapCorrupt(offset, f"message index for channel {index.channel_id} disagrees with "
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


def scan_file(f: IO[bytes], size: int) -> Scan:
    """Scan the open file ``f`` of ``size`` bytes (module docstring); raises
    :class:`McapCorrupt` on damage."""
    scan = Scan()
    f.seek(0)
    magic = f.read(8)
    if magic != MCAP_MAGIC:
        what = "empty file (0 bytes)" if size == 0 else f"magic {magic!r}"
        raise McapCorrupt(0, f"not an MCAP file: {what}, expected {MCAP_MAGIC!r}")
    complete = _ends_like_closed(f, size)
    crc = zlib.crc32(MCAP_MAGIC)
    offset = 8
    in_summary = False
    summary_start = 0
    summary_crc = 0
    f.seek(offset)

    def truncate(reason: str) -> Scan:
        scan.truncated = True
        scan.stop_offset = offset
        scan.truncation_reason = reason
        return scan

    while True:
        if offset == size:
            if complete:
                raise McapCorrupt(offset, "no footer before the end of the file")
            return truncate("the file ends without a footer (the recorder did not close it)")
        head = f.read(9)
        if len(head) < 9:
            if complete:
                raise McapCorrupt(offset, "record header runs past the end of the file")
            return truncate(f"the file ends inside a record header ({len(head)} of 9 bytes)")
        opcode, length = _RECORD_HEADER.unpack(head)
        if opcode == 0 and length == 0 and not complete and _all_zero(f, offset, size):
            return truncate(f"the last {size - offset} bytes are zeros (data never written)")
        if opcode not in _KNOWN_OPCODES:
            raise McapCorrupt(offset, f"unknown record opcode {opcode:#04x}")
        if offset == 8 and opcode != Opcode.HEADER:
            raise McapCorrupt(offset, f"first record is {Opcode(opcode).name}, expected HEADER")
        if length > size - offset - 9:
            if complete:
                raise McapCorrupt(offset, f"{Opcode(opcode).name} record claims {length} bytes, "
                                       f"past the end of the file ({size} bytes)")
            return truncate(f"the {Opcode(opcode).name} record at the end is incomplete "
                            f"({size - offset - 9} of {length} bytes)")
        content = f.read(length)
        rec = _parse(offset, opcode, content)
        if opcode == Opcode.HEADER and offset != 8:
            raise McapCorrupt(offset, "a second HEADER record")
        if opcode == Opcode.FOOTER:
            footer: Footer = rec
            if footer.summary_start not in (0, summary_start) or not in_summary:
                raise McapCorrupt(offset, f"footer's summary start {footer.summary_start} does not "
                                       f"match the data end (summary at {summary_start})")
            summary_crc = zlib.crc32(head + content[:16], summary_crc)
            if footer.summary_crc and footer.summary_crc != summary_crc:
                raise McapCorrupt(offset, f"summary CRC mismatch: footer says "
                                       f"{footer.summary_crc:#010x}, bytes give "
                                       f"{summary_crc:#010x} (summary at offset {summary_start})")
            end = offset + 9 + length
            f.seek(end)
            if f.read(8) != MCAP_MAGIC or end + 8 != size:
                raise McapCorrupt(end, "footer not followed by the closing magic at the end of the "
                                    "file")
            scan.stop_offset = size
            return scan
        if in_summary:
            summary_crc = zlib.crc32(content, zlib.crc32(head, summary_crc))
        elif opcode == Opcode.DATA_END:
            data_end: DataEnd = rec
            if data_end.data_section_crc and data_end.data_section_crc != crc:
                raise McapCorrupt(offset, f"data section CRC mismatch (bytes 0 to {offset}): the "
                                       f"file says {data_end.data_section_crc:#010x}, its bytes "
                                       f"give {crc:#010x}")
            in_summary = True
            summary_start = offset + 9 + length
        else:
            crc = zlib.crc32(content, zlib.crc32(head, crc))
            if isinstance(rec, Chunk):
                _scan_chunk(scan, offset, rec)
                scan.blocks.append(Block(offset, 9 + length, is_chunk=True))
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
                scan.blocks.append(Block(offset, 9 + length, is_chunk=False))
            elif isinstance(rec, Metadata):
                scan.metadata[rec.name] = dict(rec.metadata)
            if not isinstance(rec, Chunk | MessageIndex):
                scan.pending_index = None
        offset += 9 + length


