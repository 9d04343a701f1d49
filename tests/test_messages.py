"""Hand-tracking messages, XR→MuJoCo conventions and the WebXR/IWER converters.

The capture tests run on the real Quest 3 recording in ``../shared/assets/handdata`` and check
our own conversion against the derived reference file (used only as a check, never as input).
"""

from __future__ import annotations

import logging
import struct
import time
from pathlib import Path

import numpy as np
import pytest

from sim import transforms
from sim.errors import DexaugError
from sim.paths import SHARED_ASSETS
from teleop.input import frames
from teleop.input.iwer import IwerCapture, iwer_hand_frames, load_iwer_capture
from teleop.input.js_literal import CaptureError, parse_js_literal
from teleop.input.webxr import WEBXR_JOINTS, from_webxr_joints, hand_frame_from_webxr
from teleop.messages import (
    FINGERTIPS,
    HEADER_SIZE,
    JOINT_INDEX,
    NUM_JOINTS,
    OPENXR_JOINTS,
    SCHEMA_VERSION,
    HandFrame,
    HandState,
    MessageError,
    decode,
    encode,
    validate,
)

logger = logging.getLogger(__name__)

HANDDATA = SHARED_ASSETS / "handdata" / "quest3_webxr"
CAPTURE = HANDDATA / "cap.min.js"
REFERENCE = HANDDATA / "derived" / "quest3_hands_world.npz"
needs_capture = pytest.mark.skipif(not (CAPTURE.is_file() and REFERENCE.is_file()),
                                   reason=f"hand capture assets not found under {HANDDATA}")


