"""The validating MCAP scan under :mod:`teleop.record.session`: record by record, offsets kept.

Why our own scan instead of ``mcap.reader.make_reader``: the indexed reader needs the summary
that only a clean close writes, and the streaming reader neither reports byte offsets nor tells
a file that simply *ends early* (a killed recorder: expected, recoverable) from one that is
*damaged* (flipped bytes, garbage: must not be trusted). :func:`scan_file` walks the file
record by record with mcap's own record parsers and classifies what it finds:

- **complete**: header … data end, summary, footer, closing magic; every CRC checks.
- **truncated**: the file stops early — mid-record, at a record boundary without a footer, in
  a run of zero bytes (a file system that extended the file but lost the data), or inside the
  closing magic (a cut in the last 1–8 bytes: every record is there). Everything up to the last
  complete chunk is kept; :attr:`Scan.truncated` is True and :attr:`Scan.stop_offset` is the
  byte offset where reading stopped. No exception.
- **corrupt**: a record that is all there but wrong — bad magic, unknown opcode, a length running
  past the end of a file that does have its footer, a chunk whose CRC, size, compression or time
  bounds do not check, a message index that disagrees with its chunk, a message on an unknown
  channel, a bad data-section or summary CRC. :class:`McapCorrupt` is raised with the byte
  offset of the record at fault and what was wrong (the session reader names the file).

:func:`start_scan` and :func:`read_record` are the scan's steps, for
:mod:`teleop.record.repair`'s salvage scan, which skips damage instead of raising.

The scan keeps where the messages live (:class:`Block`: a chunk or a bare message record), so
the session reader can re-read them later without scanning again. Only the MCAP layer is
here; what the channels mean is :mod:`teleop.record.schemas`'.
"""

from __future__ import annotations

import struct
import zlib
from collections import Counter
from collections.abc import Callable
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
    McapRecord,
    Message,
    MessageIndex,
    Metadata,
    Schema,
)
from mcap.stream_reader import get_chunk_data_stream

__all__ = ["MAX_CHUNK_BYTES", "MCAP_MAGIC", "Block", "FileEndsEarly", "McapCorrupt", "Scan",
           "Walk", "decompress_chunk", "parse_record", "read_record", "record_stream", "scan_file",
           "start_scan"]

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


def record_stream(data: bytes) -> tuple[ReadDataStream, _StrictBytes]:
    """An mcap parser stream over ``data`` that fails on short reads, and its buffer."""
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
    #: complete records read at the top level of the file (chunks count as one)
    records: int = 0
    # per-chunk message index the chunk's content implies, checked against MessageIndex records
    pending_index: dict[int, list[tuple[int, int]]] | None = None
    pending_chunk_offset: int = 0


def parse_record(offset: int, opcode: int, content: bytes) -> Any:
    """Parse one record's content with mcap's parser, strictly (all fields present, nothing
    left over except where the spec allows trailing fields)."""
    stream, raw = record_stream(content)
    try:
        if opcode == Opcode.MESSAGE:
            return Message.read(stream, len(content))
        parsers: dict[Opcode, Callable[[ReadDataStream], McapRecord]] = {
            Opcode.HEADER: Header.read, Opcode.FOOTER: Footer.read, Opcode.SCHEMA: Schema.read,
            Opcode.CHANNEL: Channel.read, Opcode.CHUNK: Chunk.read,
            Opcode.MESSAGE_INDEX: MessageIndex.read, Opcode.METADATA: Metadata.read,
            Opcode.DATA_END: DataEnd.read}
        parse = parsers.get(Opcode(opcode))
        if parse is None:
            return None  # index/summary records we do not need: skipped by length
        record = parse(stream)
    except (_Short, struct.error, UnicodeDecodeError, ValueError) as exc:
        raise McapCorrupt(offset, f"malformed {Opcode(opcode).name} record: {exc}") from None
    if raw.remaining and opcode in (Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.FOOTER,
                                    Opcode.DATA_END):
        raise McapCorrupt(offset, f"{Opcode(opcode).name} record has {raw.remaining} bytes past "
                               "its last field")
    return record


def decompress_chunk(chunk: Chunk) -> bytes:
    """A chunk's uncompressed content, its CRC checked (mcap's own decompression)."""
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    return stream.read(size) if size else b""


def _scan_chunk(scan: Scan, offset: int, chunk: Chunk) -> None:
    if chunk.compression not in ("", "zstd", "lz4"):
        raise McapCorrupt(offset, f"chunk compression {chunk.compression!r} is not zstd/lz4/none")
    if chunk.uncompressed_size > MAX_CHUNK_BYTES:
        raise McapCorrupt(offset, f"chunk claims {chunk.uncompressed_size} uncompressed bytes")
    try:
        data = decompress_chunk(chunk)
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
        rec = parse_record(offset, opcode, data[pos + 9:end]) if opcode in _KNOWN_OPCODES else None
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


class FileEndsEarly(Exception):
    """The file ends early (truncation): ``reason`` says how; ``past_end``: a record's length
    runs past the end (a damaged length field looks the same: a salvage scan reads on)."""

    def __init__(self, reason: str, *, past_end: bool = False) -> None:
        super().__init__(reason)
        self.reason = reason
        self.past_end = past_end


