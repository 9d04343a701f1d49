"""``dexaug repair``: a readable copy of a killed or damaged session recording.

Why a copy, and why it is needed: a recorder killed mid-session leaves a file without summary
or footer. dexaug's own reader (:mod:`teleop.record.session`) reads it up to the cut, but the
plain ``mcap`` reader (``make_reader(...).iter_messages()``), Foxglove's seeking and other tools
need the summary and refuse it. :func:`repair` writes every complete record it can trust — each
schema, channel, metadata record and every message of every chunk whose CRC checks — into a
new, closed, indexed MCAP file, and says what it found and where the file was cut or damaged.

What counts as trustworthy is :func:`salvage_scan`'s (the session reader's validating scan,
made to step over damage): records up to the cut of a truncated file; around a damaged record,
reading resumes at the next chunk whose CRC checks (the damaged stretch is reported, never
copied). Messages of a chunk that was
cut off are not recovered: without its CRC nothing proves their bytes. The source is never
written to; the copy appears atomically (:func:`sim.io.atomic_path`) and is checked with the
strict scan before it takes its name. The copy carries a ``dexaug.repair`` metadata record
(source file, cut, damage), so a repaired session says it was repaired.
"""

from __future__ import annotations

import logging
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mcap.opcode import Opcode

from sim.errors import DexaugError
from sim.io import atomic_path
from teleop.record.mcap_scan import (
    MAX_CHUNK_BYTES,
    FileEndsEarly,
    McapCorrupt,
    Scan,
    decompress_chunk,
    parse_record,
    read_record,
    scan_file,
    start_scan,
)
from teleop.record.session import SessionError, scan_found, write_indexed_copy

__all__ = ["REPAIR_METADATA_NAME", "Damage", "RepairError", "RepairReport", "default_output",
           "repair", "salvage_scan"]

log = logging.getLogger(__name__)

#: Name of the metadata record a repaired copy carries.
REPAIR_METADATA_NAME = "dexaug.repair"


class RepairError(DexaugError):
    """A recording cannot be repaired: not MCAP, nothing recoverable, or the output would
    replace the source or an existing file."""


@dataclass(frozen=True)
class Damage:
    """A damaged stretch the salvage scan skipped: the ``offset`` of the record at fault, where
    reading resumed (``resumed_at``: the next intact chunk; None when nothing after it was
    readable) and what was wrong."""

    offset: int
    resumed_at: int | None
    reason: str


@dataclass(frozen=True)
class RepairReport:
    """What :func:`repair` did. ``state``: "complete" (the source was fine: the copy is the
    same data), "truncated" (cut at ``stop_offset``, ``reason`` says how) or "damaged" (see
    ``damage``); ``records``: complete records read from the source; ``messages``: messages
    written per topic; ``file_size``: bytes of the source."""

    src: Path
    dst: Path
    state: str
    file_size: int
    stop_offset: int
    reason: str
    records: int
    messages: dict[str, int]
    damage: tuple[Damage, ...]

    def lines(self) -> list[str]:
        """The report for people, one fact a line (the CLI prints these)."""
        per_topic = ", ".join(f"{t} {n}" for t, n in sorted(self.messages.items()))
        out = [f"{self.src}: {self.state}; {self.records} complete records read, "
               f"{sum(self.messages.values())} messages recovered ({per_topic or 'none'})"]
        if self.state == "truncated":
            out.append(f"cut at byte {self.stop_offset} of {self.file_size}: {self.reason}")
        for d in self.damage:
            span = (f"bytes {d.offset} to {d.resumed_at} skipped" if d.resumed_at is not None
                    else f"nothing readable from byte {d.offset} to the end ({self.file_size})")
            out.append(f"damaged record at byte {d.offset}: {d.reason}; {span}")
        out.append(f"wrote {self.dst}")
        return out


def default_output(src: Path) -> Path:
    """Where the copy goes without ``--out``: ``NAME.repaired.mcap`` beside the source."""
    return src.with_name(f"{src.stem}.repaired{src.suffix or '.mcap'}")


def _check_output(src: Path, dst: Path, overwrite: bool) -> None:
    same = dst.exists() and os.path.samefile(src, dst)
    if same or dst.resolve() == src.resolve():
        raise RepairError(f"{dst}: the repaired copy would replace the source; choose another "
                          "--out")
    if dst.is_dir():
        raise RepairError(f"{dst}: is a folder; --out takes the repaired file's name")
    if dst.exists() and not overwrite:
        raise RepairError(f"{dst}: already exists; choose another --out or remove it")


