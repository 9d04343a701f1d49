"""Retargeting the real Quest 3 capture onto the Shadow Hand with mink (teleop.retarget).

Everything runs the real solver (mink + daqp) on the real recording in
``../shared/assets/handdata``; the module skips where the assets are absent.
"""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

from sim.errors import ConfigError
from sim.hand.config import hand_dir, hand_names
from sim.paths import SHARED_ASSETS
from sim.transforms import pose_mul, quat_angle, quat_to_mat
from teleop.input.iwer import iwer_hand_frames, load_iwer_capture
from teleop.messages import JOINT_INDEX, HandFrame, HandState
from teleop.retarget.config import (
    TELEOP_CONFIG,
    hand_mapping_path,
    load_hand_mapping,
    load_retarget_config,
)
from teleop.retarget.result import HOLD_REASONS
from teleop.retarget.retargeter import Retargeter, RetargetError
from teleop.retarget.trace import retarget_frames, summarise_errors

CAPTURE = SHARED_ASSETS / "handdata" / "quest3_webxr" / "cap.min.js"
# the `shadow` fixture (conftest) skips where the Menagerie models are absent
pytestmark = pytest.mark.skipif(not CAPTURE.is_file(), reason=f"no hand capture {CAPTURE}")

THUMB, INDEX = JOINT_INDEX["thumb_tip"], JOINT_INDEX["index_tip"]


@pytest.fixture(scope="module")
def frames() -> list[HandFrame]:
    return iwer_hand_frames(load_iwer_capture(CAPTURE))


@pytest.fixture(scope="module")
def config():
    """teleop.toml's [retarget] without the One-Euro input filter: these tests check the IK's
    geometry frame by frame against the operator's *raw* joints (the filter is
    tests/test_retarget_closed_loop.py's)."""
    from teleop.retarget.input_filter import InputFilterSettings

    return dataclasses.replace(load_retarget_config(),
                               input_filter=InputFilterSettings(min_cutoff_hz=0.0))


@pytest.fixture(scope="module")
def retargeter(shadow, config, frames) -> Retargeter:
    rt = Retargeter(shadow, config)
    rt.calibrate_scale(frames)
    return rt


@pytest.fixture(scope="module")
def trace(retargeter, frames):
    retargeter.reset()
    return retarget_frames(retargeter, frames)


def operator_thumb_index_m(frames: list[HandFrame]) -> np.ndarray:
    return np.array([np.linalg.norm(f.right.positions[THUMB] - f.right.positions[INDEX])
                     if f.right is not None and f.right.tracked else np.nan for f in frames])


def robot_thumb_index_m(hand, q: np.ndarray) -> np.ndarray:
    tips = hand.fingertip_sites(q)  # pulp sites, base frame
    thumb, fore = hand.finger_names.index("thumb"), hand.finger_names.index("forefinger")
    return np.linalg.norm(tips[:, thumb] - tips[:, fore], axis=-1)


# --- the real capture ---------------------------------------------------------------------------


def test_capture_runs_within_limits_and_coupled(shadow, frames, trace, retargeter):
    assert len(trace.q) == len(frames) and trace.q.shape[1] == shadow.nq
    assert np.isfinite(trace.q).all()
    assert (trace.q >= shadow.lower - 1e-9).all() and (trace.q <= shadow.upper + 1e-9).all()
    for finger in shadow.config.fingers:
        for follower, (leader, coef) in finger.coupled_to.items():
            f, ld = shadow.joint_names.index(follower), shadow.joint_names.index(leader)
            np.testing.assert_array_equal(trace.q[:, f], coef * trace.q[:, ld])
    for name in retargeter.frozen_joints:  # the floating base carries the wrist
        j = shadow.joint_names.index(name)
        np.testing.assert_allclose(trace.q[:, j], retargeter.q_rest[j], atol=1e-9)
    # only the one frame of the hand segment without a right hand is held
    missing = sum(f.right is None for f in frames)
    assert trace.held.sum() == missing == retargeter.held_counts["no_hand"]
    summary = summarise_errors(trace)
    assert summary["frames"] == len(frames) and summary["held"] == missing
    # the convention mapping puts every target within the robot's reach most of the time
    for name, stats in summary["fingers"].items():
        assert stats["median_m"] < 0.012, (name, stats)


