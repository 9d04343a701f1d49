"""Objects placed as they really lie: stable resting poses found by dropping the object in real
MuJoCo (:mod:`sim.world.resting`), chosen through the bridge's control commands over real zenoh
on loopback, recorded in the session (:mod:`teleop.bridge.control`).

The stability check re-drops each pose in a world built here (a plane and the object's own
spec), independent of the module's drop code: placed in the pose, released 1 mm above the
plane and simulated for 1.5 s, its down direction must stay within 3 degrees.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from teleop import keys
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_ycb]

HAND = "shadow_right"
BOX, CAN = "004_sugar_box", "005_tomato_soup_can"
SIDE_TILT_DEG = 5.0     # an axis counts as horizontal (or vertical) within this angle


@pytest.fixture(scope="module")
def cache(tmp_path_factory) -> Path:
    """A fresh resting-pose cache for this module (first computations really compute)."""
    path = tmp_path_factory.mktemp("rest_cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("DEXAUG_CACHE_DIR", str(path))
        yield path


@pytest.fixture(scope="module")
def box_poses(cache):
    from sim.world.objects import load_object
    from sim.world.resting import resting_poses

    return resting_poses(load_object(BOX))


@pytest.fixture(scope="module")
def can_poses(cache):
    from sim.world.objects import load_object
    from sim.world.resting import resting_poses

    return resting_poses(load_object(CAN))


def _mat(quat) -> np.ndarray:
    m = np.empty(9)
    mujoco.mju_quat2Mat(m, np.asarray(quat, float))
    return m.reshape(3, 3)


def _angle_deg(a, b) -> float:
    return math.degrees(math.acos(float(np.clip(np.dot(a, b), -1.0, 1.0))))


def _redrop(name: str, pose) -> np.ndarray:
    """The object's down direction (object frame) after resting 1.5 s in ``pose`` on a plane."""
    from sim.world.objects import load_object
    from sim.world.resting import rest_placement

    obj = load_object(name)
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], friction=[0.8, 0.005, 0.0001])
    spec.attach(obj.spec(), prefix="o/", frame=spec.worldbody.add_frame())
    m = spec.compile()
    d = mujoco.MjData(m)
    pos, quat = rest_placement(obj, pose, np.zeros(2), 30.0)
    d.qpos[:3], d.qpos[3:7] = pos, quat
    for _ in range(int(1.5 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    return _mat(d.qpos[3:7]).T @ np.array([0.0, 0.0, -1.0])


def test_a_box_has_distinct_stable_poses_the_upright_one_among_them(box_poses) -> None:
    assert len(box_poses) >= 3, box_poses.poses
    downs = [np.asarray(p.down) for p in box_poses.poses]
    for i in range(len(downs)):
        for j in range(i + 1, len(downs)):
            assert _angle_deg(downs[i], downs[j]) > 30.0, (i, j)   # distinct faces
    up = box_poses.upright_index()
    assert up is not None and _angle_deg(downs[up], [0.0, 0.0, -1.0]) < SIDE_TILT_DEG
    shares = [p.share for p in box_poses.poses]
    assert shares == sorted(shares, reverse=True) and math.isclose(sum(shares), 1.0, abs_tol=1e-5)
    for pose in box_poses.poses:
        drift = _angle_deg(_redrop(BOX, pose), pose.down)
        assert drift < 3.0, (pose, drift)


def test_b_poses_are_deterministic_and_cached(box_poses, cache) -> None:
    from sim.world.objects import load_object
    from sim.world.resting import RestParams, resting_poses

    obj = load_object(BOX)
    assert not box_poses.cached and list((cache / "resting").glob("004_sugar_box-*.json"))
    again = resting_poses(obj)
    assert again.cached and again.poses == box_poses.poses
    assert again.seconds < box_poses.seconds / 5, (again.seconds, box_poses.seconds)
    fresh = resting_poses(obj, use_cache=False)              # recomputed: the same result
    assert not fresh.cached and fresh.poses == box_poses.poses
    other = resting_poses(obj, RestParams(seed=1), use_cache=False)
    assert other.key != box_poses.key
    print(f"\n{BOX}: resting poses computed in {box_poses.seconds:.2f} s, read from the cache "
          f"in {again.seconds * 1e3:.1f} ms")


def test_c_the_soup_can_stands_upright_or_lies_on_its_side(can_poses) -> None:
    axis = np.asarray(can_poses.symmetry_axis)
    assert abs(abs(axis[2]) - 1.0) < 0.01, axis                # the can's axis: its z
    assert can_poses.upright_index() is not None
    sides = [p for p in can_poses.poses if abs(p.down[2]) < math.sin(math.radians(SIDE_TILT_DEG))]
    assert len(sides) == 1, can_poses.poses                     # rolled either way: one pose
    assert sides[0].share > 0.3
    assert _angle_deg(_redrop(CAN, sides[0]), sides[0].down) < 3.0


def test_d_bad_parameters_are_refused() -> None:
    from sim.world.resting import RestParams

    with pytest.raises(ValueError, match=r"RestParams\.cluster_deg: expected a finite number > 0"):
        RestParams(cluster_deg=float("nan"))


# ------------------------------------------------------------------------------------ bridge


def _side_index(poses) -> int:
    """The most frequent pose whose object z axis is horizontal."""
    return next(i for i, p in enumerate(poses.poses)
                if abs(_mat(p.quat_wxyz)[2, 2]) < math.sin(math.radians(SIDE_TILT_DEG)))


def _up_z(bridge) -> float:
    """The z component of the simulated object's z axis."""
    return float(_mat(bridge.scene.object_pose()[1])[2, 2])


def _one_state(bridge, client) -> None:
    """One handless frame over zenoh, processed by the running loop: the bridge publishes (and
    records) a state."""
    from teleop.messages import HandFrame, encode
    from teleop.record.replay import hands_publisher, play

    pub = hands_publisher(client, bridge.keys.rig, 5.0)
    frame = HandFrame(seq=1, device_time_s=0.0, receive_time_s=0.0, head_position=np.zeros(3),
                      head_orientation_wxyz=np.array([1.0, 0.0, 0.0, 0.0]))
    assert play(pub, [(0.0, encode(frame))], "max") == 1
    assert bridge.wait_idle(10.0, received=1)
    pub.undeclare()


@pytest.fixture(scope="module")
def placed(cache, box_poses, tmp_path_factory):
    """A demo-mode bridge on the sugar box, driven over zenoh: the box laid on its side at
    yaw 90 and recorded, then the next pose, then bad requests; the replies and states seen."""
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config

    cfg = dataclasses.replace(load_bridge_config(), deterministic=True, view_enabled=False,
                              object_mode="demo")
    path = tmp_path_factory.mktemp("rest_rec") / "side.mcap"
    port = keys.free_tcp_port()
    out: dict = {"path": path, "side": _side_index(box_poses)}
    with Bridge(HAND, BOX, "rest", cfg, listen_port=port) as bridge:
        client = keys.open_session(connect_ports=[port])
        control = keys.RigKeys("rest").control_cmd
        try:
            bridge.start()   # deterministic: no physics steps without frames, poses stay put
            out["start_up_z"] = _up_z(bridge)
            out["set"] = keys.query_json(client, control("set_object_rest"),
                                         {"rest": out["side"], "yaw_deg": 90})
            out["side_up_z"], out["held"] = _up_z(bridge), bridge.scene.object_held
            out["side_quat"] = bridge.scene.object_pose()[1]
            out["status"] = keys.query_json(client, control("status"))
            assert bridge.control("start_recording", {"path": str(path)})["ok"]
            _one_state(bridge, client)
            out["next"] = keys.query_json(client, control("next_object_rest"))
            bad = {"range": {"rest": 99}, "type": {"rest": "1"}, "yaw": {"rest": 0, "yaw_deg": "inf"},
                   "path": {"rest": 0, "path": "/tmp/x"}, "missing": {}}
            for what, args in bad.items():
                out[f"bad_{what}"] = keys.query_json(client, control("set_object_rest"), args)
            # a non-finite yaw (JSON allows NaN/Infinity only by extension): sent raw
            for reply in client.get(control("set_object_rest"),
                                    payload=b'{"rest": 0, "yaw_deg": Infinity}', timeout=5.0):
                out["bad_inf"] = json.loads(reply.ok.payload.to_bytes())
            out["after_bad"] = bridge.object_rest
            assert bridge.control("stop_recording")["ok"]
        finally:
            client.close()
    return out


@needs_menagerie
def test_e_laid_on_its_side_by_a_control_command(placed, box_poses) -> None:
    """Upright at the start; on its side after ``set_object_rest``: the simulated box's z axis
    horizontal, settled and held (demo mode), turned by the yaw asked."""
    assert placed["start_up_z"] > math.cos(math.radians(SIDE_TILT_DEG))
    assert placed["set"]["ok"], placed["set"]
    rest = placed["set"]["object_rest"]
    assert rest["index"] == placed["side"] and rest["yaw_deg"] == 90.0 and not rest["upright"]
    assert placed["set"]["rest_poses"] == len(box_poses)
    assert abs(placed["side_up_z"]) < math.sin(math.radians(SIDE_TILT_DEG)), placed["side_up_z"]
    assert placed["held"]
    want = box_poses[placed["side"]].quat_at_yaw(90.0)        # settled near the pose asked
    assert abs(float(np.dot(placed["side_quat"], want))) > math.cos(math.radians(3.0) / 2)
    assert placed["status"]["object_rest"] == placed["side"]
    assert placed["status"]["object_rest_yaw_deg"] == 90.0


@needs_menagerie
def test_f_the_session_records_the_resting_pose(placed, box_poses) -> None:
    from teleop.record.session import open_session

    s = open_session(placed["path"])
    meta = s.metadata["object_rest"]
    assert meta["index"] == placed["side"] and meta["yaw_deg"] == 90.0
    assert meta["poses_key"] == box_poses.key[:16]
    first_state = next(st for _, st in s.json_messages("/state"))
    assert abs(_mat(first_state["object_quat_wxyz"])[2, 2]) < math.sin(math.radians(SIDE_TILT_DEG))
    (reset,) = [e["payload"] for _, e in s.events() if e["type"] == "object_reset"]
    nxt = (placed["side"] + 1) % len(box_poses)
    assert reset["object_rest"]["index"] == nxt and reset["previous_rest"]["index"] == placed["side"]
    assert reset["object_rest"]["yaw_deg"] == 90.0 and reset["settled"]
    assert placed["next"]["ok"] and placed["next"]["object_rest"]["index"] == nxt


@needs_menagerie
def test_g_bad_requests_are_refused_in_one_line(placed, box_poses) -> None:
    n = len(box_poses)
    for what in ("range", "type", "yaw", "path", "missing", "inf"):
        reply = placed[f"bad_{what}"]
        assert reply["ok"] is False and "\n" not in reply["error"], (what, reply)
    assert f"expected a resting pose index 0..{n - 1} of {BOX}" in placed["bad_range"]["error"]
    assert "got 99" in placed["bad_range"]["error"]
    assert "rest: expected a resting pose index (an integer)" in placed["bad_type"]["error"]
    assert "yaw_deg: expected a finite number of degrees" in placed["bad_yaw"]["error"]
    assert "yaw_deg: expected a finite number of degrees" in placed["bad_inf"]["error"]
    assert "['path'] not accepted" in placed["bad_path"]["error"]
    assert "got None" in placed["bad_missing"]["error"]
    assert placed["after_bad"] == (placed["side"] + 1) % n    # nothing refused moved the box


@needs_menagerie
def test_h_choose_object_lays_the_can_on_its_side_in_free_mode(cache, can_poses) -> None:
    """``choose_object`` with a ``rest``: the can on its side, free, stays on its side after
    0.5 s of simulation; a bad index keeps the previous object."""
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config

    cfg = dataclasses.replace(load_bridge_config(), deterministic=True, view_enabled=False,
                              object_mode="free")
    side = next(i for i, p in enumerate(can_poses.poses) if abs(p.down[2]) < 0.1)
    with Bridge(HAND, "box", "restc", cfg, listen_port=keys.free_tcp_port()) as bridge:
        bad = bridge.control("choose_object", {"object": CAN, "rest": len(can_poses)}, trusted=False)
        assert not bad["ok"] and "resting pose index" in bad["error"]
        assert bridge.object_name == "box" and bridge.object_rest is None
        reply = bridge.control("choose_object", {"object": CAN, "rest": side}, trusted=False)
        assert reply["ok"], reply
        assert not bridge.scene.object_held and bridge.placement.rest.index == side
        for _ in range(int(0.5 / bridge.scene.model.opt.timestep)):
            mujoco.mj_step(bridge.scene.model, bridge.scene.data)
        assert abs(_up_z(bridge)) < math.sin(math.radians(SIDE_TILT_DEG)), _up_z(bridge)
        pos = bridge.scene.object_pose()[0]
        assert abs(pos[0] - cfg.object_pos_m[0]) < 0.05, pos   # it did not roll away
        plain = bridge.control("choose_object", {"object": "box"}, trusted=False)
        assert plain["ok"] and bridge.object_rest is None and _up_z(bridge) > 0.99


@needs_menagerie
def test_i_a_session_names_the_arguments_to_lay_it_down_again(placed) -> None:
    from sim.errors import ConfigError
    from teleop.bridge.session_mode import session_object_rest
    from teleop.record.session import open_session

    meta = open_session(placed["path"]).metadata
    assert session_object_rest(meta, placed["path"]) == {"rest": placed["side"], "yaw_deg": 90.0}
    assert session_object_rest({}, "old.mcap") is None
    assert session_object_rest({"object_rest": {"index": None, "yaw_deg": 0.0}}, "up.mcap") is None
    with pytest.raises(ConfigError, match=r"bad\.mcap: metadata object_rest: expected null"):
        session_object_rest({"object_rest": {"index": "1", "yaw_deg": 0}}, "bad.mcap")
