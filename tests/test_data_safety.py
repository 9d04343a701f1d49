"""Recorded and generated data is never lost or mis-reported: required fields missing from a
recording are one-line errors naming the message and field; temp files of a writer killed with
SIGKILL are swept by the next write; hostile demo ids cannot leave the output folder; private
files are written 0600 from the first byte; a damaged dataset or a bad replay rate is a
one-line error. Real MCAP and HDF5 files, real subprocesses and signals, no mocks."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import CompressionType, Writer

from augment import dataset
from dexaug.pipeline.options import demo_dir
from sim.demo import Demo
from sim.errors import ConfigError, DexaugError
from sim.io import STALE_TEMP_S, atomic_path, sweep_stale_temps, write_bytes_atomic
from teleop.record import schemas
from teleop.record.demos import extract_demos
from teleop.record.metadata import encode_metadata, session_metadata
from teleop.record.replay import check_rate
from teleop.record.session import SessionError, open_session

REPO = Path(__file__).resolve().parents[1]
FINGERS = ["thumb", "forefinger", "middle", "ring", "little"]
T0_NS = 1_700_000_000_000_000_000


def _state(i: int) -> dict:
    return {"t_s": i * 0.01, "seq": i, "tracked": True, "qpos": [0.0] * 24,
            "palm_pos_m": [0.0, 0.0, 1.0], "palm_quat_wxyz": [1.0, 0.0, 0.0, 0.0],
            "object": "004_sugar_box", "object_pos_m": [0.5, 0.0, 0.8],
            "object_quat_wxyz": [1.0, 0.0, 0.0, 0.0], "extra": {}}


def _contact() -> dict:
    v = [0.0, 0.0, 1.0]
    return {"finger": "thumb", "hand_body": "rh_thdistal", "pos_world_m": v, "normal_world": v,
            "pos_object_m": v, "normal_object": v, "pos_hand_body_m": v, "normal_hand_body": v,
            "dist_m": -0.001, "force_n": 1.0}


def _write_session(path: Path, states: list[dict], contacts: list[dict]) -> Path:
    """A session file as a recorder of another version might write it: our channels and
    metadata, payloads exactly as given (the dexaug recorder itself refuses incomplete ones)."""
    meta = session_metadata({"hand": "shadow_right", "object": "004_sugar_box",
                             "fingers": FINGERS, "joint_names": [f"j{i}" for i in range(24)]},
                            start_time_ns=T0_NS, own_clock=False)
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, enable_data_crcs=True)
        w.start()
        ids = {}
        for spec in schemas.CHANNELS:
            sid = w.register_schema(spec.schema_name, spec.schema_encoding, spec.schema_data)
            ids[spec.topic] = w.register_channel(spec.topic, spec.message_encoding, sid)
        w.add_metadata(schemas.METADATA_NAME, encode_metadata(meta))
        for i, (s, c) in enumerate(zip(states, contacts, strict=True)):
            t = T0_NS + (i + 1) * 10_000_000
            w.add_message(ids["/state"], t, schemas.dumps(s), t, i)
            w.add_message(ids["/contacts"], t, schemas.dumps(c), t, i)
        w.finish()
    return path


def _contacts(i: int) -> dict:
    return {"t_s": i * 0.01, "seq": i, "object": "004_sugar_box", "contacts": [_contact()]}


@pytest.mark.parametrize(("change", "message"), [
    (lambda s, c: s.pop("object_pos_m"), r"/state message 3 \(at 0\.020 s\) has no "
                                         r"'object_pos_m' field \(schema dexaug\.State\)"),
    (lambda s, c: s.update(palm_quat_wxyz=[1.0, 0.0]),
     r"/state message 3 .* has 'palm_quat_wxyz' with 2 values, expected 4"),
    (lambda s, c: s.update(qpos=None), r"/state message 3 .* has 'qpos' = null"),
    (lambda s, c: c["contacts"][0].pop("pos_hand_body_m"),
     r"/contacts message 3 .* has no 'contacts\[0\]\.pos_hand_body_m' field"),
])
def test_a_record_missing_a_required_field_is_a_one_line_error(tmp_path: Path, change,
                                                               message: str) -> None:
    states, contacts = [_state(i) for i in range(5)], [_contacts(i) for i in range(5)]
    change(states[2], contacts[2])
    path = _write_session(tmp_path / "broken.mcap", states, contacts)
    topic = "/state" if message.startswith("/state") else "/contacts"
    with pytest.raises(SessionError, match=message) as err:
        open_session(path).json_messages(topic)
    assert str(path) in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(DexaugError, match=message):   # what demo extraction meets
        extract_demos(path)


def test_missing_field_through_the_cli_is_one_line_not_a_traceback(tmp_path: Path) -> None:
    states = [_state(i) for i in range(5)]
    del states[0]["object_pos_m"]
    path = _write_session(tmp_path / "no_object_pos.mcap", states,
                          [_contacts(i) for i in range(5)])
    run = subprocess.run([sys.executable, "-m", "dexaug", "augment", str(path), "--out",
                          str(tmp_path / "out")], cwd=REPO, capture_output=True, text=True,
                         timeout=120, env={**os.environ, "PYTHONPATH": str(REPO)})
    text = run.stdout + run.stderr
    assert run.returncode != 0
    assert "Traceback" not in text and "KeyError" not in text
    assert "/state message 1" in text and "'object_pos_m'" in text


def test_older_records_without_t_s_still_read(tmp_path: Path) -> None:
    """``t_s`` is required by today's schema but older recordings lack it (demo extraction then
    pairs by log time): they must keep reading."""
    states = [{k: v for k, v in _state(i).items() if k != "t_s"} for i in range(3)]
    contacts = [{k: v for k, v in _contacts(i).items() if k != "t_s"} for i in range(3)]
    s = open_session(_write_session(tmp_path / "old.mcap", states, contacts))
    assert [m["seq"] for _, m in s.json_messages("/state")] == [0, 1, 2]


_KILLED_WRITER = textwrap.dedent("""
    import sys, time
    from sim.io import atomic_path
    with atomic_path(sys.argv[1]) as tmp:
        with open(tmp, "wb") as f:
            for _ in range(8):
                f.write(b"x" * (1 << 20))   # a large dataset on its way
                f.flush()
            print(tmp, flush=True)
            time.sleep(60)
