"""``dexaug repair`` (teleop.record.repair) and how damaged recordings are reported: real MCAP
files (a committed recording and one written by a recorder process killed with SIGKILL),
truncated and damaged on disk, read back with the plain ``mcap`` package reader. No mocks.

"Complete messages" are computed independently of the code under test: the messages of every
chunk of the intact file that lies wholly before the cut (or outside the damaged chunk)."""

from __future__ import annotations

import logging
import os
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import make_reader

from teleop.keys import free_tcp_port
from teleop.keys import open_session as open_zenoh
from teleop.record.mcap_scan import Block, scan_file
from teleop.record.repair import REPAIR_METADATA_NAME, RepairError, default_output, repair
from teleop.record.replay import replay
from teleop.record.session import SessionError, block_messages, open_session
from tests.killed_recorder import record_then_kill

REPO = Path(__file__).resolve().parents[1]
RECORDING = REPO / "recordings" / "demo_004_sugar_box.mcap"

Msg = tuple[str, int, int, bytes]   # topic, log time ns, sequence, data


def _plain(path: Path) -> Counter[Msg]:
    """Every message as the plain mcap reader (indexed, CRCs checked) gives it."""
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        return Counter((ch.topic, m.log_time, m.sequence, m.data)
                       for _, ch, m in reader.iter_messages(log_time_order=False))


def _plain_fails(path: Path) -> bool:
    try:
        _plain(path)
    except Exception:   # the mcap reader raises various types on a file without footer
        return True
    return False


def _blocks(path: Path) -> tuple[list[Block], dict[int, str]]:
    with open(path, "rb") as f:
        scan = scan_file(f, path.stat().st_size)
    return scan.blocks, {cid: ch.topic for cid, ch in scan.channels.items()}


def _messages_of(data: bytes, blocks: list[Block], topics: dict[int, str]) -> Counter[Msg]:
    out: Counter[Msg] = Counter()
    for b in blocks:
        for m in block_messages(data[b.offset:b.offset + b.length], b.is_chunk):
            out[(topics[m.channel_id], m.log_time, m.sequence, m.data)] += 1
    return out


def test_truncated_recording_is_repaired_at_every_kind_of_cut(tmp_path: Path) -> None:
    data = RECORDING.read_bytes()
    blocks, topics = _blocks(RECORDING)
    assert len(blocks) >= 5   # several chunks: cuts between and inside them
    ends = [b.offset + b.length for b in blocks]
    cuts = sorted({ends[0], ends[0] + 1, blocks[2].offset + 100, ends[2],
                   len(data) // 2, ends[-1] - 3, ends[-1] + 40, len(data) - 9, len(data) - 8,
                   len(data) - 1})
    for cut in cuts:
        src = tmp_path / f"cut_{cut}.mcap"
        src.write_bytes(data[:cut])
        assert _plain_fails(src), cut
        report = repair(src)
        assert report.dst == default_output(src) == tmp_path / f"cut_{cut}.repaired.mcap"
        assert src.read_bytes() == data[:cut]   # the source is never written
        expected = _messages_of(data, [b for b in blocks if b.offset + b.length <= cut], topics)
        got = _plain(report.dst)
        assert got == expected, cut
        assert sum(report.messages.values()) == sum(expected.values())
        assert report.state == "truncated" and report.stop_offset <= cut
        assert f"cut at byte {report.stop_offset} of {cut}" in "\n".join(report.lines())
        repaired = open_session(report.dst)
        assert not repaired.truncated
        assert repaired.metadata == open_session(RECORDING).metadata   # session metadata kept
        assert repaired.all_metadata[REPAIR_METADATA_NAME]["source"] == str(src)
    assert not list(tmp_path.glob(".*.tmp"))   # atomic output: no temp file left behind




