"""The bridge survives its faults (teleop.bridge.faults) on a real bridge: real zenoh peers on
loopback, real MuJoCo, real MCAP files read back with the project's reader.

- a full disk (``RLIMIT_FSIZE`` in a child process, SIGXFSZ ignored so writes fail with EFBIG):
  the recording stops with ``recording_failed`` and a log line, the loop goes on answering
  frames, the partial file reads as truncated with its ``t_s`` increasing;
- a 10 m wrist jump between frames: clamped (counted, logged once), no scene reset, the object
  stays put, the recorded clock keeps increasing;
- a forced instability (NaN in qvel, the hand's base a thousand kilometres away): restored with
  ``scene_restored``, the object back on its spot, the clock never going backwards.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from teleop import keys
from teleop.messages import HandFrame, encode
from tests.conftest import HANG_S, SOON_S, needs_menagerie, wait_for, wait_for_match

pytestmark = [pytest.mark.slow, needs_menagerie]

HAND, OBJECT, RIG = "shadow_right", "box", "faults"
REPO = Path(__file__).resolve().parents[1]
JUMP_M = 10.0


def _operator_frames() -> list[HandFrame]:
    """A synthetic operator's grasp episode, noise and dropouts off (its first frames: still)."""
    from teleop.synthetic.config import SynthConfig
    from teleop.synthetic.synthesize import synthesize

    quiet = SynthConfig(position_noise_m=0.0, orientation_noise_deg=0.0, dropout_fraction=0.0,
                        time_jitter_s=0.0, latency_jitter_s=0.0)
    return list(synthesize(OBJECT, hand=HAND, seed=0, config=quiet).frames)


@pytest.fixture(scope="module")
def frames() -> list[HandFrame]:
    return _operator_frames()


def _shifted(frame: HandFrame, seq: int, dx_m: float = 0.0) -> HandFrame:
    """``frame`` as frame ``seq``, its right hand moved ``dx_m`` along x (tracking space)."""
    right = frame.right
    assert right is not None
    return dataclasses.replace(frame, seq=seq, right=dataclasses.replace(
        right, positions=right.positions + np.array([dx_m, 0.0, 0.0])))


class _Live:
    """A deterministic bridge (no view) recording into ``out``, a client peer publishing its
    ``/hands`` and collecting its ``/events`` and the ``seq`` of every ``/state``."""

    def __init__(self, frames: list[HandFrame], out: Path, **cfg: Any) -> None:
        from teleop.bridge.bridge import Bridge
        from teleop.bridge.config import load_bridge_config
        from teleop.record.replay import hands_publisher

        config = dataclasses.replace(load_bridge_config(), deterministic=True, view_enabled=False,
                                     recordings_dir=out, **cfg)
        port = keys.free_tcp_port()
        self.bridge = Bridge(HAND, OBJECT, RIG, config, listen_port=port,
                             calibration_frames=frames)
        self.client = keys.open_session(connect_ports=[port])
        k = keys.RigKeys(RIG)
        self.events: list[dict] = []
        self.state_seqs: list[int] = []
        self._subs = [
            self.client.declare_subscriber(k.events, lambda s: self.events.append(
                json.loads(s.payload.to_bytes()))),
            self.client.declare_subscriber(k.state, lambda s: self.state_seqs.append(
                json.loads(s.payload.to_bytes())["seq"]))]
        self.pub = hands_publisher(self.client, RIG, SOON_S)
        wait_for_match(self.pub, SOON_S, "the client's /hands publisher reaching the bridge")
        for pub in (self.bridge._pub_events, self.bridge._pub_state):
            wait_for_match(pub, SOON_S, f"the bridge's {pub.key_expr} reaching the client")
        self.sent = 0

    def send(self, frames: list[HandFrame]) -> None:
        for f in frames:
            self.pub.put(encode(f))
        self.sent += len(frames)

    def wait_for(self, what: str, limit_s: float = SOON_S) -> list[dict]:
        """The events of type ``what`` once there is one (AssertionError after ``limit_s``)."""
        return wait_for(lambda: [e for e in self.events if e["type"] == what], limit_s,
                        lambda: f"a {what!r} event; got {[e['type'] for e in self.events]}")

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self.pub.undeclare()
        self.bridge.close()
        self.client.close()


def _states(path: Path) -> list[dict]:
    from teleop.record.session import open_session
    return [s for _, s in open_session(path).json_messages("/state")]


def _increasing(t_s: list[float]) -> bool:
    return len(t_s) > 1 and bool(np.all(np.diff(t_s) > 0))


# ------------------------------------------------------------------------------------ disk full


