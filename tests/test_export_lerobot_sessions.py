"""``dexaug export SESSION.mcap --format lerobot`` (augment.export.lerobot_sessions, issue #55):
a recorded bridge session as one LeRobot episode at a whole frame rate, read back with dexaug's
pyarrow reader and checked against the MCAP's own messages (read here with the session reader,
not through the export's code): each frame the recorded step at or before its tick, states,
targets, poses and contacts bit for bit, ``timestamp`` exactly ``frame_index / fps``. Bad
sessions and bad rates give one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sim.errors import DexaugError
from sim.paths import REPO_ROOT
from teleop.record.session import open_session
from teleop.record.session_steps import read_session_steps
from tests.conftest import HANG_S

pytest.importorskip("pyarrow", reason="the LeRobot export's extra: pip install -e '.[lerobot]'")

from augment.export.lerobot import write_lerobot
from augment.export.lerobot_read import LeRobotData, read_lerobot
from augment.export.lerobot_sessions import SESSION_FPS, session_episode, step_rate_hz

pytestmark = pytest.mark.slow   # ~15 s: 13 `dexaug export` processes

BRIDGE = REPO_ROOT / "recordings" / "bridge_043_phillips_screwdriver.mcap"
#: the bridge session: 533 steps of 12 ms, 6.384 s from the first to the last
STEPS = 533


def _export(*argv: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "dexaug", "export", *map(str, argv)],
                          capture_output=True, text=True, timeout=HANG_S, cwd=REPO_ROOT)


def _states() -> list[dict[str, Any]]:
    return [m.payload for m in open_session(BRIDGE).messages("/state")]


def _held(states: list[dict[str, Any]], fps: int) -> list[int]:
    """Per tick k / fps (from the first state, on the states' own ``t_s`` at the clock's
    nanosecond resolution) the latest state at or before it, in exact rationals: what a frame
    must hold."""
    ns = [round(s["t_s"] * 1e9) - round(states[0]["t_s"] * 1e9) for s in states]
    out: list[int] = []
    i = 0
    while (tick := Fraction(len(out) * 10**9, fps)) <= ns[-1]:
        while i + 1 < len(ns) and ns[i + 1] <= tick:
            i += 1
        out.append(i)
    return out


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> tuple[Path, LeRobotData, subprocess.CompletedProcess[str]]:
    """The session exported at the default rate."""
    out = tmp_path_factory.mktemp("sessions") / "lerobot"
    proc = _export(BRIDGE, "--format", "lerobot", "--out", out)
    assert proc.returncode == 0, proc.stderr
    return out, read_lerobot(out), proc


def test_fps_is_a_whole_number_in_info_json(exported) -> None:
    """LeRobot types ``fps`` as int; the bridge's 83.33 steps a second are resampled to it."""
    out, data, proc = exported
    fps = json.loads((out / "meta" / "info.json").read_text())["fps"]
    assert type(fps) is int and fps == SESSION_FPS == 50
    assert f"wrote 1 session episode(s) (320 frames at {fps} fps)" in proc.stdout
    assert data.info["total_frames"] == 320 == len(_held(_states(), fps))   # 6.384 s × 50, + 1


def test_timestamps_are_frame_index_over_fps_exactly(exported) -> None:
    _, data, _ = exported
    f, fps = data.episode_frames(0), data.info["fps"]
    assert np.array_equal(f["frame_index"], np.arange(320))
    assert f["timestamp"].dtype == np.float32
    assert np.array_equal(f["timestamp"], (f["frame_index"] / fps).astype(np.float32))
    assert np.abs(f["timestamp"] - f["frame_index"] / fps).max() < 1e-4   # LeRobot's check


def test_each_frame_is_the_recorded_step_at_or_before_its_tick(exported) -> None:
    _, data, _ = exported
    states, f = _states(), data.episode_frames(0)
    assert len(states) == STEPS
    held = [states[i] for i in _held(states, data.info["fps"])]
    assert np.array_equal(f["session.step"], _held(states, data.info["fps"]))
    assert len(set(f["session.step"].tolist())) == 320   # no step held twice
    want_state = np.array([s["qpos"] + s["palm_pos_m"] + s["palm_quat_wxyz"] + s["object_pos_m"]
                           + s["object_quat_wxyz"] for s in held])
    assert f["observation.state"].dtype == np.float64
    assert np.array_equal(f["observation.state"], want_state)             # bit for bit
    assert np.array_equal(f["action"], np.array([s["extra"]["q_target"] for s in held]))
    assert np.array_equal(f["session.tracked"], [s["tracked"] for s in held])
    assert np.array_equal(f["session.assist"], [s["extra"]["assist"] for s in held])
    assert np.array_equal(f["session.held"], [s["extra"]["held"] for s in held])
    assert f["next.done"].tolist() == [False] * 319 + [True]
    assert "next.success" not in data.info["features"]   # a session carries no verdict


def test_contacts_are_the_fingers_the_contacts_channel_names(exported) -> None:
    _, data, _ = exported
    fingers = data.info["features"]["observation.fingertip_contact"]["names"]
    assert fingers == ["thumb", "forefinger", "middle", "ring", "little"]
    msgs = [m.payload for m in open_session(BRIDGE).messages("/contacts")]
    assert len(msgs) == STEPS   # one per step, paired in order
    want = np.array([[float(any(c.get("finger") == n for c in msgs[i]["contacts"]))
                      for n in fingers] for i in _held(_states(), data.info["fps"])])
    got = data.episode_frames(0)["observation.fingertip_contact"]
    assert np.array_equal(got, want) and got[:, 1].sum() > 30   # the forefinger touches


