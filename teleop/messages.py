"""The hand-tracking frame: one message per tracking update, both hands plus the head.

Why a schema of our own: the same frame travels over zenoh (``dexaug/<rig>/hands``), into MCAP
recordings and out of replay, from several sources (WebXR page, native streamer apps, IWER
captures). Fixing one versioned layout here means the bridge never cares where a frame came
from, and an old recording read by newer code fails loudly instead of being misread.

In memory (:class:`HandFrame`) everything is already in the MuJoCo world convention (+Z up,
metres, quaternions **wxyz**, see :mod:`teleop.input.frames`): converters in :mod:`teleop.input.webxr`
and the ingest code convert once, on arrival. Each hand has the 26 OpenXR
``XR_EXT_hand_tracking`` joints, PALM first (:data:`OPENXR_JOINTS`).

Wire layout (schema version 1), all little-endian, no padding, fixed except for the source
string and which hands are present::

    offset  size  type        field
    0       4     bytes       magic b"DXHF"
    4       2     uint16      schema version (1)
    6       2     uint16      flags: bit0 left present, bit1 right present,
                                     bit2 left tracked, bit3 right tracked (other bits 0)
    8       8     uint64      seq (sender's frame counter)
    16      8     float64     device_time_s (sender's clock, seconds)
    24      8     float64     receive_time_s (ingest clock, seconds)
    32      12    float32[3]  head position, metres (MuJoCo world)
    44      16    float32[4]  head orientation, quaternion **xyzw**
    60      2     uint16      n: length of the source string in bytes
    62      2     uint16      J: joints per hand (26)
    64      n     utf-8       source (e.g. "webxr", "iwer:cap.min.js")
    then for each present hand, left before right, J joints each:
            12J   float32     positions (J,3), metres
            16J   float32     orientations (J,4), quaternion **xyzw**
            4J    float32     radii (J,), metres
            J     uint8       valid (J,), 0 or 1

A frame with both hands is 64 + n + 2 × 858 bytes (about 1.8 kB). Arrays travel as float32:
tracking is millimetre-accurate, and float32 keeps micrometres at 100 m; times stay float64
because a float32 clock loses milliseconds after a few hours. ``decode(encode(f))`` therefore
equals ``f`` up to float32 rounding of the arrays (exactly, when they hold float32 values).
Quaternions are xyzw on the wire, as DESIGN section 3 and Foxglove expect; the swap to wxyz
happens in :func:`encode`/:func:`decode` and nowhere else.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from sim.errors import DexaugError

Array = np.ndarray

SCHEMA_VERSION = 1
MAGIC = b"DXHF"

#: The 26 OpenXR ``XR_EXT_hand_tracking`` joints in ``XrHandJointEXT`` order (PALM = 0).
OPENXR_JOINTS: tuple[str, ...] = (
    "palm", "wrist",
    "thumb_metacarpal", "thumb_proximal", "thumb_distal", "thumb_tip",
    "index_metacarpal", "index_proximal", "index_intermediate", "index_distal", "index_tip",
    "middle_metacarpal", "middle_proximal", "middle_intermediate", "middle_distal", "middle_tip",
    "ring_metacarpal", "ring_proximal", "ring_intermediate", "ring_distal", "ring_tip",
    "little_metacarpal", "little_proximal", "little_intermediate", "little_distal", "little_tip",
)
NUM_JOINTS = len(OPENXR_JOINTS)
#: Joint name → index in :data:`OPENXR_JOINTS`.
JOINT_INDEX: dict[str, int] = {name: i for i, name in enumerate(OPENXR_JOINTS)}
PALM = JOINT_INDEX["palm"]
WRIST = JOINT_INDEX["wrist"]
#: Fingertip joint indices, thumb first (the retargeting targets).
FINGERTIPS: tuple[int, ...] = tuple(JOINT_INDEX[f"{f}_tip"]
                                    for f in ("thumb", "index", "middle", "ring", "little"))

_HEADER = struct.Struct("<4sHHQdd3f4fHH")
HEADER_SIZE = _HEADER.size  # 64
_FLAG_LEFT, _FLAG_RIGHT, _FLAG_LEFT_TRACKED, _FLAG_RIGHT_TRACKED = 1, 2, 4, 8
_KNOWN_FLAGS = 15
_JOINT_BYTES = 12 + 16 + 4 + 1
#: Tolerance on |q| − 1 for a valid joint or head quaternion: loose on purpose (it catches
#: zero or garbage quaternions; senders are expected to normalise, ingest does).
QUAT_NORM_TOL = 1e-2
_NORM2_MIN, _NORM2_MAX = (1.0 - QUAT_NORM_TOL) ** 2, (1.0 + QUAT_NORM_TOL) ** 2


class MessageError(DexaugError):
    """A hand-tracking message is malformed: truncated, not ours (magic), from another schema
    version, non-finite where it must be finite, or with arrays of the wrong size."""


def _hand_bytes(num_joints: int) -> int:
    return num_joints * _JOINT_BYTES


def _arrays_equal(a: Array, b: Array) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))


@dataclass(eq=False)
class HandState:
    """One hand, 26 OpenXR joints (PALM first), MuJoCo world frame.

    positions: (26,3) metres. orientations_wxyz: (26,4) unit quaternions, joint frame → world
    (local axes as described in :mod:`teleop.input.frames`). radii: (26,) metres. valid: (26,) bool —
    joints not valid may hold anything (NaN by convention) and must be ignored. tracked: the
    runtime reports the hand as tracked (its wrist is valid); consumers check this first.
    """

    positions: Array
    orientations_wxyz: Array
    radii: Array
    valid: Array
    tracked: bool = True

    def __post_init__(self) -> None:
        # Fixed dtypes make equality, hashing into recordings and the wire format predictable.
        self.positions = np.asarray(self.positions, dtype=np.float64)
        self.orientations_wxyz = np.asarray(self.orientations_wxyz, dtype=np.float64)
        self.radii = np.asarray(self.radii, dtype=np.float64)
        self.valid = np.asarray(self.valid, dtype=bool)
        self.tracked = bool(self.tracked)

    @classmethod
    def untracked(cls) -> HandState:
        """A hand the runtime lost: all joints invalid (NaN), tracked=False."""
        return cls(np.full((NUM_JOINTS, 3), np.nan), np.full((NUM_JOINTS, 4), np.nan),
                   np.full(NUM_JOINTS, np.nan), np.zeros(NUM_JOINTS, bool), tracked=False)

    def joint_position(self, name: str) -> Array:
        """Position (3,) metres of the joint called ``name`` (see :data:`OPENXR_JOINTS`)."""
        return self.positions[JOINT_INDEX[name]]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, HandState):
            return NotImplemented
        return (self.tracked == other.tracked and _arrays_equal(self.valid, other.valid)
                and _arrays_equal(self.positions, other.positions)
                and _arrays_equal(self.orientations_wxyz, other.orientations_wxyz)
                and _arrays_equal(self.radii, other.radii))

    __hash__ = None  # type: ignore[assignment]  # mutable arrays


@dataclass(eq=False)
class HandFrame:
    """One tracking update: head pose, both hands (None when the source has no such hand),
    timestamps. All poses in the MuJoCo world (metres, quaternions wxyz).

    seq: the sender's frame counter (gaps reveal dropped frames). device_time_s: the sender's
    clock, seconds. receive_time_s: the ingest clock when the frame arrived, seconds (latency =
    difference, when the clocks are synchronised). source: who produced it ("webxr", "iwer:…").
    """

    seq: int
    device_time_s: float
    receive_time_s: float
    head_position: Array
    head_orientation_wxyz: Array
    left: HandState | None = None
    right: HandState | None = None
    source: str = ""
    schema_version: int = SCHEMA_VERSION

    def __post_init__(self) -> None:
        self.head_position = np.asarray(self.head_position, dtype=np.float64)
        self.head_orientation_wxyz = np.asarray(self.head_orientation_wxyz, dtype=np.float64)

    @property
    def hands(self) -> tuple[str, ...]:
        """The sides present in this frame, left first."""
        return tuple(side for side in ("left", "right") if getattr(self, side) is not None)

    def hand(self, side: str) -> HandState | None:
        """The hand called ``side`` ("left" or "right")."""
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        return self.left if side == "left" else self.right

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, HandFrame):
            return NotImplemented
        return (self.schema_version == other.schema_version and self.seq == other.seq
                and _float_eq(self.device_time_s, other.device_time_s)
                and _float_eq(self.receive_time_s, other.receive_time_s)
                and _arrays_equal(self.head_position, other.head_position)
                and _arrays_equal(self.head_orientation_wxyz, other.head_orientation_wxyz)
                and self.left == other.left and self.right == other.right
                and self.source == other.source)

    __hash__ = None  # type: ignore[assignment]


def _float_eq(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


# --- validation ---------------------------------------------------------------------------------


def _check_shape(name: str, arr: Array, shape: tuple[int, ...]) -> None:
    if arr.shape != shape:
        raise MessageError(f"{name}: expected shape {shape}, got {arr.shape}")


def validate_hand(hand: HandState, side: str = "hand") -> None:
    """Check one hand's invariants; raises :class:`MessageError` naming the side and joint."""
    _check_shape(f"{side}.positions", hand.positions, (NUM_JOINTS, 3))
    _check_shape(f"{side}.orientations_wxyz", hand.orientations_wxyz, (NUM_JOINTS, 4))
    _check_shape(f"{side}.radii", hand.radii, (NUM_JOINTS,))
    _check_shape(f"{side}.valid", hand.valid, (NUM_JOINTS,))
    v = hand.valid
    # one vectorised pass for the common (valid) case; diagnostics only when something fails
    q = hand.orientations_wxyz
    norm2 = np.einsum("ij,ij->i", q, q)
    quat_ok = (norm2 >= _NORM2_MIN) & (norm2 <= _NORM2_MAX)  # NaN compares False, silently
    joint_ok = np.isfinite(hand.positions).all(axis=1) & quat_ok & (hand.radii >= 0.0)
    if not joint_ok[v].all():
        bad = v & ~np.isfinite(hand.positions).all(axis=1)
        if bad.any():
            names = [OPENXR_JOINTS[i] for i in np.flatnonzero(bad)]
            raise MessageError(f"{side}: non-finite position (NaN/inf) in joints marked valid: "
                               f"{', '.join(names)}")
        bad = v & ~quat_ok
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise MessageError(f"{side}: joint {OPENXR_JOINTS[i]} is marked valid but its "
                               f"orientation is not a unit quaternion "
                               f"(|q| = {math.sqrt(norm2[i]):.6g})")
        i = int(np.flatnonzero(v & ~joint_ok)[0])
        raise MessageError(f"{side}: joint {OPENXR_JOINTS[i]} is marked valid but its radius "
                           f"is {hand.radii[i]!r} (expected a finite value >= 0 m)")
    if hand.tracked and not v[WRIST]:
        raise MessageError(f"{side}: tracked=True but the wrist joint is not valid "
                           "(a tracked hand must have a valid wrist)")