def _disk_full_child(out: str, limit_bytes: int) -> None:
    """Run in a child process: a recording under RLIMIT_FSIZE = ``limit_bytes``; prints what
    the client saw as one JSON line."""
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr,
                        format="%(levelname)s %(name)s: %(message)s")
    frames = _operator_frames()
    live = _Live(frames, Path(out))
    try:
        live.bridge.start()
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)   # a write past the limit fails (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE,
                           (limit_bytes, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
        started = live.bridge.control("start_recording")
        for k in range(0, 3000, 100):   # until the disk is "full"
            live.send([_shifted(frames[(k + i) % len(frames)], k + i) for i in range(100)])
            # each batch processed (so recorded, or failed to be) before the next is sent
            assert live.bridge.wait_idle(SOON_S, received=live.sent), live.bridge.status()
            if live.bridge.status()["counts"].get("recording_failed"):
                break
        live.wait_for("recording_failed")   # the event has reached the client
        after = [_shifted(frames[i], 100_000 + i) for i in range(20)]
        live.send(after)
        assert live.bridge.wait_idle(SOON_S, received=live.sent), live.bridge.status()
        wanted = set(range(100_000, 100_020))
        wait_for(lambda: wanted <= set(live.state_seqs), SOON_S,   # their /state reached it too
                 lambda: f"/state for frames 100000-100019; got {sorted(wanted & set(live.state_seqs))}")
        answered = sorted({s for s in live.state_seqs if s is not None and s >= 100_000})
        print(json.dumps({"started": started, "events": live.events, "answered": answered,
                          "status": live.bridge.status()}))
    finally:
        live.close()


def test_a_full_disk_stops_the_recording_and_the_loop_goes_on(tmp_path) -> None:
    from teleop.record.session import open_session

    limit = 1 << 20   # room for the header and a few chunks of 100 frames
    code = (f"from tests.test_bridge_faults import _disk_full_child; "
            f"_disk_full_child({str(tmp_path)!r}, {limit})")
    run = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         timeout=HANG_S, env={**os.environ, "MUJOCO_GL": "egl"})
    assert run.returncode == 0, run.stderr[-3000:]
    seen = json.loads(run.stdout.strip().splitlines()[-1])
    assert seen["started"]["ok"], seen["started"]
    path = Path(seen["started"]["path"])
    (failed,) = [e for e in seen["events"] if e["type"] == "recording_failed"]
    assert failed["path"] == str(path) and "File too large" in failed["reason"]
    assert "goes on without recording" in run.stderr and "File too large" in run.stderr, \
        run.stderr[-2000:]
    status = seen["status"]
    assert status["loop_running"] and status["recording"] is None
    assert status["counts"]["recording_failed"] == 1
    assert seen["answered"] == list(range(100_000, 100_020))   # frames after it still answered
    # what was written stays readable: a truncated file, cut at a chunk, its clock increasing
    assert path.stat().st_size <= limit
    sess = open_session(path)
    assert sess.truncated
    t_s = [s["t_s"] for _, s in sess.json_messages("/state")]
    assert len(t_s) > 10 and _increasing(t_s), t_s[:20]
    assert [e["type"] for _, e in sess.events()][:1] == ["recording_started"]


def _recorder_child(out: str) -> None:
    """Run in a child process: the recorder alone under a file size limit; prints one JSON line."""
    from teleop.record.recorder import RecordingFailed, SessionRecorder
    from teleop.record.session import SessionError

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    hard = resource.getrlimit(resource.RLIMIT_FSIZE)[1]
    seen: dict[str, Any] = {}
    resource.setrlimit(resource.RLIMIT_FSIZE, (1000, hard))    # not even the header fits
    try:
        SessionRecorder(Path(out) / "header.mcap", metadata={"hand": HAND})
    except SessionError as exc:
        seen["header_error"] = str(exc)
    resource.setrlimit(resource.RLIMIT_FSIZE, (hard, hard))
    rec = SessionRecorder(Path(out) / "close.mcap", metadata={"hand": HAND})
    for i in range(50):
        rec.write_state([0.0], [i, 0, 0], [1, 0, 0, 0], [0, 0, 0], [1, 0, 0, 0], t_s=i * 0.01)
    rec.flush()
    seen["kept"] = rec.stats.bytes_on_disk
    resource.setrlimit(resource.RLIMIT_FSIZE, (rec.stats.bytes_on_disk + 10, hard))
    try:
        rec.close()        # the last chunk, summary and footer no longer fit
    except RecordingFailed as exc:
        seen["close_error"] = str(exc)
    print(json.dumps(seen))


def test_a_recorder_write_errors_are_one_line_and_leave_a_readable_file(tmp_path) -> None:
    from teleop.record.session import open_session

    code = f"from tests.test_bridge_faults import _recorder_child; _recorder_child({str(tmp_path)!r})"
    run = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         timeout=HANG_S)
    assert run.returncode == 0, run.stderr[-3000:]
    seen = json.loads(run.stdout.strip().splitlines()[-1])
    assert seen["header_error"] == f"{tmp_path / 'header.mcap'}: cannot write the recording: " \
                                   "File too large"
    assert not (tmp_path / "header.mcap").exists()              # no stub left behind
    assert "File too large" in seen["close_error"] and f"kept {seen['kept']} bytes" in \
        seen["close_error"]
    path = tmp_path / "close.mcap"
    assert path.stat().st_size == seen["kept"]                  # cut back to the last chunk
    sess = open_session(path)
    assert sess.truncated
    assert [s["t_s"] for _, s in sess.json_messages("/state")] == [i * 0.01 for i in range(50)]