def test_scale_calibration(retargeter, frames, config):
    # bone-chain length wrist → middle tip of this operator: ≈ 19.3 cm; Shadow ≈ 19.1 cm
    assert 0.18 < retargeter.operator_length_m < 0.21
    assert retargeter.scale == pytest.approx(
        retargeter.robot_length_m / retargeter.operator_length_m * config.scale)
    with pytest.raises(RetargetError, match="right hand"):
        Retargeter(retargeter.hand, config).calibrate_scale(
            [dataclasses.replace(f, right=None) for f in frames[:5]])


def test_wrist_and_targets_follow_the_operator(shadow, frames, trace, retargeter):
    """World-frame composition: base pose ∘ palm offset = reported palm pose, and a target
    (no pinch active) is the operator's fingertip pad (the tip joint moved by its radius along
    −z of its frame, to the palmar skin) scaled about the operator's wrist."""
    op = operator_thumb_index_m(frames)
    i = int(np.nanargmax(op))
    hs = frames[i].right
    ppos, pquat = shadow.palm_pose(trace.q[i])
    palm_p, palm_q = pose_mul(trace.base_pos_m[i], trace.base_quat_wxyz[i], ppos[0], pquat[0])
    np.testing.assert_allclose(palm_p, trace.palm_pos_m[i], atol=1e-9)
    assert quat_angle(palm_q, trace.palm_quat_wxyz[i]) < 1e-6
    wrist = hs.joint_position("wrist")
    tips_world, _ = pose_mul(trace.base_pos_m[i][None], trace.base_quat_wxyz[i][None],
                             trace.tip_targets_m[i],
                             np.tile([1.0, 0, 0, 0], (len(trace.finger_names), 1)))
    mapping = retargeter.mapping.fingers
    idx = [JOINT_INDEX[mapping[f]] for f in trace.finger_names]
    dorsal = quat_to_mat(hs.orientations_wxyz[idx])[:, :, 2]
    pads = hs.positions[idx] - hs.radii[idx, None] * dorsal
    assert (np.linalg.norm(pads - hs.positions[idx], axis=1) > 0.004).all()  # Quest: 5–9 mm
    expected = wrist + retargeter.scale * (pads - wrist)
    np.testing.assert_allclose(tips_world, expected, atol=1e-9)


def test_pinch_and_open_distances(shadow, frames, trace):
    """Acceptance: the pinch frames give a robot thumb–index pulp distance under 2 cm, the
    open-hand frames (operator > 8 cm) over 6 cm."""
    op = operator_thumb_index_m(frames)
    robot = robot_thumb_index_m(shadow, trace.q)
    pinch = np.argsort(np.nan_to_num(op, nan=np.inf))[:3]
    assert op[pinch].max() < 0.025  # the capture's closest pinch: ≈ 2.0–2.2 cm
    assert (robot[pinch] < 0.02).all(), (op[pinch], robot[pinch])
    open_ = op > 0.08
    assert open_.sum() > 100
    assert (robot[open_] > 0.06).all(), robot[open_].min()


def test_deterministic(shadow, config, frames, trace, retargeter):
    again = Retargeter(shadow, config)
    again.calibrate_scale(frames)
    second = retarget_frames(again, frames)
    for key in ("q", "base_pos_m", "base_quat_wxyz", "tip_targets_m", "tip_errors_m", "held"):
        np.testing.assert_array_equal(getattr(trace, key), getattr(second, key), err_msg=key)
    retargeter.reset()
    third = retarget_frames(retargeter, frames)
    np.testing.assert_array_equal(trace.q, third.q)