def validate(frame: HandFrame) -> None:
    """Check a frame's invariants, raising :class:`MessageError` at the first violation.

    Schema version is :data:`SCHEMA_VERSION`; seq fits uint64; times are finite (NaN would
    poison latency statistics and replay ordering); the head pose is finite with a unit
    quaternion; each present hand has 26-joint arrays, and every joint marked valid has a
    finite position, a unit quaternion and a radius >= 0; a tracked hand has a valid wrist;
    the source encodes to at most 65535 bytes of UTF-8.
    """
    if frame.schema_version != SCHEMA_VERSION:
        raise MessageError(f"schema version: expected {SCHEMA_VERSION}, got "
                           f"{frame.schema_version}")
    if not isinstance(frame.seq, int | np.integer) or not 0 <= int(frame.seq) < 2**64:
        raise MessageError(f"seq must be an integer in [0, 2**64), got {frame.seq!r}")
    for name in ("device_time_s", "receive_time_s"):
        value = getattr(frame, name)
        if not math.isfinite(value):
            raise MessageError(f"{name} must be finite, got {value!r}")
    _check_shape("head_position", frame.head_position, (3,))
    _check_shape("head_orientation_wxyz", frame.head_orientation_wxyz, (4,))
    if not all(map(math.isfinite, frame.head_position.tolist())):
        raise MessageError(f"head_position must be finite, got {frame.head_position}")
    n = math.sqrt(float(frame.head_orientation_wxyz @ frame.head_orientation_wxyz))
    if not abs(n - 1.0) <= QUAT_NORM_TOL:
        raise MessageError(f"head_orientation_wxyz is not a unit quaternion (|q| = {n:.6g})")
    for side in ("left", "right"):
        hand = getattr(frame, side)
        if hand is not None:
            if not isinstance(hand, HandState):
                raise MessageError(f"{side} must be a HandState or None, got "
                                   f"{type(hand).__name__}")
            validate_hand(hand, side)
    if len(frame.source.encode("utf-8")) > 0xFFFF:
        raise MessageError("source is longer than 65535 bytes of UTF-8")