def random_quats_wxyz(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def f32(x: np.ndarray) -> np.ndarray:
    """Values exactly representable on the wire (float32), so round trips compare exactly."""
    return np.asarray(x, dtype=np.float32).astype(np.float64)


def random_hand(rng: np.random.Generator, *, n_invalid: int = 0,
                tracked: bool = True) -> HandState:
    valid = np.ones(NUM_JOINTS, bool)
    if n_invalid:
        valid[rng.choice(np.arange(2, NUM_JOINTS), n_invalid, replace=False)] = False
    pos = f32(rng.uniform(-1, 2, (NUM_JOINTS, 3)))
    quat = f32(random_quats_wxyz(rng, NUM_JOINTS))
    radii = f32(rng.uniform(0.005, 0.02, NUM_JOINTS))
    pos[~valid] = np.nan
    quat[~valid] = np.nan
    radii[~valid] = np.nan
    if not tracked:
        valid[:] = False
    return HandState(pos, quat, radii, valid, tracked)


def random_frame(rng: np.random.Generator, left: bool, right: bool, **hand_kw) -> HandFrame:
    return HandFrame(
        seq=int(rng.integers(0, 2**63)), device_time_s=float(rng.uniform(0, 1e5)),
        receive_time_s=float(rng.uniform(0, 1e5)),
        head_position=f32(rng.uniform(-1, 2, 3)),
        head_orientation_wxyz=f32(random_quats_wxyz(rng, 1)[0]),
        left=random_hand(rng, **hand_kw) if left else None,
        right=random_hand(rng, **hand_kw) if right else None,
        source="test-ü")


# --- frames ---------------------------------------------------------------------------------


def test_xr_to_mujoco_is_a_proper_rotation_with_the_documented_axes() -> None:
    c = frames.XR_TO_MUJOCO
    assert np.linalg.det(c) == pytest.approx(1.0)
    np.testing.assert_allclose(c @ c.T, np.eye(3), atol=1e-15)
    # 1 m in front of the viewer (XR −Z) is MuJoCo +X; XR up (+Y) is MuJoCo +Z; XR +X is −Y
    np.testing.assert_allclose(frames.xr_to_mujoco_positions([0, 0, -1]), [1, 0, 0])
    np.testing.assert_allclose(frames.xr_to_mujoco_positions([0, 1, 0]), [0, 0, 1])
    np.testing.assert_allclose(frames.xr_to_mujoco_positions([1, 0, 0]), [0, -1, 0])
    np.testing.assert_allclose(transforms.quat_to_mat(frames.XR_TO_MUJOCO_QUAT_WXYZ), c,
                               atol=1e-15)
    p = np.random.default_rng(0).normal(size=(5, 7, 3))
    np.testing.assert_allclose(frames.mujoco_to_xr_positions(frames.xr_to_mujoco_positions(p)),
                               p, atol=1e-15)


def test_quaternion_conversion_agrees_with_rotating_vectors() -> None:
    rng = np.random.default_rng(1)
    q_xr_wxyz = random_quats_wxyz(rng, 50)
    q_xr_xyzw = transforms.quat_wxyz_to_xyzw(q_xr_wxyz)
    np.testing.assert_array_equal(transforms.quat_xyzw_to_wxyz(q_xr_xyzw), q_xr_wxyz)
    v = rng.normal(size=(50, 3))
    q_mj = frames.xr_to_mujoco_quat_wxyz(q_xr_xyzw)
    # rotate in XR then map == map then rotate with the converted quaternion
    lhs = frames.xr_to_mujoco_positions(transforms.rotate(q_xr_wxyz, v))
    rhs = transforms.rotate(q_mj, frames.xr_to_mujoco_positions(v))
    np.testing.assert_allclose(lhs, rhs, atol=1e-12)
    np.testing.assert_allclose(transforms.rotate(q_xr_wxyz, v),
                               transforms.rotate(q_xr_wxyz, v), atol=1e-12)
    np.testing.assert_allclose(frames.mujoco_to_xr_quat_xyzw(q_mj), q_xr_xyzw, atol=1e-12)
    # the XR identity orientation stays the identity
    np.testing.assert_allclose(frames.xr_to_mujoco_quat_wxyz([0, 0, 0, 1]), [1, 0, 0, 0],
                               atol=1e-15)


def test_pose_helpers_compose_invert_and_commute_with_the_conversion() -> None:
    rng = np.random.default_rng(2)
    pa, qa = rng.normal(size=(4, 3)), random_quats_wxyz(rng, 4)
    pb, qb = rng.normal(size=(4, 3)), random_quats_wxyz(rng, 4)
    pi, qi = transforms.pose_inv(pa, qa)
    p_id, q_id = transforms.pose_mul(pa, qa, pi, qi)
    np.testing.assert_allclose(p_id, 0, atol=1e-12)
    np.testing.assert_allclose(np.abs(q_id[:, 0]), 1, atol=1e-12)
    # compose in XR then convert == convert then compose
    pc, qc = transforms.pose_mul(pa, qa, pb, qb)
    conv = [frames.xr_to_mujoco_pose(p, transforms.quat_wxyz_to_xyzw(q))
            for p, q in ((pa, qa), (pb, qb), (pc, qc))]
    p2, q2 = transforms.pose_mul(*conv[0], *conv[1])
    np.testing.assert_allclose(p2, conv[2][0], atol=1e-12)
    np.testing.assert_allclose(q2, conv[2][1], atol=1e-12)
    assert np.isnan(frames.quat_normalize_wxyz(np.zeros(4))).all()


# --- messages -------------------------------------------------------------------------------


def test_joint_table_follows_openxr() -> None:
    assert len(OPENXR_JOINTS) == 26 and OPENXR_JOINTS[0] == "palm"
    assert OPENXR_JOINTS[1] == "wrist" and OPENXR_JOINTS[25] == "little_tip"
    assert FINGERTIPS == (5, 10, 15, 20, 25)
    assert issubclass(MessageError, DexaugError)


@pytest.mark.parametrize(("left", "right"), [(True, True), (True, False), (False, True),
                                             (False, False)])
def test_round_trip_is_exact_for_wire_precision_values(left: bool, right: bool) -> None:
    rng = np.random.default_rng(10 + 2 * left + right)
    for n_invalid in (0, 3):
        frame = random_frame(rng, left, right, n_invalid=n_invalid)
        data = encode(frame)
        assert len(data) == HEADER_SIZE + len(frame.source.encode()) + 858 * (left + right)
        back = decode(data)
        assert back == frame
        assert back.hands == frame.hands
        assert encode(back) == data


def test_round_trip_of_untracked_hand_and_float64_values() -> None:
    rng = np.random.default_rng(3)
    frame = random_frame(rng, True, True)
    frame.left = HandState.untracked()
    frame.right.positions = frame.right.positions + 1e-9  # not float32-representable
    back = decode(encode(frame))
    assert back.left == HandState.untracked() and not back.left.tracked
    np.testing.assert_allclose(back.right.positions, frame.right.positions, atol=1e-6)


@pytest.fixture
def wire() -> bytes:
    return encode(random_frame(np.random.default_rng(4), True, True))


@pytest.mark.parametrize("cut", [0, 3, 5, 10, 40, HEADER_SIZE - 1, HEADER_SIZE + 3, 500,
                                 HEADER_SIZE + 6 + 858, -1])
def test_truncated_messages_are_rejected(wire: bytes, cut: int) -> None:
    with pytest.raises(MessageError, match="truncated"):
        decode(wire[:cut])


def test_foreign_magic_version_joint_count_and_trailing_bytes(wire: bytes) -> None:
    with pytest.raises(MessageError, match="magic"):
        decode(b"XXHF" + wire[4:])
    with pytest.raises(MessageError, match=f"expected {SCHEMA_VERSION}, got 99"):
        decode(wire[:4] + struct.pack("<H", 99) + wire[6:])
    with pytest.raises(MessageError, match="expected 26 joints per hand, got 25"):
        decode(wire[:62] + struct.pack("<H", 25) + wire[64:])
    with pytest.raises(MessageError, match="trailing"):
        decode(wire + b"\0")
    with pytest.raises(MessageError, match="flag"):
        decode(wire[:6] + struct.pack("<H", 0x10 | 3) + wire[8:])


def test_nan_in_a_valid_joint_is_rejected_on_decode_and_encode(wire: bytes) -> None:
    # left hand positions start after the header and the 6-byte source; joint 10 = index_tip
    offset = HEADER_SIZE + len("test-ü".encode()) + 10 * 12 + 4
    bad = wire[:offset] + struct.pack("<f", np.nan) + wire[offset + 4:]
    with pytest.raises(MessageError, match="index_tip"):
        decode(bad)
    frame = decode(wire)
    frame.right.positions[3, 2] = np.inf
    with pytest.raises(MessageError, match=r"right.*thumb_proximal"):
        encode(frame)
    frame.right.valid[3] = False  # an invalid joint may hold anything
    decode(encode(frame))


def test_validate_rejects_broken_invariants() -> None:
    rng = np.random.default_rng(5)
    frame = random_frame(rng, True, False)
    frame.left.positions = frame.left.positions[:25]
    with pytest.raises(MessageError, match=r"left.positions: expected shape \(26, 3\)"):
        validate(frame)
    frame = random_frame(rng, True, False)
    frame.left.valid[JOINT_INDEX["wrist"]] = False
    with pytest.raises(MessageError, match="wrist"):
        validate(frame)
    frame = random_frame(rng, False, True)
    frame.right.orientations_wxyz[4] *= 2
    with pytest.raises(MessageError, match="unit quaternion"):
        validate(frame)
    frame = random_frame(rng, False, False)
    frame.device_time_s = float("nan")
    with pytest.raises(MessageError, match="device_time_s"):
        validate(frame)
    frame = random_frame(rng, False, False)
    frame.schema_version = 2
    with pytest.raises(MessageError, match="expected 1, got 2"):
        encode(frame)


# --- WebXR converter ------------------------------------------------------------------------


def synthetic_webxr_hand(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    p = rng.uniform(-0.5, 1.5, (25, 3))
    q = transforms.quat_wxyz_to_xyzw(random_quats_wxyz(rng, 25))
    r = rng.uniform(0.005, 0.02, 25)
    return p, q, r


def test_from_webxr_joints_converts_and_synthesises_palm() -> None:
    p, q, r = synthetic_webxr_hand(np.random.default_rng(6))
    hand = from_webxr_joints(p, q, r)
    assert hand.tracked and hand.valid.all()
    np.testing.assert_allclose(hand.positions[1:], frames.xr_to_mujoco_positions(p))
    np.testing.assert_allclose(hand.orientations_wxyz[1:], frames.xr_to_mujoco_quat_wxyz(q),
                               atol=1e-12)
    mc = WEBXR_JOINTS.index("middle-finger-metacarpal")
    palm_xr = 0.5 * (p[mc] + p[mc + 1])
    np.testing.assert_allclose(hand.positions[0], frames.xr_to_mujoco_positions(palm_xr))
    np.testing.assert_allclose(hand.orientations_wxyz[0], hand.orientations_wxyz[mc + 1])
    assert hand.radii[0] == r[mc]
    validate_frame = HandFrame(0, 0.0, 0.0, np.zeros(3), np.array([1.0, 0, 0, 0]), left=hand)
    assert decode(encode(validate_frame)).left.valid.all()


def test_from_webxr_joints_marks_missing_joints() -> None:
    p, q, r = synthetic_webxr_hand(np.random.default_rng(7))
    p[9] = np.nan  # index-finger-tip
    q[11] = 0.0  # middle-finger-phalanx-proximal: a zero quaternion is no orientation
    hand = from_webxr_joints(p, q, r)
    assert hand.tracked
    assert not hand.valid[JOINT_INDEX["index_tip"]]
    assert not hand.valid[JOINT_INDEX["middle_proximal"]]
    assert not hand.valid[JOINT_INDEX["palm"]]  # needs both middle-metacarpal joints
    assert hand.valid.sum() == 23
    p[0] = np.nan
    hand = from_webxr_joints(p, q, r)
    assert not hand.tracked and not hand.valid[JOINT_INDEX["wrist"]]
    with pytest.raises(MessageError, match="25 WebXR joints"):
        from_webxr_joints(p[:24], q[:24], r[:24])


def test_hand_frame_from_webxr_builds_a_wire_ready_frame() -> None:
    rng = np.random.default_rng(8)
    frame = hand_frame_from_webxr(7, 1.5, [0.0, 1.6, 0.0], [0.0, 0.0, 0.0, 1.0],
                                  {"right": synthetic_webxr_hand(rng)}, receive_time_s=1.52)
    assert frame.hands == ("right",) and frame.source == "webxr"
    np.testing.assert_allclose(frame.head_position, [0.0, 0.0, 1.6])
    back = decode(encode(frame))
    assert back.seq == 7 and back.receive_time_s == 1.52 and back.right.valid.all()


# --- JavaScript literal reader ----------------------------------------------------------------


def test_js_literal_reader_handles_minifier_syntax() -> None:
    src = ("var b=1,a={x:!0,y:!1,'q':'it\\'s .5 a:b',d:.5,e:-.25,f:5.,g:[1,2,],h:void 0,"
           "j:{1:2},k:1e-3,n:/* c */3};export{a as capture};")
    assert parse_js_literal(src) == {"x": True, "y": False, "q": "it's .5 a:b", "d": 0.5,
                                     "e": -0.25, "f": 5.0, "g": [1, 2], "h": None,
                                     "j": {"1": 2}, "k": 1e-3, "n": 3}
    assert parse_js_literal('{"schema": [], "frames": []}') == {"schema": [], "frames": []}
    escapes = r"""var a={s:'a\'b\\u"c\n\x41\u00e9\u{1F600}',t:"x\'y\"z"};export{a as capture}"""
    assert parse_js_literal(escapes) == {"s": 'a\'b\\u"c\nAé\U0001F600', "t": "x'y\"z"}


def test_unparseable_capture_names_file_and_position(tmp_path: Path) -> None:
    bad = tmp_path / "broken.js"
    bad.write_text("var a={schema:[],\nframes:[[1,2 3]]};export{a as capture};")
    with pytest.raises(CaptureError, match=r"broken\.js.*line 2, column 14"):
        load_iwer_capture(bad)
    bad.write_text("export const other = 1;")
    with pytest.raises(CaptureError, match=r"broken\.js: no `capture`"):
        load_iwer_capture(bad)
    with pytest.raises(CaptureError, match=r"missing\.js"):
        load_iwer_capture(tmp_path / "missing.js")


# --- the real Quest 3 capture -----------------------------------------------------------------


@pytest.fixture(scope="module")
def capture() -> IwerCapture:
    return load_iwer_capture(CAPTURE)


@pytest.fixture(scope="module")
def hand_frames(capture: IwerCapture) -> list[HandFrame]:
    return iwer_hand_frames(capture)


@needs_capture
def test_capture_parses(capture: IwerCapture) -> None:
    assert len(capture.frames) == 1796
    assert sorted(i for i, s in capture.schema.items() if s.has_hand) == [2, 3]
    assert capture.schema[2].handedness == "left" and capture.schema[3].handedness == "right"
    assert 19 < capture.duration_s < 21
    assert iwer_hand_frames(capture, keep_handless=True)[0].hands == ()


@needs_capture
def test_capture_hand_frames_match_the_reference_conversion(
        hand_frames: list[HandFrame]) -> None:
    ref = np.load(REFERENCE)
    assert len(hand_frames) == 757 == len(ref["t_s"])
    assert (hand_frames[0].seq, hand_frames[-1].seq) == (955, 1711)
    np.testing.assert_allclose([f.device_time_s for f in hand_frames], ref["t_s"], atol=1e-9)
    np.testing.assert_allclose([f.head_position for f in hand_frames],
                               frames.xr_to_mujoco_positions(ref["head_pos"]), atol=2e-3)
    for side in ("left", "right"):
        present = np.array([f.hand(side) is not None for f in hand_frames])
        np.testing.assert_array_equal(present, ref[f"{side}_valid"])
        hands = [f.hand(side) for f in hand_frames if f.hand(side) is not None]
        assert all(h.tracked and h.valid.all() for h in hands)
        pos = np.stack([h.positions for h in hands])
        want = frames.xr_to_mujoco_positions(ref[f"{side}_joint_pos"][present])
        err = np.abs(pos[:, 1:] - want).max()
        logger.info("%s hand: %d frames, max joint position error %.2e m", side, len(hands), err)
        assert err < 2e-3
        q = np.stack([h.orientations_wxyz for h in hands])[:, 1:]
        q_ref = frames.quat_normalize_wxyz(
            frames.xr_to_mujoco_quat_wxyz(ref[f"{side}_joint_quat_xyzw"][present]))
        assert (np.abs(np.sum(q * q_ref, axis=-1)) > 1 - 1e-5).all()
        # PALM between the wrist and the middle knuckle; joint +X runs along the bone
        palm, wrist = pos[:, JOINT_INDEX["palm"]], pos[:, JOINT_INDEX["wrist"]]
        knuckle = pos[:, JOINT_INDEX["middle_proximal"]]
        palm_reach = np.linalg.norm(palm - wrist, axis=1)
        assert (palm_reach < np.linalg.norm(knuckle - wrist, axis=1)).all()
        i, j = JOINT_INDEX["index_proximal"], JOINT_INDEX["index_intermediate"]
        bone = pos[:, j] - pos[:, i]
        x_axis = transforms.rotate(np.stack([h.orientations_wxyz[i] for h in hands]),
                                         np.array([1.0, 0.0, 0.0]))
        cos = np.sum(bone * x_axis, axis=1) / np.linalg.norm(bone, axis=1)
        assert np.median(cos) > 0.95


@needs_capture
def test_capture_right_hand_opens_and_pinches(hand_frames: list[HandFrame]) -> None:
    rights = [f.right for f in hand_frames if f.right is not None]
    thumb, index = JOINT_INDEX["thumb_tip"], JOINT_INDEX["index_tip"]
    d = np.array([np.linalg.norm(h.positions[thumb] - h.positions[index]) for h in rights])
    gap = d - np.array([h.radii[thumb] + h.radii[index] for h in rights])
    logger.info("right thumb-index tip distance: min %.4f m, max %.4f m; min surface gap "
                "%.4f m", d.min(), d.max(), gap.min())
    # joint centres sit inside the fingertips: a pinch leaves the centres about r1 + r2 apart
    assert d.min() < 0.025 and gap.min() < 0.005
    assert d.max() > 0.06


@needs_capture
def test_capture_frames_survive_the_wire(hand_frames: list[HandFrame]) -> None:
    blobs = [encode(f) for f in hand_frames]
    t0 = time.perf_counter()
    decoded = [decode(b) for b in blobs]
    per_frame = (time.perf_counter() - t0) / len(blobs)
    logger.info("decode: %.1f us per frame (%d bytes for two hands)", per_frame * 1e6,
                max(len(b) for b in blobs))
    for f, g in zip(hand_frames, decoded, strict=True):
        assert g.seq == f.seq and g.source == "iwer:cap.min.js"
        for side in f.hands:
            np.testing.assert_allclose(g.hand(side).positions, f.hand(side).positions,
                                       atol=1e-6)