""")


def _killed_mid_write(target: Path) -> Path:
    child = subprocess.Popen([sys.executable, "-c", _KILLED_WRITER, str(target)], cwd=REPO,
                             env={**os.environ, "PYTHONPATH": str(REPO)},
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        tmp = child.stdout.readline().strip()
        assert tmp, child.stderr.read()
    finally:
        child.send_signal(signal.SIGKILL)
        child.communicate(timeout=10)
    assert child.returncode == -signal.SIGKILL
    assert Path(tmp).stat().st_size == 8 << 20 and not target.exists()
    assert f".{os.path.basename(target)}.{child.pid}." in tmp   # the writer's pid in the name
    return Path(tmp)


def test_temp_file_of_a_killed_dataset_write_is_swept_by_the_next_write(tmp_path: Path) -> None:
    target = tmp_path / "grasps.h5"
    orphan = _killed_mid_write(target)
    other_target = tmp_path / "grasps.h5.bak"   # another file's temp is never touched
    other = tmp_path / f".{other_target.name}.1.abcdefgh.tmp"
    other.write_bytes(b"not ours")
    os.utime(other, (0, 0))
    table = dataset.from_fsg([], ["j0"], ["thumb", "index"])
    dataset.save(target, {"004_sugar_box": table})
    assert not orphan.exists() and other.exists()
    assert list(dataset.load(target)) == ["004_sugar_box"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([target.name, other.name])


def test_sweep_keeps_live_writers_and_removes_old_temp_files(tmp_path: Path) -> None:
    target = tmp_path / "out.json"
    with atomic_path(target) as live:   # our own write in progress (live pid, fresh)
        live.write_bytes(b"{}")
        legacy_fresh = tmp_path / f".{target.name}.k2j4h5g6.tmp"   # name without a pid
        legacy_old = tmp_path / f".{target.name}.a1b2c3d4.tmp"
        reused_pid = tmp_path / f".{target.name}.{os.getpid()}.zz99yy88.tmp"
        for p in (legacy_fresh, legacy_old, reused_pid):
            p.write_bytes(b"?")
        old = time.time() - STALE_TEMP_S - 60
        os.utime(legacy_old, (old, old))
        os.utime(reused_pid, (old, old))
        removed = sweep_stale_temps(target)
        assert sorted(removed) == sorted([legacy_old, reused_pid])
        assert live.exists() and legacy_fresh.exists()
    assert target.read_bytes() == b"{}" and not live.exists()


def test_private_files_are_0600_from_the_first_byte(tmp_path: Path) -> None:
    key = tmp_path / "token.key"
    with atomic_path(key, mode=0o600) as tmp:
        assert stat.S_IMODE(tmp.stat().st_mode) == 0o600   # before any content is written
        tmp.write_bytes(b"secret")
    assert stat.S_IMODE(key.stat().st_mode) == 0o600
    write_bytes_atomic(key, b"secret2", mode=0o600)   # replacing keeps it private
    assert stat.S_IMODE(key.stat().st_mode) == 0o600 and key.read_bytes() == b"secret2"
    public = tmp_path / "report.html"
    write_bytes_atomic(public, b"<html>")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(public.stat().st_mode) == 0o666 & ~umask


def _demo(demo_id: str) -> Demo:
    return Demo(id=demo_id, hand="shadow_right", object="004_sugar_box", joints=np.zeros(24),
                palm_pos_m=np.zeros(3), palm_quat_wxyz=np.array([1.0, 0, 0, 0]),
                tip_contacts={}, contact_points_obj={}, source=Path("x.mcap"), time_s=0.0,
                how="grasp_mark")


@pytest.mark.parametrize("demo_id", ["..", ".", "", "../escape", "a/../../b", "/etc/passwd",
                                     "..\\..\\win", "nul\x00byte", "../" * 50 + "deep",
                                     "x" * 1000, ".hidden@1.00s"])
def test_a_hostile_demo_id_stays_inside_the_output_folder(tmp_path: Path, demo_id: str) -> None:
    out_root = tmp_path / "out"
    folder = demo_dir(out_root, _demo(demo_id))
    assert folder.parent == out_root and folder.name not in ("", ".", "..")
    assert not folder.name.startswith(".")
    folder.mkdir(parents=True)   # a legal folder name (length, characters)
    assert folder.resolve().parent == out_root.resolve()
    assert list(tmp_path.iterdir()) == [out_root]
    assert demo_dir(out_root, _demo(demo_id)) == folder   # stable: results are found again


def test_ordinary_demo_ids_keep_their_folder_names(tmp_path: Path) -> None:
    for demo_id in ("demo_004_sugar_box@1.23s", "synth-005.tomato@0.50s"):
        assert demo_dir(tmp_path, _demo(demo_id)) == tmp_path / demo_id
    assert demo_dir(tmp_path, _demo("a b/c")) == tmp_path / "a_b_c"
    assert demo_dir(tmp_path, _demo("x" * 300)) != demo_dir(tmp_path, _demo("x" * 299 + "y"))


def test_a_cut_dataset_is_a_one_line_error(tmp_path: Path) -> None:
    path = tmp_path / "grasps.h5"
    dataset.save(path, {"004_sugar_box": dataset.from_fsg([], ["j0"], ["thumb"])})
    path.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(dataset.DatasetError, match=r"grasps\.h5: not a readable grasp dataset"):
        dataset.load(path)


@pytest.mark.parametrize("rate", [0, -5, 0.0, float("nan"), float("inf"), "fast", True])
def test_a_bad_replay_rate_is_a_config_error(rate: object) -> None:
    with pytest.raises(ConfigError, match=r"replay rate: expected a finite number > 0"):
        check_rate(rate)   # type: ignore[arg-type]
    check_rate("max")
    check_rate(0.5)