# --- wire format --------------------------------------------------------------------------------


def encode(frame: HandFrame) -> bytes:
    """Serialise a frame to the wire layout of the module docstring (validates it first, so
    an invalid frame never leaves the process)."""
    validate(frame)
    source = frame.source.encode("utf-8")
    flags = 0
    for present, tracked, hand in ((_FLAG_LEFT, _FLAG_LEFT_TRACKED, frame.left),
                                   (_FLAG_RIGHT, _FLAG_RIGHT_TRACKED, frame.right)):
        if hand is not None:
            flags |= present | (tracked if hand.tracked else 0)
    hq = frame.head_orientation_wxyz
    parts = [_HEADER.pack(MAGIC, SCHEMA_VERSION, flags, int(frame.seq),
                          float(frame.device_time_s), float(frame.receive_time_s),
                          *frame.head_position.tolist(), hq[1], hq[2], hq[3], hq[0],
                          len(source), NUM_JOINTS),
             source]
    for hand in (frame.left, frame.right):
        if hand is None:
            continue
        parts.append(hand.positions.astype("<f4").tobytes())
        parts.append(hand.orientations_wxyz[:, [1, 2, 3, 0]].astype("<f4").tobytes())
        parts.append(hand.radii.astype("<f4").tobytes())
        parts.append(hand.valid.astype(np.uint8).tobytes())
    return b"".join(parts)