# ------------------------------------------------------------------------------------ wrist jump


def test_b_a_10_m_wrist_jump_is_limited_not_a_reset(frames, tmp_path, caplog) -> None:
    caplog.set_level(logging.WARNING, logger="teleop.bridge.faults")
    live = _Live(frames, tmp_path)
    try:
        bridge = live.bridge
        bridge.start()
        path = Path(bridge.control("start_recording")["path"])
        live.send([_shifted(frames[k], k) for k in range(20)])
        live.send([_shifted(frames[k], k, JUMP_M) for k in range(20, 25)])   # 10 m away...
        live.send([_shifted(frames[k], k) for k in range(25, 45)])           # ...and back
        assert bridge.wait_idle(SOON_S, received=live.sent)
        assert bridge.control("stop_recording")["ok"]
        counts = bridge.status()["counts"]
        step_m = bridge.config.hand_max_step_m
    finally:
        live.close()
    states = _states(path)
    assert len(states) == 45 and _increasing([s["t_s"] for s in states])
    obj = np.array([s["object_pos_m"] for s in states])
    assert np.linalg.norm(obj - obj[0], axis=1).max() < 1e-3          # the object stayed put
    palm = np.array([s["palm_pos_m"] for s in states])
    reach_m = np.linalg.norm(palm - palm[0], axis=1).max()
    assert reach_m < 5 * step_m + 0.3, reach_m      # 5 limited frames (and the approach), not 10 m
    assert "scene_restored" not in counts and not [e for e in live.events
                                                   if e["type"] == "scene_restored"]
    assert counts["hand_base_limited"] >= 5, counts
    limited = [r for r in caplog.records if "hand_max_step_m" in r.getMessage()]
    assert len(limited) == 1 and limited[0].levelno == logging.WARNING   # once per episode


# --------------------------------------------------------------------------------- instability


def _far_base(bridge: Any) -> None:
    """The hand's base a thousand kilometres from its mocap target: the weld pulls it back."""
    bridge.scene.data.qpos[bridge.scene.base_qadr] = 1e6


def _nan_qvel(bridge: Any) -> None:
    bridge.scene.data.qvel[bridge.scene.hand_dadr[0]] = np.nan


@pytest.mark.parametrize("upset", [_nan_qvel, _far_base], ids=["nan_qvel", "far_base"])
def test_c_an_unstable_simulation_is_restored(frames, tmp_path, upset) -> None:
    """The test is the loop thread here: it steps the bridge itself, to upset it in between."""
    live = _Live(frames, tmp_path)
    bridge = live.bridge
    try:
        path = Path(bridge.control("start_recording")["path"])
        home, _ = bridge.scene.object_pose()

        def step(k0: int, n: int) -> None:
            live.send([_shifted(frames[k], k) for k in range(k0, k0 + n)])
            wait_for(lambda: bridge.counts["accepted"] >= live.sent, SOON_S,
                     lambda: f"{live.sent} frames accepted; counts {dict(bridge.counts)}",
                     every_s=0.002)
            while bridge.step_once():
                pass

        step(0, 20)
        upset(bridge)
        step(20, 20)
        restored = live.wait_for("scene_restored")
        counts = bridge.status()["counts"]
        pos, _ = bridge.scene.object_pose()
        assert bridge.control("stop_recording")["ok"]
    finally:
        live.close()
    states = _states(path)
    assert len(states) == 40 and _increasing([s["t_s"] for s in states])
    assert np.isfinite(np.array([s["qpos"] for s in states], float)).all()
    assert np.linalg.norm(pos - home) < 1e-3          # back on its spot, not at the origin
    assert len(restored) == 1 and counts["scene_restored"] == 1, counts
    assert "reset the simulation" in restored[0]["reason"] and restored[0]["object"] == OBJECT


def test_hand_max_step_is_configured_and_checked(tmp_path) -> None:
    from sim.errors import ConfigError
    from teleop.bridge.config import load_bridge_config

    assert load_bridge_config().hand_max_step_m == 0.1          # configs/teleop.toml's default
    toml = tmp_path / "teleop.toml"
    toml.write_text("[bridge]\nhand_max_step_m = 0.05\n")
    assert load_bridge_config(toml).hand_max_step_m == 0.05
    for bad in ("0.0", "-1.0", '"fast"'):
        toml.write_text(f"[bridge]\nhand_max_step_m = {bad}\n")
        with pytest.raises(ConfigError, match=r"teleop\.toml.*hand_max_step_m"):
            load_bridge_config(toml)
