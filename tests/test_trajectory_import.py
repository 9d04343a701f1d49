"""Offline hand trajectories → raw-input sessions (teleop.input.keypoints, teleop.input.trajectory,
``dexaug import-trajectory``): retargeting quality on a real MediaPipe video, joint frames
against a real headset's, and a synthesised grasp of a placed object driven through the real
bridge on zenoh loopback by ``rerecord``.

Skips where the shared assets (the MediaPipe and Quest captures, the Menagerie hand) are absent.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dexaug.cli import main
from sim.paths import SHARED_ASSETS
from sim.transforms import quat_to_mat, rpy_deg_to_mat
from teleop.input.keypoints import (
    MEDIAPIPE_TO_OPENXR,
    Anchor,
    joint_rotations,
    keypoint_frames,
    openxr_positions,
)
from teleop.input.trajectory import load_trajectory
from teleop.messages import JOINT_INDEX, OPENXR_JOINTS, WRIST
from teleop.synthetic.human_hand import HandPose, HumanHand, lerp_pose
from tests.conftest import needs_menagerie

MEDIAPIPE = SHARED_ASSETS / "handdata" / "mediapipe_video" / "human_joint_right.pkl"
QUEST = SHARED_ASSETS / "handdata" / "quest3_webxr" / "derived" / "quest3_hands_world.npz"
needs_mediapipe = pytest.mark.skipif(not MEDIAPIPE.is_file(), reason=f"no MediaPipe capture {MEDIAPIPE}")
needs_quest = pytest.mark.skipif(not QUEST.is_file(), reason=f"no Quest capture {QUEST}")

#: OpenXR joints of each finger from its metacarpal to its tip.
CHAINS = {f: [JOINT_INDEX[n] for n in OPENXR_JOINTS if n.startswith(f"{f}_")]
          for f in ("thumb", "index", "middle", "ring", "little")}


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (degrees) between rotation matrices (...,3,3)."""
    tr = np.einsum("...ij,...ij->...", a, b)
    return np.degrees(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))


def _flexion_rad(pos: np.ndarray, finger: str) -> np.ndarray:
    """Per frame, the summed bend (radians) between consecutive bones of a human finger, from
    the wrist (long fingers) or the thumb's base: how far it is curled."""
    chain = CHAINS[finger] if finger == "thumb" else [WRIST, *CHAINS[finger][1:]]
    bones = np.diff(pos[:, chain], axis=1)
    bones /= np.linalg.norm(bones, axis=-1, keepdims=True)
    return np.arccos(np.clip(np.einsum("tij,tij->ti", bones[:, :-1], bones[:, 1:]), -1, 1)).sum(1)


def _grasp_keypoints(side: str, n: int, wrist_pos_m: np.ndarray, wrist_rot: np.ndarray
                     ) -> tuple[np.ndarray, HumanHand, list[HandPose]]:
    """The parametric hand closing from relaxed to a power grasp over ``n`` frames at a fixed
    wrist pose: its 21 MediaPipe-order keypoints (n,21,3) in the world, the hand and poses."""
    human = HumanHand(0.185, side)
    poses = [lerp_pose(HandPose.relaxed(), HandPose.power(), s) for s in np.linspace(0, 1, n)]
    pts = np.stack([human.joints(p, wrist_pos_m, wrist_rot)[0] for p in poses])
    return pts[:, list(MEDIAPIPE_TO_OPENXR)], human, poses


# --- conversion --------------------------------------------------------------------------------