def test_recorder_killed_with_sigkill_is_repaired(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    started, flushed = record_then_kill(path, 1.2, flush_interval_s=0.1)
    assert _plain_fails(path)
    killed = open_session(path)
    assert killed.truncated

    report = repair(path, tmp_path / "fixed.mcap")
    got = _plain(tmp_path / "fixed.mcap")
    want = Counter((m.topic, m.log_time_ns, m.sequence, m.data) for m in killed.messages())
    assert got == want and sum(got.values()) == sum(report.messages.values())
    hands = sorted(m for m in got if m[0] == "/hands")
    assert flushed <= len(hands) <= started and len(hands) > 100
    assert [m[2] for m in hands] == list(range(1, len(hands) + 1))   # no hole (the SDK counts from 1)
    assert report.messages["/state"] >= len(hands) - 1
    assert [e["type"] for _, e in open_session(tmp_path / "fixed.mcap").events()] == [
        "recording_started"]


@pytest.mark.parametrize("how", ["flipped chunk bytes", "broken chunk length"])
def test_damaged_chunk_is_skipped_and_everything_else_recovered(tmp_path: Path, how: str
                                                                ) -> None:
    data = bytearray(RECORDING.read_bytes())
    blocks, topics = _blocks(RECORDING)
    bad = blocks[len(blocks) // 2]
    if how == "flipped chunk bytes":
        mid = bad.offset + bad.length // 2
        data[mid:mid + 4] = bytes(b ^ 0xFF for b in data[mid:mid + 4])
    else:   # the record's 8-byte length field now claims far more than the file holds
        data[bad.offset + 1:bad.offset + 9] = (10**12).to_bytes(8, "little")
    src = tmp_path / "damaged.mcap"
    src.write_bytes(bytes(data))
    with pytest.raises(SessionError, match=rf"corrupt MCAP session at offset {bad.offset}\b"):
        open_session(src)
    report = repair(src, tmp_path / "fixed.mcap")
    assert report.state == "damaged" and [d.offset for d in report.damage] == [bad.offset]
    assert report.damage[0].resumed_at is not None and report.damage[0].resumed_at > bad.offset
    assert f"damaged record at byte {bad.offset}" in "\n".join(report.lines())
    expected = _messages_of(bytes(data), [b for b in blocks if b is not bad], topics)
    assert _plain(tmp_path / "fixed.mcap") == expected
    assert sum(expected.values()) < sum(open_session(RECORDING).counts.values())


@pytest.mark.parametrize("missing", range(1, 9))
def test_cut_in_the_last_bytes_reads_as_truncated_not_corrupt(tmp_path: Path,
                                                              missing: int) -> None:
    data = RECORDING.read_bytes()
    path = tmp_path / "s.mcap"
    path.write_bytes(data[:-missing])
    s = open_session(path)
    assert s.truncated and "closing magic" in s.truncation_reason
    assert s.counts == open_session(RECORDING).counts   # every record is there
    # only a cut is forgiven: wrong bytes where the magic belongs are still damage
    path.write_bytes(data[:-missing] + b"\x00" * missing)
    with pytest.raises(SessionError, match="corrupt MCAP session"):
        open_session(path)


def test_early_cut_says_what_was_found_and_where(tmp_path: Path,
                                                 caplog: pytest.LogCaptureFixture) -> None:
    blocks, _ = _blocks(RECORDING)
    cut = blocks[0].offset + blocks[0].length // 2   # inside the first chunk
    path = tmp_path / "early.mcap"
    path.write_bytes(RECORDING.read_bytes()[:cut])
    with caplog.at_level(logging.WARNING, logger="teleop.record.session"):
        s = open_session(path)
    assert s.truncated and s.counts.get("/state", 0) == 0
    note = s.cut_note
    assert f"truncated at byte {blocks[0].offset} of {cut}" in note
    assert "CHUNK record at the end is incomplete" in note
    assert "complete records (0 chunks, 0 messages) were read before the cut" in note
    assert "0 chunks, 0 messages" in caplog.text and f"offset {blocks[0].offset}" in caplog.text
    # replay names the cut instead of silently publishing nothing
    zs = open_zenoh(free_tcp_port())
    try:
        with pytest.raises(SessionError, match=rf"no /hands messages; the file is truncated at "
                                               rf"byte {blocks[0].offset}"):
            replay(path, zs, "t-early", rate="max", wait_for_subscriber_s=0.0)
    finally:
        zs.close()
    with pytest.raises(RepairError, match=r"nothing to recover, no message survives"):
        repair(path)
    assert not default_output(path).exists()
    # demo extraction names the cut too, not "raw input only"
    from teleop.record.demos import DemoError, extract_demos

    with pytest.raises(DemoError, match=rf"no /state message survives: the file is truncated "
                                        rf"at byte {blocks[0].offset}") as err:
        extract_demos(path)
    assert "raw input only" not in str(err.value)


def test_repair_refuses_to_replace_the_source_or_an_existing_file(tmp_path: Path) -> None:
    src = tmp_path / "s.mcap"
    data = RECORDING.read_bytes()[:-100]
    src.write_bytes(data)
    for dst in (src, tmp_path / "." / "s.mcap"):
        with pytest.raises(RepairError, match="would replace the source"):
            repair(src, dst, overwrite=True)
    os.link(src, tmp_path / "hardlink.mcap")
    with pytest.raises(RepairError, match="would replace the source"):
        repair(src, tmp_path / "hardlink.mcap", overwrite=True)
    other = tmp_path / "other.mcap"
    other.write_bytes(b"keep me")
    with pytest.raises(RepairError, match="already exists"):
        repair(src, other)
    with pytest.raises(RepairError, match="is a folder"):
        repair(src, tmp_path, overwrite=True)
    assert other.read_bytes() == b"keep me" and src.read_bytes() == data
    assert repair(src, other, overwrite=True).state == "truncated"
    assert not _plain_fails(other)


@pytest.mark.parametrize("content", [b"", b"not an mcap file at all" * 4])
def test_repair_of_a_non_mcap_file_is_a_one_line_error(tmp_path: Path, content: bytes) -> None:
    src = tmp_path / "junk.mcap"
    src.write_bytes(content)
    with pytest.raises(RepairError, match=r"junk\.mcap: cannot repair, offset 0: not an MCAP") \
            as err:
        repair(src)
    assert "\n" not in str(err.value)
    with pytest.raises(RepairError, match="cannot open"):
        repair(tmp_path / "missing.mcap")
