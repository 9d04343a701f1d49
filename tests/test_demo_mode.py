"""The paper's demonstration mode (DESIGN §6) on a real bridge: real zenoh peers on loopback,
real MuJoCo, deterministic mode.

The push: a synthetic operator's open right hand (``teleop.synthetic``, noise off) is put 20 cm
behind the 10 cm box on the table with its palm at 11 cm (the forearm clears the table) and
swept 25 cm forward through it in 60 frames (0.72 s simulated, ~0.35 m/s), then held. In demo
mode the box settles on the table, is held, and stays put while the hand presses on it (the
contacts are still recorded); in free mode the same sweep shoves it several centimetres.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim.errors import ConfigError
from teleop import keys
from teleop.messages import HandFrame, encode
from tests.conftest import needs_menagerie

pytestmark = needs_menagerie

HAND, OBJECT = "shadow_right", "box"
BOX_HALF_M = 0.05          # the box primitive's half height
PALM_Z_M = 0.11            # the palm's height during the sweep (the box's top is at 0.10)
SWEEP_M, SWEEP_FRAMES = 0.25, 60
TABLE = {"top_z_m": 0.0, "center_m": [0.0, 0.0], "half_extents_m": [0.5, 0.5]}


@pytest.fixture(scope="module")
def operator() -> tuple[list[HandFrame], HandFrame]:
    """The synthetic operator's frames (for the scale calibration) and its open-hand frame."""
    from teleop.synthetic.config import SynthConfig
    from teleop.synthetic.synthesize import synthesize

    quiet = SynthConfig(position_noise_m=0.0, orientation_noise_deg=0.0, dropout_fraction=0.0,
                        time_jitter_s=0.0, latency_jitter_s=0.0)
    ep = synthesize(OBJECT, hand=HAND, seed=0, config=quiet)
    return list(ep.frames), ep.frames[0]


def _palm_in_tracking(frames: list[HandFrame], frame: HandFrame) -> np.ndarray:
    """Where ``frame`` puts the robot's palm in the operator's tracking space (an independent
    retargeter calibrated as the bridge's is)."""
    from sim.hand.model import Hand
    from sim.transforms import quat_to_mat
    from teleop.retarget.retargeter import Retargeter

    hand = Hand.load(HAND)
    r = Retargeter(hand)
    r.calibrate_scale(frames)
    res = r.step_frame(frame)
    palm, _ = hand.palm_pose(res.q)
    return np.asarray(res.base_pos_m) + quat_to_mat(np.asarray(res.base_quat_wxyz)) @ palm[0]


def _sweep(frame: HandFrame) -> list[HandFrame]:
    """``frame`` translated forward (+x) by up to SWEEP_M, then held for 20 frames."""
    def at(k: int) -> HandFrame:
        right = frame.right
        assert right is not None
        dx = np.array([SWEEP_M * min(k, SWEEP_FRAMES) / SWEEP_FRAMES, 0.0, 0.0])
        return dataclasses.replace(frame, seq=frame.seq + k, device_time_s=frame.device_time_s + k / 60,
                                   receive_time_s=frame.receive_time_s + k / 60,
                                   right=dataclasses.replace(right, positions=right.positions + dx))
    return [at(k) for k in range(SWEEP_FRAMES + 20)]


def _config(operator, mode: str):
    from teleop.bridge.config import load_bridge_config

    cfg = load_bridge_config()
    start = np.array([cfg.object_pos_m[0] - 0.2, cfg.object_pos_m[1], PALM_Z_M])
    offset = start - _palm_in_tracking(*operator)
    return dataclasses.replace(cfg, deterministic=True, view_enabled=False, object_mode=mode,
                               world_offset_m=offset)


def _record_push(operator, mode: str, path: Path) -> dict:
    """The push (module docstring) through a bridge in ``mode``, recorded to ``path``; after
    it the mode is switched to the other one (the object put back in it), still recording.
    The bridge's status at the start."""
    from teleop.bridge.bridge import Bridge
    from teleop.record.replay import hands_publisher, play

    port = keys.free_tcp_port()
    with Bridge(HAND, OBJECT, "dm", _config(operator, mode), listen_port=port,
                calibration_frames=operator[0]) as bridge:
        client = keys.open_session(connect_ports=[port])
        try:
            bridge.start()
            control = keys.RigKeys("dm").control_cmd
            status = keys.query_json(client, control("status"))
            assert bridge.control("start_recording", {"path": str(path)})["ok"]
            pub = hands_publisher(client, "dm", 5.0)
            frames = _sweep(operator[1])
            assert play(pub, [(0.0, encode(f)) for f in frames], "max") == len(frames)
            assert bridge.wait_idle(60.0, received=len(frames))
            pub.undeclare()
            other = "free" if mode == "demo" else "demo"
            reply = keys.query_json(client, control("set_object_mode"), {"object_mode": other})
            assert reply == {"ok": True, "object_mode": other, "changed": True}
            assert keys.query_json(client, control("stop_recording"))["ok"]
        finally:
            client.close()
    return status