@pytest.mark.parametrize("side", ["right", "left"])
def test_parametric_hand_round_trips_in_every_space(side: str) -> None:
    """Keypoints of the parametric hand come back as its own joints: positions exact, the wrist
    frame exact (the palm-plane rule is calibrated on this template), fingers within 12°, the
    template's radii; "xr" input lands on the same world frames and "hand" input on the anchor."""
    from teleop.input.frames import mujoco_to_xr_positions

    wrist_p, wrist_r = np.array([0.3, -0.1, 1.0]), rpy_deg_to_mat(np.array([20.0, -30.0, 40.0]))
    pts, human, poses = _grasp_keypoints(side, 5, wrist_p, wrist_r)
    frames, _, _ = keypoint_frames(pts, fmt="mediapipe", side=side, fps=25.0, space="world")
    assert [f.device_time_s for f in frames] == pytest.approx([0.0, 0.04, 0.08, 0.12, 0.16])
    assert all(f.hand(side).tracked and f.hand("right" if side == "left" else "left") is None
               for f in frames)
    for frame, pose in zip(frames, poses, strict=True):
        hs = frame.hand(side)
        true_p, true_r = human.joints(pose, wrist_p, wrist_r)
        np.testing.assert_allclose(hs.positions[list(MEDIAPIPE_TO_OPENXR)], true_p[list(MEDIAPIPE_TO_OPENXR)],
                                   atol=1e-12)
        rot = quat_to_mat(hs.orientations_wxyz)
        assert _angle_deg(rot[WRIST], true_r[WRIST]) < 0.01
        long_joints = [j for f in ("index", "middle", "ring", "little") for j in CHAINS[f][1:]]
        assert _angle_deg(rot[long_joints], true_r[long_joints]).max() < 12.0
        np.testing.assert_allclose(hs.radii, human.radii, rtol=0.02)

    xr_frames, _, _ = keypoint_frames(mujoco_to_xr_positions(pts), fmt="mediapipe", side=side,
                                      fps=25.0, space="xr")
    for a, b in zip(frames, xr_frames, strict=True):
        np.testing.assert_allclose(a.hand(side).positions, b.hand(side).positions, atol=1e-12)
    full = np.stack([human.joints(p, wrist_p, wrist_r)[0] for p in poses])   # 26 OpenXR joints
    for joints in (full, full[:, 1:]):                                         # with/without PALM
        xr_joints, _, _ = keypoint_frames(mujoco_to_xr_positions(joints), fmt="openxr", side=side,
                                          fps=25.0, space="xr")
        np.testing.assert_allclose(np.stack([f.hand(side).positions for f in xr_joints]), full,
                                   atol=1e-12)
    anchor = Anchor.from_rpy([0.1, 0.2, 1.1], [0.0, 0.0, 90.0])
    hand_frames, _, _ = keypoint_frames(pts, fmt="mediapipe", side=side, fps=25.0, space="hand",
                                        anchor=anchor)
    wrists = np.stack([f.hand(side).positions[WRIST] for f in hand_frames])
    np.testing.assert_allclose(wrists.mean(axis=0), anchor.wrist_pos_m, atol=1e-12)
    rot = quat_to_mat(hand_frames[0].hand(side).orientations_wxyz[WRIST])
    assert _angle_deg(rot, anchor.wrist_rot) < 0.01   # a fixed wrist: mean pose = every pose


def test_missing_keypoints_make_untracked_frames() -> None:
    """A frame with a NaN keypoint or coincident points is the hand lost (untracked), as a
    headset reports it; the others are unaffected, and every frame is valid on the wire."""
    from teleop.messages import decode, encode

    pts, _, _ = _grasp_keypoints("right", 6, np.array([0.3, 0.0, 1.0]), np.eye(3))
    pts[1, 7] = np.nan
    pts[4] = 0.0
    frames, _, _ = keypoint_frames(pts, fmt="mediapipe", side="right", fps=30.0, space="world")
    tracked = [True, False, True, True, False, True]
    assert [f.right.tracked for f in frames] == tracked
    assert [decode(encode(f)).right.tracked for f in frames] == tracked   # valid on the wire


@needs_quest
def test_derived_joint_frames_match_a_real_headsets() -> None:
    """From only the 21 MediaPipe-like joints of the Quest 3 capture, the derived frames agree
    with the runtime's own (both hands): wrist within 3° (median), finger phalanges within 12°,
    the thumb within 30°, and the synthesised metacarpal bases within 15 mm."""
    from teleop.input.webxr import webxr_to_openxr_arrays

    data = np.load(QUEST)
    for side in ("left", "right"):
        v = data[f"{side}_valid"]
        pos, quat, _, ok = webxr_to_openxr_arrays(data[f"{side}_joint_pos"][v],
                                                  data[f"{side}_joint_quat_xyzw"][v],
                                                  data[f"{side}_joint_radius"][v])
        pos, quat = pos[ok.all(axis=1)], quat[ok.all(axis=1)]
        runtime = quat_to_mat(quat)
        completed = openxr_positions(pos[:, list(MEDIAPIPE_TO_OPENXR)], "mediapipe")
        err = np.median(_angle_deg(joint_rotations(completed, side), runtime), axis=0)
        assert err[WRIST] < 3.0, side
        phalanges = [j for f in ("index", "middle", "ring", "little") for j in CHAINS[f][1:]]
        assert err[phalanges].max() < 12.0, (side, err[phalanges])
        assert err[CHAINS["thumb"]].max() < 30.0, (side, err[CHAINS["thumb"]])
        mc = [CHAINS[f][0] for f in ("index", "middle", "ring", "little")]
        assert np.median(np.linalg.norm(completed[:, mc] - pos[:, mc], axis=-1)) < 0.015