def repair(src: Path, dst: Path | None = None, *, overwrite: bool = False) -> RepairReport:
    """Write a readable copy of the recording ``src`` to ``dst`` (default
    :func:`default_output`); module docstring. ``overwrite`` lets an existing ``dst`` (never
    the source) be replaced.

    Raises:
        RepairError: ``src`` cannot be opened or is not MCAP, nothing in it is recoverable, or
            ``dst`` is the source or already exists (each message names the file).
    """
    src = Path(src)
    dst = default_output(src) if dst is None else Path(dst)
    try:
        f = open(src, "rb")  # noqa: SIM115  # closed below, the scan needs the handle throughout
    except OSError as exc:
        raise RepairError(f"{src}: cannot open the recording: {exc.strerror}") from None
    _check_output(src, dst, overwrite)
    with f:
        size = os.fstat(f.fileno()).st_size
        try:
            scan, damage = salvage_scan(f, size)
        except McapCorrupt as exc:
            raise RepairError(f"{src}: cannot repair, offset {exc.offset}: {exc.reason}") from None
    if not scan.blocks:
        cut = f" ({scan.truncation_reason})" if scan.truncated else ""
        raise RepairError(f"{src}: nothing to recover, no message survives: {scan_found(scan)} "
                          f"before byte {scan.stop_offset} of {size}{cut}")
    state = "damaged" if damage else "truncated" if scan.truncated else "complete"
    note = {"source": str(src), "state": state, "source_size": str(size),
            "stop_offset": str(scan.stop_offset), "reason": scan.truncation_reason,
            "damage": "; ".join(f"byte {d.offset}: {d.reason}" for d in damage)}
    try:
        with atomic_path(dst) as tmp:
            written = write_indexed_copy(tmp, src, scan, {REPAIR_METADATA_NAME: note})
            _verify(tmp, dst, scan)
    except SessionError as exc:   # the source changed while being copied
        raise RepairError(str(exc)) from None
    except OSError as exc:
        raise RepairError(f"{dst}: cannot write the repaired copy: {exc.strerror or exc}"
                          ) from None
    report = RepairReport(src, dst, state, size, scan.stop_offset, scan.truncation_reason,
                          scan.records, dict(written), tuple(damage))
    for line in report.lines():
        log.debug("%s", line)
    return report


def _verify(tmp: Path, dst: Path, scan: Scan) -> None:
    """The copy must read as complete with the strict scan and hold every recovered message."""
    with open(tmp, "rb") as f:
        try:
            check = scan_file(f, os.fstat(f.fileno()).st_size)
        except McapCorrupt as exc:  # a bug here, never the source's fault
            raise RepairError(f"{dst}: the repaired copy does not check at offset {exc.offset}: "
                              f"{exc.reason}") from None
    if check.truncated or sum(check.counts.values()) != sum(scan.counts.values()):
        raise RepairError(f"{dst}: the repaired copy holds {scan_found(check)}, expected "
                          f"{sum(scan.counts.values())} messages")


def salvage_scan(f: IO[bytes], size: int) -> tuple[Scan, list[Damage]]:
    """:func:`~teleop.record.mcap_scan.scan_file`, but a damaged record does not raise: it is
    listed, its partial effect undone, and reading resumes at the next chunk whose CRC checks (a
    chunk's CRC makes a false resumption point practically impossible). Raises
    :class:`McapCorrupt` only when ``f`` is not MCAP at all."""
    scan, walk = start_scan(f, size)
    damage: list[Damage] = []
    while True:
        saved = _snapshot(scan)
        try:
            if not read_record(scan, walk):
                break
            continue
        except FileEndsEarly as stop:
            resume = _next_chunk(f, walk.offset + 1, size) if stop.past_end else None
            if resume is None:
                scan.truncated, scan.truncation_reason = True, stop.reason
                break
            fault, reason = walk.offset, f"record there is broken: {stop.reason}"
        except McapCorrupt as exc:
            fault, reason = exc.offset, exc.reason
            resume = _next_chunk(f, max(exc.offset, walk.offset) + 1, size)
        _restore(scan, saved)
        damage.append(Damage(fault, resume, reason))
        walk.check_data_crc = False   # the skipped bytes are in it
        if resume is None:
            walk.offset = fault
            break
        walk.offset = resume
    scan.stop_offset = walk.offset
    return scan, damage


def _snapshot(scan: Scan) -> tuple[Any, ...]:
    """What a record may change in ``scan`` (small: a session has a handful of channels)."""
    return (dict(scan.schemas), dict(scan.channels), dict(scan.metadata), len(scan.blocks),
            Counter(scan.counts), scan.start_ns, scan.end_ns, scan.header, scan.records)


def _restore(scan: Scan, saved: tuple[Any, ...]) -> None:
    """Undo a damaged record's partial effect on ``scan``."""
    (scan.schemas, scan.channels, scan.metadata, n_blocks, scan.counts, scan.start_ns,
     scan.end_ns, scan.header, scan.records) = saved
    del scan.blocks[n_blocks:]
    scan.pending_index = None


def _next_chunk(f: IO[bytes], start: int, size: int) -> int | None:
    """Offset of the first chunk record at or after ``start`` whose CRC checks, None when none
    does: where a salvage scan resumes after damage."""
    window = 1 << 20
    opcode = bytes([Opcode.CHUNK])
    pos = start
    while pos < size - 9:
        f.seek(pos)
        buf = f.read(min(window, size - pos))
        i = buf.find(opcode)
        while i != -1:
            if _intact_chunk_at(f, pos + i, size):
                return pos + i
            i = buf.find(opcode, i + 1)
        pos += len(buf)
    return None


def _intact_chunk_at(f: IO[bytes], offset: int, size: int) -> bool:
    f.seek(offset)
    head = f.read(9)
    length = int.from_bytes(head[1:9], "little") if len(head) == 9 else -1
    if not 40 <= length <= size - offset - 9:   # 40 bytes: a chunk's fixed fields
        return False
    try:
        chunk = parse_record(offset, Opcode.CHUNK, f.read(length))
        if not chunk.uncompressed_crc or chunk.uncompressed_size > MAX_CHUNK_BYTES:
            return False   # no CRC: nothing proves these bytes are a chunk
        decompress_chunk(chunk)
    except Exception:  # any parse, decompression or CRC failure: not an intact chunk
        return False
    return True