@pytest.fixture(scope="module")
def pushed(operator, tmp_path_factory) -> dict[str, tuple[Path, dict]]:
    """mode → (recording of the push, bridge status before it)."""
    out = {}
    for mode in ("demo", "free"):
        path = tmp_path_factory.mktemp("demo_mode") / f"{mode}.mcap"
        out[mode] = (path, _record_push(operator, mode, path))
    return out


def _motion(path: Path) -> tuple[np.ndarray, int]:
    """The object's positions over the recorded states, and how many states had contacts."""
    from teleop.record.session import open_session

    s = open_session(path)
    pos = np.array([st["object_pos_m"] for _, st in s.json_messages("/state")])
    touching = sum(bool(c["contacts"]) for _, c in s.json_messages("/contacts"))
    return pos, touching


def test_a_demo_mode_object_settles_and_holds_against_a_push(pushed) -> None:
    """Settled on the table top before the hand arrives (what /state records from the first
    step), held: under 1 mm of motion (0.2 mm measured) while the hand presses on it for
    dozens of steps."""
    path, status = pushed["demo"]
    assert status["object_mode"] == "demo" and status["object_held"]
    pos, touching = _motion(path)
    assert abs(pos[0][2] - BOX_HALF_M) < 5e-4, pos[0]      # resting on the table top at z = 0
    assert touching >= 20, touching                        # the hand did press on it
    drift = np.linalg.norm(pos - pos[0], axis=1).max()
    assert drift < 0.001, drift


def test_b_free_mode_the_same_push_moves_it(pushed) -> None:
    path, status = pushed["free"]
    assert status["object_mode"] == "free" and not status["object_held"]
    pos, touching = _motion(path)
    assert touching > 0
    assert np.linalg.norm(pos[-1] - pos[0]) > 0.03, pos[-1] - pos[0]


def test_c_recording_names_the_mode_the_table_and_a_mode_change(pushed) -> None:
    from teleop.record.session import open_session

    for mode, (path, _) in pushed.items():
        s = open_session(path)
        assert s.metadata["object_mode"] == mode
        assert s.metadata["table"] == TABLE
        (change,) = [e["payload"] for _, e in s.events() if e["type"] == "object_reset"]
        assert change["previous"] == mode
        assert change["object_mode"] == ("free" if mode == "demo" else "demo")
        assert ("settled" in change) == (mode == "free")  # to demo: dropped and settled again


def test_d_an_older_session_rerecords_as_free_or_as_asked(operator, tmp_path) -> None:
    """A raw-input session without the new keys rerecords (treated as free mode, the config's
    table); an explicit mode wins; a session naming a bad mode is refused naming the file."""
    from teleop.bridge.rerecord import rerecord
    from teleop.record.session import open_session
    from teleop.synthetic.writer import write_session

    frames = _sweep(operator[1])[:30]
    old = write_session(frames, tmp_path / "old.mcap", {"hand": HAND, "object": OBJECT})
    assert {"object_mode", "table"}.isdisjoint(open_session(old).metadata)
    for asked, expected in ((None, "free"), ("demo", "demo")):
        out = open_session(rerecord(old, tmp_path / f"re_{expected}.mcap", object_mode=asked))
        assert out.counts["/state"] == len(frames)
        assert out.metadata["object_mode"] == expected and out.metadata["table"] == TABLE
    bad = write_session(frames, tmp_path / "bad.mcap", {"hand": HAND, "object": OBJECT,
                                                        "object_mode": "glued"})
    with pytest.raises(ConfigError, match=r"bad\.mcap: metadata object_mode.*demo, free"):
        rerecord(bad, tmp_path / "never.mcap")


def test_object_mode_is_validated(tmp_path) -> None:
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config

    bad = tmp_path / "teleop.toml"
    bad.write_text('[bridge]\nobject_mode = "glued"\n')
    with pytest.raises(ConfigError, match=r"teleop\.toml: bridge\.object_mode: expected one of "
                                          r"demo, free"):
        load_bridge_config(bad)
    cfg = dataclasses.replace(load_bridge_config(), view_enabled=False, table=False)
    with Bridge(HAND, OBJECT, "dmv", cfg, listen_port=keys.free_tcp_port()) as bridge:
        reply = bridge.control("set_object_mode", {"object_mode": "glued"})
        assert not reply["ok"] and "demo, free" in reply["error"]
        assert bridge.control("set_object_mode", {"object_mode": "demo"})["changed"] is False
        assert bridge.scene.object_held  # no table to drop onto: held at its home pose