# --- retargeting quality -----------------------------------------------------------------------


@needs_mediapipe
@needs_menagerie
def test_mediapipe_video_retargets_faithfully(shadow) -> None:
    """The MediaPipe video (621 frames, 30 fps, right hand, wrist-relative metres) through the
    mink retargeter: every frame is retargeted; relative to the wrist the robot fingertips sit
    where the scaled human finger pads are (median ≤ 12 mm, p95 ≤ 25 mm per finger); and each
    robot finger's summed joint angle follows the human finger's curl (Pearson r ≥ 0.85 for the
    fingers, ≥ 0.6 for the thumb) — while against the human curl half the video later it does
    not (r < 0.5), so the correlation measures following, not just motion."""
    from teleop.retarget.retargeter import Retargeter
    from teleop.retarget.trace import retarget_frames

    traj = load_trajectory(MEDIAPIPE)
    assert traj.points.shape == (621, 21, 3) and traj.object_pos_m is None
    frames, _, _ = keypoint_frames(traj.points, fmt="mediapipe", side="right", fps=30.0, space="hand")
    assert frames[-1].device_time_s == pytest.approx(620 / 30)
    retargeter = Retargeter(shadow)
    retargeter.calibrate_scale(frames)
    assert retargeter.operator_length_m == pytest.approx(0.189, abs=0.005)   # metres, an adult hand
    trace = retarget_frames(retargeter, frames)
    assert not trace.held.any()

    pos = np.stack([f.right.positions for f in frames])
    wrist = pos[:, WRIST][:, None]
    tips = [JOINT_INDEX[retargeter.mapping.fingers[f]] for f in retargeter.finger_names]
    r_base = quat_to_mat(trace.base_quat_wxyz)
    robot_tips = trace.base_pos_m[:, None] + np.einsum("tij,tfj->tfi", r_base, trace.tip_positions_m)
    # the robot's pulps follow the operator's pads: the tip joint moved by its radius to the
    # palmar side (the tip frame's +z points to the back of the finger)
    quat = np.stack([f.right.orientations_wxyz for f in frames])
    radii = np.stack([f.right.radii for f in frames])
    pads = pos[:, tips] - radii[:, tips, None] * quat_to_mat(quat[:, tips])[..., 2]
    err = np.linalg.norm((robot_tips - wrist) - retargeter.scale * (pads - wrist), axis=-1)
    assert np.median(err, axis=0).max() <= 0.012, np.median(err, axis=0)
    assert np.percentile(err, 95, axis=0).max() <= 0.025, np.percentile(err, 95, axis=0)

    human_finger = dict(zip(retargeter.finger_names, ("thumb", "index", "middle", "ring", "little"),
                            strict=True))
    names = list(shadow.joint_names)
    for fc in shadow.config.fingers:
        human = _flexion_rad(pos, human_finger[fc.name])
        robot = trace.q[:, [names.index(j) for j in fc.joints]].sum(axis=1)
        r = np.corrcoef(human, robot)[0, 1]
        assert r >= (0.6 if fc.name == "thumb" else 0.85), (fc.name, r)
        assert abs(np.corrcoef(np.roll(human, len(human) // 2), robot)[0, 1]) < 0.5, fc.name


# --- files, CLI, sessions ----------------------------------------------------------------------


def _write_bad(tmp_path: Path, name: str, points: np.ndarray, **extra: np.ndarray) -> Path:
    path = tmp_path / name
    np.savez(path, keypoints=points, **extra) if path.suffix == ".npz" else np.save(path, points)
    return path


@needs_mediapipe
def test_bad_input_is_one_line_naming_the_file_and_writes_nothing(tmp_path: Path, capsys) -> None:
    pts = load_trajectory(MEDIAPIPE).points[:50]
    swapped = pts.copy()
    swapped[:, 5:9], swapped[:, 17:21] = pts[:, 17:21], pts[:, 5:9]     # index ↔ little
    cases = {
        "image.npy": (pts / 0.6 + [0.45, 0.5, 0.0], ["--side", "right"], "image landmarks"),
        "mm.npy": (pts * 1000.0, ["--side", "right"], "metres"),
        "order.npy": (swapped, ["--side", "right"], "order"),
        "mano.npy": (pts[:, [0, 5, 6, 7, 9, 10, 11, 17, 18, 19, 13, 14, 15, 1, 2, 3, 4, 8, 12, 16, 20]],
                     ["--side", "right"], "order"),                     # MANO's native order
        "mirror.npy": (pts, ["--side", "left", "--hand", "shadow_right"], "side"),
        "joints.npy": (pts[:, :20], ["--side", "right"], "expected shape"),
        "obj.npz": (pts, ["--side", "right"], "object"),
    }
    out = tmp_path / "out" / "s.mcap"
    for name, (points, flags, words) in cases.items():
        extra = {"object_pos_m": np.zeros((len(points), 3))} if name.endswith(".npz") else {}
        src = _write_bad(tmp_path, name, points, **extra)
        assert main(["import-trajectory", str(src), *flags, "--out", str(out)]) == 2, name
        err = " ".join(capsys.readouterr().err.split())
        assert name in err and words in err, (name, err)
        assert not out.exists() and not (out.parent.exists() and any(out.parent.iterdir()))
    capsys.readouterr()


@needs_mediapipe
def test_pickles_only_hold_arrays(tmp_path: Path) -> None:
    import pickle

    from teleop.input.keypoints import KeypointError

    evil = tmp_path / "evil.pkl"
    evil.write_bytes(pickle.dumps(print))          # any callable would run on a plain load
    with pytest.raises(KeypointError, match=r"evil\.pkl.*refusing to unpickle builtins\.print"):
        load_trajectory(evil)
    assert load_trajectory(MEDIAPIPE).points.dtype == np.float64


@needs_menagerie
def test_synthesised_grasp_with_an_object_rerecords_through_the_bridge(tmp_path: Path, capsys) -> None:
    """A hand closing over a box placed at a known pose → npz → ``dexaug import-trajectory`` →
    session (every frame on /hands, every object pose on /tf, the first in the metadata) →
    ``rerecord`` through the real bridge on zenoh loopback → one retargeted state per frame
    and the box on the table where it was given (x, y and yaw)."""
    from teleop.bridge.config import load_bridge_config
    from teleop.bridge.rerecord import rerecord
    from teleop.record.session import open_session

    n, yaw = 36, 30.0
    box_p = np.array([0.42, 0.06, 0.85])                  # tracking space: table top at z 0.8
    box_q = np.array([math.cos(math.radians(yaw) / 2), 0.0, 0.0, math.sin(math.radians(yaw) / 2)])
    # palm down over the box, knuckles above its centre, closing around its top
    pts, _, _ = _grasp_keypoints("right", n, box_p + np.array([-0.09, 0.0, 0.09]), np.eye(3))
    src = tmp_path / "grasp.npz"
    np.savez(src, keypoints=pts, object_pos_m=np.tile(box_p, (n, 1)),
             object_quat_wxyz=np.tile(box_q, (n, 1)))
    raw = tmp_path / "grasp.mcap"
    assert main(["import-trajectory", str(src), "--side", "right", "--space", "world", "--fps",
                 "30", "--hand", "shadow_right", "--object", "box", "--out", str(raw)]) == 0
    assert f"{n} frames" in capsys.readouterr().out
    session = open_session(raw)
    meta = session.metadata
    assert session.counts["/hands"] == n and session.counts["/tf"] == n
    assert meta["object"] == "box" and meta["hand"] == "shadow_right" and meta["side"] == "right"
    assert meta["source_format"] == "mediapipe" and meta["source_space"] == "world"
    np.testing.assert_allclose(meta["object_pos_m"], box_p)
    tf = [m.payload["transforms"][0] for m in session.messages("/tf")]
    assert {t["child_frame_id"] for t in tf} == {"object"}
    np.testing.assert_allclose([list(t["translation"].values()) for t in tf], np.tile(box_p, (n, 1)))

    out = open_session(rerecord(raw, tmp_path / "full.mcap"))
    assert out.counts["/hands"] == n and out.counts["/state"] == n and not out.truncated
    states = [p for _, p in out.json_messages("/state")]
    assert all(s["tracked"] for s in states)                  # every frame was retargeted
    offset = load_bridge_config().world_offset_m
    obj = np.array(states[0]["object_pos_m"])
    np.testing.assert_allclose(obj[:2], box_p[:2] + offset[:2], atol=1e-3)
    r = quat_to_mat(np.array(states[0]["object_quat_wxyz"]))
    assert math.degrees(math.atan2(r[1, 0], r[0, 0])) == pytest.approx(yaw, abs=0.5)
    assert obj[2] == pytest.approx(0.05, abs=0.01)            # resting on the table (z 0)
    hands_in = [m.data for m in session.messages("/hands")]
    assert [m.data for m in out.messages("/hands")] == hands_in   # the bridge saw our bytes
