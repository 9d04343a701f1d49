"""The teleop bridge end to end: real zenoh peers on loopback (multicast scouting off, distinct
free ports), real MuJoCo, the real Quest 3 capture replayed through zenoh.

Skips where the shared assets (capture, Menagerie hand) are absent.
"""

from __future__ import annotations

import dataclasses
import math
import struct

import numpy as np
import pytest
import zenoh

from sim.paths import SHARED_ASSETS
from teleop import keys
from teleop.messages import JOINT_INDEX, HandFrame, encode
from tests.conftest import SOON_S, wait_for, wait_for_match, wait_for_queryable

CAPTURE = SHARED_ASSETS / "handdata" / "quest3_webxr" / "cap.min.js"
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not CAPTURE.is_file(), reason=f"no hand capture {CAPTURE}")]


@pytest.fixture(scope="module")
def frames() -> list[HandFrame]:
    from teleop.input.iwer import iwer_hand_frames, load_iwer_capture
    return iwer_hand_frames(load_iwer_capture(CAPTURE))


def _config(**kw):
    from teleop.bridge.config import load_bridge_config
    cfg = load_bridge_config()
    return dataclasses.replace(cfg, **kw)


class _Rig:
    """A bridge on one peer and a client peer connected to it (distinct free ports)."""

    def __init__(self, frames, rig: str, **cfg_kw) -> None:
        from teleop.bridge.bridge import Bridge
        port = keys.free_tcp_port()
        self.rig = rig
        self.bridge = Bridge("shadow_right", None, rig, _config(**cfg_kw), listen_port=port,
                             calibration_frames=frames)
        self.client = keys.open_session(connect_ports=[port])
        self.bridge.start()
        self.k = keys.RigKeys(rig)
        wait_for_queryable(self.client, self.k.control_cmd("status"), SOON_S,
                           "the bridge's control queryable reaching the client")

    def query(self, cmd: str, payload: dict | None = None) -> dict:
        return keys.query_json(self.client, self.k.control_cmd(cmd), payload, timeout_s=SOON_S)

    def close(self) -> None:
        self.bridge.close()
        self.client.close()


def _op_pinch(frame: HandFrame) -> float:
    h = frame.right
    if h is None or not (h.valid[JOINT_INDEX["thumb_tip"]] and h.valid[JOINT_INDEX["index_tip"]]):
        return math.nan
    return float(np.linalg.norm(h.positions[JOINT_INDEX["thumb_tip"]]
                                - h.positions[JOINT_INDEX["index_tip"]]))


def _robot_pinch(hand, q: np.ndarray) -> np.ndarray:
    tips = hand.fingertip_sites(np.asarray(q, float))
    names = hand.finger_names
    return np.linalg.norm(tips[:, names.index("thumb")] - tips[:, names.index("forefinger")],
                          axis=-1)


def _record(rig: _Rig, path, play) -> None:
    # a path is for in-process callers only (a remote caller names a file in recordings_dir)
    assert rig.bridge.control("start_recording", {"path": str(path), "overwrite": True})["ok"]
    n = play()
    assert rig.bridge.wait_idle(SOON_S, received=n)
    assert rig.query("mark_grasp")["ok"]
    assert rig.query("stop_recording")["ok"]


def test_quest_capture_replays_into_a_recording(frames, tmp_path, shadow):
    """Live path at real time: pinch frames → robot thumb–index < 2 cm, open frames > 6 cm."""
    from teleop.record.replay import replay_capture
    from teleop.record.session import open_session
    rig = _Rig(frames, "t1")
    path = tmp_path / "live.mcap"
    try:
        _record(rig, path, lambda: replay_capture(frames, rig.client, "t1", rate=1.0))
        status = rig.query("status")
        from teleop.bridge.status import BridgeStatus
        # the reply a remote caller parses has exactly the typed keys (no more, none missing)
        assert set(status) == BridgeStatus.__required_keys__, set(status) ^ BridgeStatus.__required_keys__
        if rig.bridge.view_active:
            assert status["counts"].get("views", 0) > 0
    finally:
        rig.close()
    sess = open_session(path)
    hands = {f.seq: f for _, f in sess.hands()}
    states = [s for _, s in sess.json_messages("/state") if s["seq"] is not None]
    assert len(hands) == len(frames) and len(states) > 0.9 * len(frames)
    types = [e["type"] for _, e in sess.events()]
    assert "recording_started" in types and "grasp_mark" in types
    op = np.array([_op_pinch(hands[s["seq"]]) for s in states])
    q = np.array([s["extra"]["q_target"] for s in states])
    robot = _robot_pinch(shadow, q)
    pinch = np.argsort(np.nan_to_num(op, nan=np.inf))[:3]
    assert op[pinch].max() < 0.025
    assert (robot[pinch] < 0.02).all(), (op[pinch], robot[pinch])
    open_ = np.nan_to_num(op, nan=0) > 0.08
    assert open_.sum() > 10 and (robot[open_] > 0.06).mean() > 0.95
    # the simulated hand moves with its targets (physics at its own timestep)
    qsim = np.array([s["qpos"] for s in states])
    assert np.isfinite(qsim).all() and np.median(np.abs(qsim - q).mean(axis=1)) < 0.15


