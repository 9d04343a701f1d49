"""``dexaug export SESSION.mcap --format lerobot`` (augment.export.lerobot_sessions, issue #55):
a recorded bridge session as one LeRobot episode, read back with dexaug's pyarrow reader and
checked against the MCAP's own messages (read here with the session reader, not through the
export's code): states, targets, poses and contacts bit for bit, at the recording's rate. Bad
sessions give one-line errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

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
from augment.export.lerobot_sessions import session_episode, session_fps

pytestmark = pytest.mark.slow   # ~10 s: `dexaug export` processes

BRIDGE = REPO_ROOT / "recordings" / "bridge_043_phillips_screwdriver.mcap"


def _export(*argv: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "dexaug", "export", *map(str, argv)],
                          capture_output=True, text=True, timeout=HANG_S, cwd=REPO_ROOT)


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> tuple[Path, LeRobotData, subprocess.CompletedProcess[str]]:
    out = tmp_path_factory.mktemp("sessions") / "lerobot"
    proc = _export(BRIDGE, "--format", "lerobot", "--out", out)
    assert proc.returncode == 0, proc.stderr
    return out, read_lerobot(out), proc


def test_a_session_is_one_episode_of_what_the_mcap_holds(exported) -> None:
    _, data, proc = exported
    assert "wrote 1 session episode(s) (533 frames)" in proc.stdout and "frames/s" in proc.stdout
    states = [m.payload for m in open_session(BRIDGE).messages("/state")]
    assert len(data.episodes) == 1 and data.info["total_frames"] == len(states) == 533
    f = data.episode_frames(0)
    want_state = np.array([s["qpos"] + s["palm_pos_m"] + s["palm_quat_wxyz"] + s["object_pos_m"]
                           + s["object_quat_wxyz"] for s in states])
    assert f["observation.state"].dtype == np.float64
    assert np.array_equal(f["observation.state"], want_state)             # bit for bit
    assert np.array_equal(f["action"], np.array([s["extra"]["q_target"] for s in states]))
    assert np.array_equal(f["session.tracked"], [s["tracked"] for s in states])
    assert np.array_equal(f["session.assist"], [s["extra"]["assist"] for s in states])
    assert np.array_equal(f["session.held"], [s["extra"]["held"] for s in states])
    t_s = np.array([s["t_s"] for s in states])
    assert np.allclose(f["timestamp"], t_s - t_s[0], atol=1e-6)
    assert f["next.done"].tolist() == [False] * 532 + [True]
    assert "next.success" not in data.info["features"]   # a session carries no verdict


def test_contacts_are_the_fingers_the_contacts_channel_names(exported) -> None:
    _, data, _ = exported
    fingers = data.info["features"]["observation.fingertip_contact"]["names"]
    assert fingers == ["thumb", "forefinger", "middle", "ring", "little"]
    msgs = [m.payload for m in open_session(BRIDGE).messages("/contacts")]
    want = np.array([[float(any(c.get("finger") == n for c in m["contacts"])) for n in fingers]
                     for m in msgs])
    got = data.episode_frames(0)["observation.fingertip_contact"]
    assert np.array_equal(got, want) and got[:, 1].sum() > 50   # the forefinger touches


def test_the_rate_task_and_meta_are_the_recordings(exported) -> None:
    _, data, _ = exported
    info, row = data.info, data.episodes[0]
    assert info["fps"] == pytest.approx(1 / 0.012, rel=1e-12)   # the bridge's 12 ms step
    assert np.allclose(np.diff(data.frames["timestamp"].astype(np.float64)), 1 / info["fps"],
                       atol=1e-6)
    assert data.tasks == ["grasp and lift the phillips screwdriver with the shadow right"]
    assert info["robot_type"] == "shadow_right" and info["video_path"] is None
    assert row["dexaug/session"] == BRIDGE.name and row["dexaug/rig"] == "rerecord"
    assert '"fingers": ["forefinger", "middle"]' in row["dexaug/grasp_marks"]
    assert row["tasks"] == data.tasks and row["length"] == 533
    x = data.frames["action"]
    assert np.array_equal(data.stats["action"]["min"], x.min(axis=0))
    assert np.allclose(row["stats/action/mean"], x.mean(axis=0), rtol=1e-12, atol=1e-15)


def test_two_sessions_are_two_episodes(tmp_path) -> None:
    """The same writer: sessions follow each other, indices running on."""
    ep = session_episode(read_session_steps(BRIDGE))
    done = write_lerobot(tmp_path / "two", [ep, ep])
    data = read_lerobot(tmp_path / "two")
    assert done.episodes == 2 and data.episodes[1]["dataset_from_index"] == 533
    assert np.array_equal(data.episode_frames(1)["action"], data.episode_frames(0)["action"])
    assert np.array_equal(data.frames["index"], np.arange(1066))


def test_uneven_steps_are_refused() -> None:
    """A session with a step missing has no one frame rate: refused, not resampled."""
    steps = read_session_steps(BRIDGE)
    assert session_fps(steps) == pytest.approx(83.333333, rel=1e-6)
    steps.clock_ns = np.delete(steps.clock_ns, 100)
    with pytest.raises(DexaugError, match="not evenly spaced"):
        session_fps(steps)


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
    garbage = tmp_path / "notes.mcap"
    garbage.write_text("not a recording")
    cases = [((garbage,), "not an MCAP file"),
             ((BRIDGE, "--camera", "32x32"), "--camera does not apply to sessions"),
             ((BRIDGE, "--object", "043_phillips_screwdriver"), "--object does not apply"),
             ((BRIDGE, REPO_ROOT / "recordings"), "is a directory")]
    for argv, says in cases:
        proc = _export(*argv, "--format", "lerobot", "--out", tmp_path / "x")
        assert proc.returncode != 0 and says in proc.stderr, (argv, proc.stderr)
        assert len(proc.stderr.strip().splitlines()) <= 2, proc.stderr   # usage + one line
    proc = _export(BRIDGE, "--format", "npz", "--out", tmp_path / "x.npz")
    assert "sessions (.mcap) export only as --format lerobot" in proc.stderr