def test_vanished_hand_holds_last_output(shadow, config, frames):
    rt = Retargeter(shadow, config)
    seq = list(frames[100:160])
    bad_tip = dataclasses.replace(seq[30].right)
    bad_tip.valid = bad_tip.valid.copy()
    bad_tip.positions = bad_tip.positions.copy()
    bad_tip.valid[INDEX] = False
    bad_tip.positions[INDEX] = np.nan
    seq[20] = dataclasses.replace(seq[20], right=None)
    seq[25] = dataclasses.replace(seq[25], right=HandState.untracked())
    seq[30] = dataclasses.replace(seq[30], right=bad_tip)
    results = [rt.step_frame(f) for f in seq]
    for k, reason in ((20, "no_hand"), (25, "untracked"), (30, "invalid_joints")):
        assert results[k].held and results[k].reason == reason
        np.testing.assert_array_equal(results[k].q, results[k - 1].q)
        np.testing.assert_array_equal(results[k].base_pos_m, results[k - 1].base_pos_m)
        assert not results[k + 1].held
        assert rt.held_counts[reason] == 1
    assert rt.held_frames == 3 and set(rt.held_counts) == set(HOLD_REASONS)
    # a hand that never appeared: the rest posture, held, no crash
    rt.reset()
    first = rt.step(None, 0.0)
    assert first.held and np.array_equal(first.q, rt.q_rest)


# --- configuration errors -----------------------------------------------------------------------


def _bad_copy(tmp_path: Path, src: Path, old: str, new: str) -> Path:
    """A copy of config file ``src`` (under ``<tmp>/<its folder>/``) with ``old`` → ``new``."""
    path = tmp_path / src.parent.name / src.name
    path.parent.mkdir()
    shutil.copy(src, path)
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize(("old", "new", "key"), [
    ("iterations = 1", 'iterations = "one"', "retarget.iterations"),
    ("iterations = 1", "iteratons = 1", "retarget: unknown key(s) ['iteratons']"),
    ('solver = "daqp"', 'solver = "nosuchsolver"', "retarget.solver"),
    ("filter_time_constant_s = 0.015", "filter_time_constant_s = -1",
     "retarget.filter_time_constant_s"),
])
def test_config_errors_name_file_and_key(tmp_path, old, new, key):
    path = _bad_copy(tmp_path, TELEOP_CONFIG, old, new)
    with pytest.raises(ConfigError) as exc:
        load_retarget_config(path)
    assert "configs/teleop.toml" in str(exc.value) and key in str(exc.value)


@pytest.mark.parametrize(("old", "new", "key"), [
    ('thumb = "thumb_tip"', 'thumb = "thumb_nail"', "fingers.thumb"),
    ('side = "right"', 'side = "up"', "side"),
    ('scale_finger = "middle"', 'scale_finger = "palm"', "scale_finger"),
    ("wrist_pos_m = ", "wrist_position_m = ", "unknown key(s) ['wrist_position_m']"),
])
def test_hand_mapping_errors_name_file_and_key(tmp_path, shadow, old, new, key):
    path = _bad_copy(tmp_path, hand_mapping_path(shadow.name), old, new)
    with pytest.raises(ConfigError) as exc:
        load_hand_mapping(shadow.name, path)
    assert f"{shadow.name}/retarget.toml: {key}" in str(exc.value)


def test_mapping_comes_from_the_hand_folder(shadow, config):
    mapping = config.hand(shadow.name)
    assert mapping.file == hand_mapping_path(shadow.name) == hand_dir(shadow.name) / "retarget.toml"
    assert mapping.hand == shadow.name and set(mapping.fingers) <= set(shadow.finger_names)


def test_unmapped_hand_and_finger(tmp_path, shadow, config):
    unmapped = next((h for h in hand_names() if not hand_mapping_path(h).is_file()), "no_such_hand")
    with pytest.raises(ConfigError, match=rf"hands/{unmapped}/retarget\.toml: missing file"):
        config.hand(unmapped)
    path = _bad_copy(tmp_path, hand_mapping_path(shadow.name), "little = ", "pinky = ")
    bad = dataclasses.replace(config, hands={shadow.name: load_hand_mapping(shadow.name, path)})
    with pytest.raises(ConfigError, match=r"retarget\.toml: fingers: unknown finger.*pinky"):
        Retargeter(shadow, bad)