def _pinch_offset(frames, hand) -> np.ndarray:
    """World offset that puts the robot's thumb–index midpoint at the closest pinch onto the
    resting box's centre (computed offline with an independent Retargeter)."""
    from sim.transforms import quat_to_mat
    from sim.world.objects import load_object
    from teleop.retarget.retargeter import Retargeter
    r = Retargeter(hand)
    r.calibrate_scale(frames)
    res = [r.step_frame(f) for f in frames]
    i = int(np.nanargmin([_op_pinch(f) for f in frames]))
    tips = hand.fingertip_sites(res[i].q[None])[0]
    names = hand.finger_names
    mid = 0.5 * (tips[names.index("thumb")] + tips[names.index("forefinger")])
    world = res[i].base_pos_m + quat_to_mat(res[i].base_quat_wxyz) @ mid
    cfg = _config()
    z = -float(load_object("box").collision_mesh().bounds[0][2]) + 1e-3
    return np.array([*cfg.object_pos_m, z]) - world


def test_recorded_contacts_in_object_and_fingertip_frames(frames, tmp_path, shadow):
    from teleop.record.replay import replay_capture
    from teleop.record.session import open_session
    offset = _pinch_offset(frames, shadow)
    rig = _Rig(frames, "t2", deterministic=True, world_offset_m=offset, view_enabled=False)
    path = tmp_path / "contacts.mcap"
    try:
        _record(rig, path, lambda: replay_capture(frames, rig.client, "t2", rate="max"))
    finally:
        rig.close()
    recs = [c for _, m in open_session(path).json_messages("/contacts") for c in m["contacts"]]
    tip = [c for c in recs if c["finger"] is not None]
    assert tip, f"no fingertip contacts among {len(recs)}"
    for c in tip[:50]:
        for k in ("pos_object_m", "normal_object", "pos_hand_body_m", "normal_hand_body"):
            assert c[k] is not None and len(c[k]) == 3 and all(v is not None for v in c[k])
        assert abs(np.linalg.norm(c["normal_object"]) - 1) < 1e-6
        assert abs(np.linalg.norm(c["normal_hand_body"]) - 1) < 1e-6


def test_replaying_a_recording_is_deterministic(frames, tmp_path):
    from teleop.record.replay import replay, replay_capture
    from teleop.record.session import open_session
    src = tmp_path / "src.mcap"
    rig = _Rig(frames[:300], "t3", deterministic=True, view_enabled=False)
    try:
        _record(rig, src, lambda: replay_capture(frames[:300], rig.client, "t3", rate="max"))
    finally:
        rig.close()
    runs = []
    for i in range(2):
        rig = _Rig(frames[:300], f"t3r{i}", deterministic=True, view_enabled=False)
        out = tmp_path / f"replay{i}.mcap"
        try:
            _record(rig, out, lambda rig=rig, i=i: replay(src, rig.client, f"t3r{i}", rate="max"))
        finally:
            rig.close()
        st = [s for _, s in open_session(out).json_messages("/state") if s["seq"] is not None]
        runs.append((np.array([s["seq"] for s in st]), np.array([s["extra"]["q_target"] for s in st]),
                     np.array([s["qpos"] for s in st])))
    assert len(runs[0][0]) == 300
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    np.testing.assert_array_equal(runs[0][2], runs[1][2])
    # bit-identical raw input
    a = [m.data for m in open_session(src).messages("/hands", decode=False)]
    b = [m.data for m in open_session(tmp_path / "replay0.mcap").messages("/hands", decode=False)]
    assert a == b


def _nan_joint(frame: HandFrame) -> bytes:
    f = dataclasses.replace(frame, left=None)
    buf = bytearray(encode(f))
    off = 64 + len(f.source.encode()) + 12 * JOINT_INDEX["wrist"]
    struct.pack_into("<f", buf, off, float("nan"))
    return bytes(buf)


