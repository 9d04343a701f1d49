"""MCAP session recording: round trip of every channel, Foxglove schemas, crash safety (a
recorder process killed with SIGKILL), truncation at any byte, and corruption reported with the
byte offset. Real files in tmp_path, real subprocesses, no mocks."""

from __future__ import annotations

import base64
import json
import logging
import re
from pathlib import Path

import numpy as np
import pytest
from foxglove import messages as fm
from mcap.reader import make_reader

from teleop.messages import NUM_JOINTS, HandFrame, HandState, encode
from teleop.record import foxglove, schemas
from teleop.record.contact_record import ContactRecord
from teleop.record.foxglove import FrameTransform
from teleop.record.recorder import SessionRecorder
from teleop.record.session import SessionError, open_session, repair_session
from tests.killed_recorder import record_then_kill

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
JOINTS = [f"rh_J{i}" for i in range(24)]
FINGERS = ["thumb", "forefinger", "middle", "ring", "little"]
T0_NS = 1_700_000_000_000_000_000
DT_NS = 11_111_111  # 90 Hz


def _hand(rng: np.random.Generator, tracked: bool = True) -> HandState:
    """Random hand with float32-exact values, so decode(encode(h)) == h exactly."""
    q = rng.normal(size=(NUM_JOINTS, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    valid = np.ones(NUM_JOINTS, bool)
    valid[rng.integers(2, NUM_JOINTS)] = False
    pos = rng.normal(scale=0.1, size=(NUM_JOINTS, 3)).astype(np.float32).astype(float)
    pos[~valid] = np.nan
    return HandState(pos, q.astype(np.float32).astype(float),
                     np.full(NUM_JOINTS, 0.008, np.float32), valid, tracked)


def _frame(i: int, rng: np.random.Generator) -> HandFrame:
    return HandFrame(seq=i, device_time_s=i / 90, receive_time_s=i / 90 + 0.003,
                     head_position=np.array([0.0, 0.0, 1.6], np.float32),
                     head_orientation_wxyz=[1.0, 0.0, 0.0, 0.0], left=_hand(rng),
                     right=_hand(rng) if i % 3 else None, source="test")


def _metadata() -> dict:
    return {"hand": "shadow_right", "object": "ycb_025_mug", "joint_names": JOINTS,
            "fingers": FINGERS, "rig": "lab1", "config_hashes": {"teleop.toml": "abc123"}}


def _contact(rng: np.random.Generator, finger: str | None) -> ContactRecord:
    qo = rng.normal(size=4)
    qb = rng.normal(size=4)
    n = rng.normal(size=3)
    return ContactRecord.from_world(
        finger=finger, hand_body=f"rh_{finger or 'palm'}", pos_world_m=rng.normal(size=3) * 0.1,
        normal_world=n / np.linalg.norm(n), dist_m=-0.001, object_pos_m=[0.5, 0.0, 0.8],
        object_quat_wxyz=qo / np.linalg.norm(qo), body_pos_m=rng.normal(size=3) * 0.1,
        body_quat_wxyz=qb / np.linalg.norm(qb), force_n=2.5 if finger else float("nan"))


def _record(path: Path, n: int, *, rng: np.random.Generator, **kwargs) -> dict:
    """Record n steps of every channel; returns what was written, for comparison."""
    written: dict = {"frames": [], "states": [], "contacts": [], "jpegs": []}
    with SessionRecorder(path, metadata=_metadata(), start_time_ns=T0_NS, **kwargs) as rec:
        for i in range(n):
            t = T0_NS + (i + 1) * DT_NS
            frame = _frame(i, rng)
            rec.write_hands(frame, t)
            qpos = rng.uniform(-1, 1, size=len(JOINTS))
            rec.write_state(qpos, [0.0, 0.1, 1.0], [1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.8],
                            [0.0, 0.0, 0.0, 1.0], seq=i, log_time_ns=t)
            contacts = [_contact(rng, f) for f in (FINGERS[: i % 4] + [None] * (i % 2))]
            rec.write_contacts(contacts, log_time_ns=t)
            rec.write_tf([FrameTransform("palm", "rh_ffdistal", [0.0, 0.0, 0.1],
                                         [1.0, 0.0, 0.0, 0.0])], t)
            rec.write_markers(foxglove.scene_update([
                foxglove.scene_entity("object", t, models=[foxglove.model(
                    "file:///assets/mug.obj", [0.5, 0.0, 0.8], [1.0, 0.0, 0.0, 0.0])]),
                foxglove.hand_skeleton_entity(frame.left, t, entity_id="operator_left")]), t)
            jpeg = b"\xff\xd8" + rng.bytes(64) + b"\xff\xd9"
            rec.write_view(jpeg, t)
            if i == n // 2:
                rec.write_event("grasp_mark", {"note": "stable"}, log_time_ns=t)
                rec.write_event("object_changed", {"object": "ycb_011_banana"}, log_time_ns=t)
            written["frames"].append(frame)
            written["states"].append(qpos)
            written["contacts"].append(contacts)
            written["jpegs"].append(jpeg)
    written["stats"] = rec.stats
    return written


def test_round_trip_all_channels(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    n = 60
    w = _record(path, n, rng=np.random.default_rng(1), record_view=True)
    s = open_session(path)
    assert not s.truncated and s.stop_offset == s.file_size == path.stat().st_size
    assert s.counts == {"/hands": n, "/state": n, "/contacts": n, "/events": 4,
                        "/tf": 2 * n, "/markers": 2 * n, "/view": n}
    assert s.start_time_ns == T0_NS and s.end_time_ns == T0_NS + n * DT_NS
    assert s.duration_s == pytest.approx(n * DT_NS * 1e-9)
    meta = s.metadata
    assert meta["hand"] == "shadow_right" and meta["joint_names"] == JOINTS == s.joint_names
    assert meta["config_hashes"] == {"teleop.toml": "abc123"} and meta["rig"] == "lab1"
    assert meta["format_version"] == schemas.FORMAT_VERSION and "mcap_version" in meta

    frames = [f for _, f in s.hands()]
    assert frames == w["frames"]  # HandFrame equality (float32-exact arrays, NaN-aware)

    states = s.json_messages("/state")
    for (t, st), qpos, i in zip(states, w["states"], range(n), strict=True):
        assert t == T0_NS + (i + 1) * DT_NS and st["seq"] == i
        np.testing.assert_array_equal(st["qpos"], qpos)
        assert st["palm_quat_wxyz"] == [1.0, 0.0, 0.0, 0.0]
        assert st["object"] == ("ycb_025_mug" if i <= n // 2 else "ycb_011_banana")

    for (_, msg), contacts in zip(s.json_messages("/contacts"), w["contacts"], strict=True):
        back = [ContactRecord.from_json(c) for c in msg["contacts"]]
        assert len(back) == len(contacts)
        for a, b in zip(back, contacts, strict=True):
            assert a.finger == b.finger and a.hand_body == b.hand_body
            for key in ("pos_world_m", "normal_world", "pos_object_m", "normal_object",
                        "pos_hand_body_m", "normal_hand_body"):
                np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
            assert a.dist_m == b.dist_m and (a.force_n == b.force_n or
                                             (np.isnan(a.force_n) and np.isnan(b.force_n)))

    events = [e for _, e in s.events()]
    assert [e["type"] for e in events] == ["recording_started", "grasp_mark", "object_changed",
                                          "recording_stopped"]
    assert events[2]["payload"] == {"object": "ycb_011_banana"}

    views = [m.payload for m in s.messages("/view")]
    assert [base64.b64decode(v["data"]) for v in views] == w["jpegs"]
    assert views[0]["format"] == "jpeg" and views[0]["timestamp"] == foxglove.time_dict(
        T0_NS + DT_NS)

    tf = [m.payload for m in s.messages("/tf")]
    assert {t["child_frame_id"] for m in tf for t in m["transforms"]} == {
        "palm", "object", "rh_ffdistal"}
    obj_tf = next(t for t in tf[0]["transforms"] if t["child_frame_id"] == "object")
    # wxyz (0,0,0,1) in our API is xyzw (0,0,1,0) in Foxglove's
    assert obj_tf["rotation"] == {"x": 0.0, "y": 0.0, "z": 1.0, "w": 0.0}
    assert w["stats"].flushed == w["stats"].written


def test_contact_frames_are_consistent() -> None:
    """pos_object_m / pos_hand_body_m express the same world point in the other frames."""
    from sim import transforms

    rng = np.random.default_rng(3)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    c = ContactRecord.from_world(finger="thumb", hand_body="rh_thdistal",
                                 pos_world_m=[0.1, 0.2, 0.3], normal_world=[0.0, 0.0, -1.0],
                                 dist_m=0.0, object_pos_m=[0.5, 0.0, 0.8], object_quat_wxyz=q,
                                 body_pos_m=[0.1, 0.2, 0.25], body_quat_wxyz=[1, 0, 0, 0])
    p_world, _ = transforms.pose_mul([0.5, 0.0, 0.8], q, c.pos_object_m, [1, 0, 0, 0])
    np.testing.assert_allclose(p_world, [0.1, 0.2, 0.3], atol=1e-12)
    np.testing.assert_allclose(transforms.rotate(q, c.normal_object), [0, 0, -1],
                               atol=1e-12)
    np.testing.assert_allclose(c.pos_hand_body_m, [0.0, 0.0, 0.05], atol=1e-12)


def test_foxglove_schemas_and_mcap_interop(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    _record(path, 5, rng=np.random.default_rng(2), record_view=True, compression="lz4")
    s = open_session(path)
    names = {t: c.schema_name for t, c in s.channels.items()}
    assert names == {"/hands": "dexaug.HandFrame", "/state": "dexaug.State",
                     "/contacts": "dexaug.Contacts", "/events": "dexaug.Event",
                     "/tf": "foxglove.FrameTransforms", "/markers": "foxglove.SceneUpdate",
                     "/view": "foxglove.CompressedImage"}
    sdk = {"/tf": fm.FrameTransforms, "/markers": fm.SceneUpdate, "/view": fm.CompressedImage}
    for topic, ch in s.channels.items():
        if ch.schema_encoding == "jsonschema":
            assert ch.message_encoding == "json"
            assert json.loads(ch.schema_data)["title"] == ch.schema_name, topic
        elif topic in sdk:   # the SDK's own schema, byte for byte, and its encoding
            schema = sdk[topic].get_schema()
            assert (ch.schema_encoding, ch.message_encoding) == ("protobuf", "protobuf")
            assert (ch.schema_name, ch.schema_data) == (schema.name, bytes(schema.data))
        else:
            assert b"Wire layout" in ch.schema_data
    # the official reader, indexed path with CRC checks, sees the same file
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count == sum(s.counts.values())
        assert {summary.schemas[c.schema_id].name for c in summary.channels.values()} == set(
            names.values())
        assert sum(1 for _ in reader.iter_messages()) == sum(s.counts.values())
    # SceneUpdate entities carry every primitive list; the contact arrows point +x-rotated
    markers = [m.payload for m in s.messages("/markers")]
    contact_entities = [e for m in markers for e in m["entities"] if e["id"] == "contacts"]
    assert len(contact_entities) == 5
    keys = {"arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"}
    assert all(keys <= set(e) for e in contact_entities)


def test_view_off_by_default_and_input_checks(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    rng = np.random.default_rng(4)
    with SessionRecorder(path, metadata=_metadata()) as rec:
        assert rec.write_view(b"\xff\xd8xx") is False
        rec.write_hands(encode(_frame(0, rng)))  # raw wire bytes are accepted as received
        with pytest.raises(ValueError, match="qpos has 3 values"):
            rec.write_state([0, 0, 0], [0, 0, 0], [1, 0, 0, 0], [0, 0, 0], [1, 0, 0, 0])
        with pytest.raises(ValueError, match="written by the recorder"):
            rec.write_event("recording_started")
        with pytest.raises(ValueError, match="unknown event type"):
            rec.write_event("lunch")
        rec.write_event("object_reset")
        assert rec.stats.flushed["/events"] == rec.stats.written["/events"] == 2  # flushed now
    with pytest.raises(SessionError, match="closed"):
        rec.write_event("grasp_mark")
    s = open_session(path)
    assert "/view" not in s.channels and s.counts["/hands"] == 1
    with pytest.raises(SessionError, match="already exists"):
        SessionRecorder(path, metadata=_metadata())
    with SessionRecorder(path, metadata=_metadata(), overwrite=True):
        pass
    assert open_session(path).counts["/hands"] == 0


def test_chunks_are_time_bounded(tmp_path: Path) -> None:
    """A chunk is written once it spans flush_interval_s of log time (or wall time)."""
    path = tmp_path / "s.mcap"
    rng = np.random.default_rng(5)
    frame = _frame(0, rng)
    with SessionRecorder(path, metadata=_metadata(), start_time_ns=T0_NS,
                         flush_interval_s=0.1) as rec:
        for i in range(100):  # 1.1 s of data at 90 Hz -> about 11 chunks
            rec.write_hands(frame, T0_NS + i * DT_NS)
        assert 9 <= rec.stats.chunks <= 13
        assert rec.stats.written["/hands"] - rec.stats.flushed["/hands"] <= 10




def test_killed_recorder_leaves_a_readable_file(tmp_path: Path,
                                                caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "killed.mcap"
    # killed on the event (300 frames started: 1.5 s at 200 Hz, longer on a loaded machine),
    # not after 1.5 s of wall time, which a starved child fills with fewer frames
    started, flushed = record_then_kill(path, frames=300)
    assert started > 150  # about 300 at 200 Hz

    with caplog.at_level(logging.WARNING, logger="teleop.record.session"):
        s = open_session(path)
    assert s.truncated and s.stop_offset <= s.file_size
    assert "truncated at byte offset" in caplog.text
    n = s.counts["/hands"]
    assert flushed <= n <= started  # everything flushed before the kill is there
    assert n > 0.5 * started  # a crash loses at most the last chunk (<= 0.5 s of 1.5 s)
    assert s.counts["/state"] >= n - 1
    seqs = [f.seq for _, f in s.hands()]
    assert seqs == list(range(n))
    assert [e["type"] for _, e in s.events()] == ["recording_started"]

    repaired = repair_session(path, tmp_path / "repaired.mcap")
    assert not repaired.truncated and repaired.counts == s.counts
    with open(tmp_path / "repaired.mcap", "rb") as f:
        assert make_reader(f, validate_crcs=True).get_summary().statistics.message_count == sum(
            s.counts.values())


def test_truncated_at_any_byte_reads_up_to_the_damage(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    _record(path, 30, rng=np.random.default_rng(6), flush_interval_s=0.05)
    data = path.read_bytes()
    full = open_session(path)
    cut_path = tmp_path / "cut.mcap"
    rng = np.random.default_rng(7)
    cuts = sorted(set(rng.integers(8, len(data) - 8, size=60).tolist()))
    previous = 0
    for cut in cuts:
        cut_path.write_bytes(data[:cut])
        s = open_session(cut_path)
        total = sum(s.counts.values())
        assert s.truncated and s.stop_offset <= cut, cut
        assert previous <= total <= sum(full.counts.values())
        previous = total
        assert sum(1 for _ in s.messages()) == total
    # a file system that extended the file with zeros reads as truncated too
    cut_path.write_bytes(data[: len(data) // 2] + bytes(4096))
    assert open_session(cut_path).truncated


def test_corruption_names_the_offset(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    _record(path, 30, rng=np.random.default_rng(8), flush_interval_s=0.05)
    data = path.read_bytes()
    bad = tmp_path / "bad.mcap"
    # bytes flipped in the middle (inside a chunk)
    mid = len(data) // 2
    bad.write_bytes(data[:mid] + bytes(b ^ 0xFF for b in data[mid:mid + 4]) + data[mid + 4:])
    with pytest.raises(SessionError, match=r"offset \d+") as err:
        open_session(bad)
    assert str(bad) in str(err.value)
    offset = int(re.search(r"offset (\d+)", str(err.value)).group(1))
    assert offset <= mid
    # every single-byte flip anywhere in the file is detected (CRCs + structure checks)
    rng = np.random.default_rng(9)
    for pos in sorted(set(rng.integers(0, len(data), size=150).tolist()) | {0, 8, len(data) - 1}):
        damaged = bytearray(data)
        damaged[pos] ^= 0x5A
        bad.write_bytes(bytes(damaged))
        with pytest.raises(SessionError, match=r"corrupt MCAP session at offset \d+"):
            open_session(bad)


@pytest.mark.parametrize("content", [b"", b"hello world, not an mcap file" * 10,
                                     b"\x89MCAP1\r\n" + bytes(100)])
def test_not_mcap_names_the_file(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "garbage.mcap"
    path.write_bytes(content)
    with pytest.raises(SessionError, match=r"garbage\.mcap.*offset 0.*not an MCAP file"):
        open_session(path)


def test_random_garbage_after_header_is_corrupt(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    with SessionRecorder(path, metadata=_metadata()):
        pass
    head = path.read_bytes()[:200]
    rng = np.random.default_rng(10)
    path.write_bytes(head + b"\xee" + rng.bytes(5000) + b"\x89MCAP0\r\n")
    with pytest.raises(SessionError, match=r"s\.mcap.*offset \d+"):
        open_session(path)
    with pytest.raises(SessionError, match="cannot open"):
        open_session(tmp_path / "missing.mcap")