def _decode_hand(buf: memoryview, offset: int, num_joints: int, tracked: bool) -> HandState:
    j = num_joints
    f32 = np.dtype("<f4")
    pos = np.frombuffer(buf, f32, 3 * j, offset).reshape(j, 3)
    offset += 12 * j
    quat_xyzw = np.frombuffer(buf, f32, 4 * j, offset).reshape(j, 4)
    offset += 16 * j
    radii = np.frombuffer(buf, f32, j, offset)
    offset += 4 * j
    valid_raw = np.frombuffer(buf, np.uint8, j, offset)
    if valid_raw.max() > 1:
        raise MessageError(f"hand valid flags must be 0 or 1, got {sorted(set(valid_raw))}")
    return HandState(pos, quat_xyzw[:, [3, 0, 1, 2]], radii, valid_raw.astype(bool), tracked)


def decode(data: bytes | bytearray | memoryview) -> HandFrame:
    """Parse and validate one wire message; raises :class:`MessageError` saying what is wrong
    (truncation with expected vs actual byte counts, foreign magic, schema version expected vs
    got, joint count, non-finite valid joints, ...)."""
    buf = memoryview(data).cast("B")
    size = len(buf)
    if size < 6:
        raise MessageError(f"truncated message: {size} bytes, a header needs {HEADER_SIZE}")
    magic = bytes(buf[:4])
    if magic != MAGIC:
        raise MessageError(f"not a dexaug hand frame: magic {magic!r}, expected {MAGIC!r}")
    (version,) = struct.unpack_from("<H", buf, 4)
    if version != SCHEMA_VERSION:
        raise MessageError(f"unsupported hand frame schema version: expected {SCHEMA_VERSION}, "
                           f"got {version}")
    if size < HEADER_SIZE:
        raise MessageError(f"truncated message: {size} bytes, the header needs {HEADER_SIZE}")
    (_, _, flags, seq, t_dev, t_recv, hx, hy, hz, qx, qy, qz, qw, n_source,
     num_joints) = _HEADER.unpack_from(buf, 0)
    if flags & ~_KNOWN_FLAGS:
        raise MessageError(f"unknown flag bits {flags:#06x} (schema {SCHEMA_VERSION} uses 0x000f)")
    for present, tracked_bit in ((_FLAG_LEFT, _FLAG_LEFT_TRACKED),
                                 (_FLAG_RIGHT, _FLAG_RIGHT_TRACKED)):
        if flags & tracked_bit and not flags & present:
            raise MessageError(f"flags {flags:#06x} mark a hand tracked that is not present")
    if num_joints != NUM_JOINTS:
        raise MessageError(f"wrong joint count: expected {NUM_JOINTS} joints per hand, got "
                           f"{num_joints}")
    sides = [s for s, bit in (("left", _FLAG_LEFT), ("right", _FLAG_RIGHT)) if flags & bit]
    expected = HEADER_SIZE + n_source + len(sides) * _hand_bytes(num_joints)
    if size < expected:
        raise MessageError(f"truncated message: {size} bytes, expected {expected} (header "
                           f"{HEADER_SIZE} + source {n_source} + {len(sides)} hand(s) × "
                           f"{_hand_bytes(num_joints)})")
    if size > expected:
        raise MessageError(f"message has {size - expected} trailing bytes: expected {expected} "
                           f"bytes for {len(sides)} hand(s) of {num_joints} joints, got {size}")
    try:
        source = bytes(buf[HEADER_SIZE:HEADER_SIZE + n_source]).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MessageError(f"source string is not valid UTF-8: {exc}") from None
    offset = HEADER_SIZE + n_source
    hands: dict[str, HandState] = {}
    for side in sides:
        tracked = bool(flags & (_FLAG_LEFT_TRACKED if side == "left" else _FLAG_RIGHT_TRACKED))
        hands[side] = _decode_hand(buf, offset, num_joints, tracked)
        offset += _hand_bytes(num_joints)
    frame = HandFrame(seq=seq, device_time_s=t_dev, receive_time_s=t_recv,
                      head_position=np.array([hx, hy, hz]),
                      head_orientation_wxyz=np.array([qw, qx, qy, qz]),
                      left=hands.get("left"), right=hands.get("right"), source=source,
                      schema_version=version)
    validate(frame)
    return frame