def test_bad_input_is_counted_and_a_vanished_hand_holds(frames):
    rig = _Rig(frames, "t4", deterministic=True, view_enabled=False)
    try:
        # BLOCK, as the replayer publishes: every sample of the burst below must arrive to be
        # counted, and the default DROP discards samples when the send queue is full (this test
        # failed once on a loaded machine)
        pub = rig.client.declare_publisher(rig.k.hands,
                                           congestion_control=zenoh.CongestionControl.BLOCK)
        wait_for_match(pub, SOON_S, "the client's /hands publisher reaching the bridge")
        good = [f for f in frames if f.right is not None][100:140]
        wrong = bytearray(encode(good[0]))
        wrong[4:6] = struct.pack("<H", 99)
        for f in good[:20]:
            pub.put(encode(f))
        for bad in (b"garbage", encode(good[20])[:100], _nan_joint(good[21]), bytes(wrong)):
            pub.put(bad)
        for f in good[20:]:
            pub.put(encode(f))
        assert rig.bridge.wait_idle(SOON_S, received=44), rig.bridge.status()["counts"]
        q_before = rig.bridge._q_target.copy()
        for k, f in enumerate(good[-5:]):
            pub.put(encode(dataclasses.replace(f, right=None, seq=10_000 + k)))
        assert rig.bridge.wait_idle(SOON_S, received=49)
        st = rig.query("status")
        assert st["loop_running"]
        assert st["counts"]["malformed"] == 3 and st["counts"]["wrong_schema"] == 1
        assert st["counts"]["processed"] == 45
        assert st["held"]["no_hand"] >= 5 and st["last_seq"] == 10_004
        np.testing.assert_array_equal(rig.bridge._q_target, q_before)
        pub.undeclare()
    finally:
        rig.close()


def test_bridge_config_errors_name_file_and_key(tmp_path):
    from sim.errors import ConfigError
    from teleop.bridge.config import load_bridge_config
    bad = tmp_path / "teleop.toml"
    bad.write_text("[bridge]\nview_rate_hz = -1.0\n")
    with pytest.raises(ConfigError, match=r"teleop\.toml.*view_rate_hz"):
        load_bridge_config(bad)
    bad.write_text("[bridge]\nstate_rate = 10.0\n")
    with pytest.raises(ConfigError, match=r"teleop\.toml.*state_rate"):
        load_bridge_config(bad)
    bad.write_text("[bridge]\nworld_offset_m = [0.0, 1.0]\n")
    with pytest.raises(ConfigError, match=r"teleop\.toml.*world_offset_m"):
        load_bridge_config(bad)


def test_control_object_commands_and_errors(frames):
    rig = _Rig(frames[:5], "t5", deterministic=True, view_enabled=False)
    try:
        events = []
        sub = rig.client.declare_subscriber(rig.k.events,
                                            lambda s: events.append(s.payload.to_bytes()))
        wait_for_match(rig.bridge._pub_events, SOON_S, "the bridge's /events reaching the client")
        assert rig.query("choose_object", {"object": "cylinder"}) == {"ok": True,
                                                                       "object": "cylinder"}
        rig.bridge.scene.set_object_pose(np.array([0.0, 0.3, 0.2]), np.array([1.0, 0, 0, 0]))
        assert rig.query("reset_object")["ok"]
        pos, _ = rig.bridge.scene.object_pose()
        # demo mode (the default) drops it there and lets it settle: micrometres off the spot
        np.testing.assert_allclose(pos[:2], _config().object_pos_m, atol=1e-4)
        assert not rig.query("stop_recording")["ok"]          # not recording: an error reply
        assert not rig.query("choose_object", {"object": "no_such_object"})["ok"]
        assert not rig.query("frobnicate")["ok"]
        st = rig.query("status")
        assert st["object"] == "cylinder" and st["loop_running"]
        wait_for(lambda: len(events) >= 2, SOON_S, lambda: f"2 events; got {events}")
        import json
        types = [json.loads(e)["type"] for e in events]
        assert types == ["object_changed", "object_reset"]
        sub.undeclare()
    finally:
        rig.close()


def test_recording_closed_hook(tmp_path) -> None:
    """--auto-augment's hook: called once with the finished file when a recording stops, and a
    failing hook never takes the bridge down."""
    from teleop.bridge.bridge import Bridge
    from teleop.record.session import open_session

    closed = []

    def hook(path):
        closed.append(path)
        raise RuntimeError("augmenter exploded")

    port = keys.free_tcp_port()
    with Bridge("shadow_right", None, "hook", _config(view_enabled=False), listen_port=port,
                on_recording_closed=hook) as bridge:
        path = tmp_path / "s.mcap"
        assert bridge.control("start_recording", {"path": str(path)})["ok"]
        assert bridge.control("stop_recording")["ok"]
        assert closed == [path] and not open_session(path).truncated
        assert bridge.status()["ok"]