@dataclass
class Walk:
    """A scan's position and running CRCs (a salvage scan past damage sets check_data_crc)."""

    f: IO[bytes]
    size: int
    complete: bool
    offset: int = 8
    crc: int = zlib.crc32(MCAP_MAGIC)
    check_data_crc: bool = True
    in_summary: bool = False
    summary_start: int = 0
    summary_crc: int = 0


def start_scan(f: IO[bytes], size: int) -> tuple[Scan, Walk]:
    """An empty :class:`Scan`, a :class:`Walk` at the first record; checks the magic."""
    f.seek(0)
    magic = f.read(8)
    if magic != MCAP_MAGIC:
        what = "empty file (0 bytes)" if size == 0 else f"magic {magic!r}"
        raise McapCorrupt(0, f"not an MCAP file: {what}, expected {MCAP_MAGIC!r}")
    return Scan(), Walk(f, size, _ends_like_closed(f, size))


def scan_file(f: IO[bytes], size: int) -> Scan:
    """Scan the open file ``f`` of ``size`` bytes (module docstring); McapCorrupt on damage."""
    scan, walk = start_scan(f, size)
    try:
        while read_record(scan, walk):
            pass
    except FileEndsEarly as stop:
        scan.truncated = True
        scan.truncation_reason = stop.reason
    scan.stop_offset = walk.offset
    return scan


def read_record(scan: Scan, walk: Walk) -> bool:
    """Read the record at ``walk.offset`` into ``scan`` and advance; False when the file has
    been read to its end (footer and closing magic). Raises :class:`FileEndsEarly` when the
    file ends early, :class:`McapCorrupt` on damage (``walk.offset`` is then the record's)."""
    f, size, offset, complete = walk.f, walk.size, walk.offset, walk.complete
    if offset == size:
        if complete:
            raise McapCorrupt(offset, "no footer before the end of the file")
        raise FileEndsEarly("the file ends without a footer (the recorder did not close it)")
    f.seek(offset)
    head = f.read(9)
    if len(head) < 9:
        if complete:
            raise McapCorrupt(offset, "record header runs past the end of the file")
        raise FileEndsEarly(f"the file ends inside a record header ({len(head)} of 9 bytes)")
    opcode, length = _RECORD_HEADER.unpack(head)
    if opcode == 0 and length == 0 and not complete and _all_zero(f, offset, size):
        raise FileEndsEarly(f"the file ends at {size - offset} bytes of zeros (data never "
                            "written)")
    if opcode not in _KNOWN_OPCODES:
        raise McapCorrupt(offset, f"unknown record opcode {opcode:#04x}")
    if offset == 8 and opcode != Opcode.HEADER:
        raise McapCorrupt(offset, f"first record is {Opcode(opcode).name}, expected HEADER")
    if length > size - offset - 9:
        if complete:
            raise McapCorrupt(offset, f"{Opcode(opcode).name} record claims {length} bytes, "
                                   f"past the end of the file ({size} bytes)")
        raise FileEndsEarly(f"the {Opcode(opcode).name} record at the end is incomplete "
                            f"({size - offset - 9} of {length} bytes)", past_end=True)
    f.seek(offset + 9)
    content = f.read(length)
    rec = parse_record(offset, opcode, content)
    if opcode == Opcode.HEADER and offset != 8:
        raise McapCorrupt(offset, "a second HEADER record")
    end = offset + 9 + length
    if opcode == Opcode.FOOTER:
        _check_footer(walk, rec, head, content)
        scan.records += 1
        f.seek(end)
        tail = f.read(9)
        walk.offset = end
        if tail == MCAP_MAGIC:
            walk.offset = size
            return False
        if len(tail) < 8 and MCAP_MAGIC.startswith(tail):
            raise FileEndsEarly(f"the file ends inside the closing magic ({len(tail)} of 8 "
                                "bytes; every record is complete)")
        raise McapCorrupt(end, "footer not followed by the closing magic at the end of the file")
    if walk.in_summary:
        walk.summary_crc = zlib.crc32(content, zlib.crc32(head, walk.summary_crc))
    elif opcode == Opcode.DATA_END:
        data_end: DataEnd = rec
        if walk.check_data_crc and data_end.data_section_crc not in (0, walk.crc):
            raise McapCorrupt(offset, f"data section CRC mismatch (bytes 0 to {offset}): the "
                                   f"file says {data_end.data_section_crc:#010x}, its bytes "
                                   f"give {walk.crc:#010x}")
        walk.in_summary = True
        walk.summary_start = end
    else:
        walk.crc = zlib.crc32(content, zlib.crc32(head, walk.crc))
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
    scan.records += 1
    walk.offset = end
    return True


def _check_footer(walk: Walk, footer: Footer, head: bytes, content: bytes) -> None:
    if footer.summary_start not in (0, walk.summary_start) or not walk.in_summary:
        raise McapCorrupt(walk.offset, f"footer's summary start {footer.summary_start} does not "
                                       f"match the data end (summary at {walk.summary_start})")
    crc = zlib.crc32(head + content[:16], walk.summary_crc)
    if footer.summary_crc and footer.summary_crc != crc:
        raise McapCorrupt(walk.offset, f"summary CRC mismatch: footer says "
                                       f"{footer.summary_crc:#010x}, bytes give {crc:#010x} "
                                       f"(summary at offset {walk.summary_start})")