def test_the_task_and_meta_are_the_recordings(exported) -> None:
    _, data, _ = exported
    info, row = data.info, data.episodes[0]
    assert data.tasks == ["grasp and lift the phillips screwdriver with the shadow right"]
    assert info["robot_type"] == "shadow_right" and info["video_path"] is None
    assert row["dexaug/session"] == BRIDGE.name and row["dexaug/rig"] == "rerecord"
    assert row["dexaug/step_hz"] == pytest.approx(1 / 0.012, rel=1e-12)   # the bridge's 12 ms
    assert '"fingers": ["forefinger", "middle"]' in row["dexaug/grasp_marks"]
    assert row["tasks"] == data.tasks and row["length"] == 320
    x = data.frames["action"]
    assert np.array_equal(data.stats["action"]["min"], x.min(axis=0))
    assert np.allclose(row["stats/action/mean"], x.mean(axis=0), rtol=1e-12, atol=1e-15)


def test_the_highest_rate_holds_a_step_of_its_own_each_frame() -> None:
    """83 fps, the whole rate just under 83.33 steps a second: 530 frames, no step twice."""
    steps = read_session_steps(BRIDGE)
    ep = session_episode(steps, 83)
    held = _held(_states(), 83)
    assert ep.fps == 83 and len(ep) == len(held) == 530
    assert np.array_equal(ep.columns["session.step"], held)
    assert np.array_equal(ep.columns["action"], steps.q_target[held])


def test_a_whole_step_rate_exports_every_step() -> None:
    """Where the steps are a whole rate apart (here 10 ms: the clock restated), that rate holds
    every step in order, the recorded frames themselves."""
    steps = read_session_steps(BRIDGE)
    steps.clock_ns = np.arange(STEPS, dtype=np.int64) * 10_000_000 + steps.clock_ns[0]
    ep = session_episode(steps, 100)
    assert len(ep) == STEPS and np.array_equal(ep.columns["session.step"], np.arange(STEPS))
    assert np.array_equal(ep.columns["observation.state"][:, :len(steps.joint_names)], steps.qpos)


def test_two_sessions_are_two_episodes(tmp_path) -> None:
    """The same writer: sessions follow each other, indices running on."""
    ep = session_episode(read_session_steps(BRIDGE))
    done = write_lerobot(tmp_path / "two", [ep, ep])
    data = read_lerobot(tmp_path / "two")
    assert done.episodes == 2 and data.episodes[1]["dataset_from_index"] == 320
    assert np.array_equal(data.episode_frames(1)["action"], data.episode_frames(0)["action"])
    assert np.array_equal(data.frames["index"], np.arange(640))


def test_uneven_steps_are_refused() -> None:
    """A session with a step missing has no one step rate: refused, not resampled."""
    steps = read_session_steps(BRIDGE)
    assert step_rate_hz(steps) == pytest.approx(83.333333, rel=1e-6)
    steps.clock_ns = np.delete(steps.clock_ns, 100)
    with pytest.raises(DexaugError, match="not evenly spaced"):
        step_rate_hz(steps)


@pytest.mark.parametrize(("fps", "says"), [
    ("84", "fps 84 is above the session's step rate (83.333 steps/s): frames would repeat; "
           "give at most 83"),
    ("0", "argument --fps: expected a whole number >= 1, got 0"),
    ("-5", "argument --fps: expected a whole number >= 1, got -5"),
    ("2.5", "argument --fps: expected a whole number >= 1, got '2.5'"),
])
def test_a_bad_fps_gives_one_line(fps, says, tmp_path) -> None:
    proc = _export(BRIDGE, "--format", "lerobot", "--out", tmp_path / "x", f"--fps={fps}")
    err = proc.stderr.strip()
    assert proc.returncode == 2 and says in err, err
    assert "\n" not in err and "Traceback" not in err and not (tmp_path / "x").exists()


def test_a_bad_fps_in_the_library_is_refused() -> None:
    steps = read_session_steps(BRIDGE)
    for fps in (0, -1, 50.0, True):
        with pytest.raises(DexaugError, match="a LeRobot frame rate is a whole number above 0"):
            session_episode(steps, fps)   # type: ignore[arg-type]


@pytest.mark.parametrize(("session", "says"), [
    ("demo_062_dice.mcap", "record no joint targets (extra.q_target)"),
    ("synth_005_tomato_soup_can.mcap", "no /state messages; the session holds raw input only"),
])
def test_a_session_without_the_channels_gives_one_line(session, says, tmp_path) -> None:
    proc = _export(REPO_ROOT / "recordings" / session, "--format", "lerobot", "--out",
                   tmp_path / "x")
    err = proc.stderr.strip()
    assert proc.returncode != 0 and says in err and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_what_sessions_cannot_take_is_refused(tmp_path) -> None:
    import h5py

    garbage = tmp_path / "notes.mcap"
    garbage.write_text("not a recording")
    grasps = tmp_path / "grasps.h5"
    h5py.File(grasps, "w").close()   # refused on its options before it is read
    cases = [((garbage,), "not an MCAP file"),
             ((BRIDGE, "--camera", "32x32"), "--camera does not apply to sessions"),
             ((BRIDGE, "--object", "043_phillips_screwdriver"), "--object does not apply"),
             ((BRIDGE, REPO_ROOT / "recordings"), "is a directory"),
             ((grasps, "--fps", "50"), "--fps does not apply to --format lerobot")]
    for argv, says in cases:
        proc = _export(*argv, "--format", "lerobot", "--out", tmp_path / "x")
        assert proc.returncode != 0 and says in proc.stderr, (argv, proc.stderr)
        assert len(proc.stderr.strip().splitlines()) <= 2, proc.stderr   # usage + one line
    proc = _export(BRIDGE, "--format", "npz", "--out", tmp_path / "x.npz")
    assert "sessions (.mcap) export only as --format lerobot" in proc.stderr
