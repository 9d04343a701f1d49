"""The page → ingest WebSocket binary frame: one XR frame of head and hand joint poses.

The headset page (``teleop/input/web/app.js``) sends one binary WebSocket message per XR frame;
:func:`parse_ws_frame` turns it into a :class:`teleop.messages.HandFrame` (MuJoCo world, wxyz,
through :func:`teleop.input.webxr.hand_frame_from_webxr`) and :func:`pack_ws_frame` builds the
same bytes from Python for tests and benchmarks. Layout (little-endian)::

    offset size type        field
    0      4    bytes       magic b"DXW1"
    4      4    uint32      seq (the page's XR frame counter)
    8      8    float64     t_ms: XR frame time, epoch milliseconds (timeOrigin + frame time)
    16     1    uint8       flags: bit0 left present, bit1 right present
    17     3    -           padding
    20     28   float32[7]  head pose: position (m), quaternion xyzw, XR reference space
    48     800  float32     per present hand (left first): 25 × (p3, q4 xyzw, radius),
                            WebXR joint order; NaN for a joint the runtime did not report
"""

from __future__ import annotations

import struct
from collections.abc import Mapping

import numpy as np

from teleop.input.webxr import NUM_WEBXR_JOINTS, hand_frame_from_webxr
from teleop.messages import HandFrame, MessageError

__all__ = ["WS_HAND_SIZE", "WS_HEADER_SIZE", "WS_MAGIC", "pack_ws_frame", "parse_ws_frame"]

Array = np.ndarray

WS_MAGIC = b"DXW1"
_WS_HEADER = struct.Struct("<4sIdB3x7f")
WS_HEADER_SIZE = _WS_HEADER.size  # 48
_HAND_FLOATS = NUM_WEBXR_JOINTS * 8
WS_HAND_SIZE = 4 * _HAND_FLOATS  # 800


def pack_ws_frame(seq: int, t_ms: float, head_xr: Array, hands: Mapping[str, Array]) -> bytes:
    """The page's binary frame (module docstring) from Python: ``head_xr`` (7,) p3 q4 xyzw;
    ``hands`` side → (25, 8) rows p3 q4 radius. Tests and benchmarks speak the page's protocol
    with it; the page itself builds the same bytes in ``app.js``."""
    flags = (1 if "left" in hands else 0) | (2 if "right" in hands else 0)
    parts = [_WS_HEADER.pack(WS_MAGIC, int(seq) & 0xFFFFFFFF, float(t_ms), flags,
                             *np.asarray(head_xr, float).reshape(7).tolist())]
    for side in ("left", "right"):
        if side in hands:
            parts.append(np.asarray(hands[side], "<f4").reshape(_HAND_FLOATS).tobytes())
    return b"".join(parts)


def parse_ws_frame(data: bytes, receive_time_s: float, *, source: str = "webxr") -> HandFrame:
    """One binary message of the page → a :class:`HandFrame` (MuJoCo world, wxyz).

    Raises :class:`MessageError` naming what is wrong (size, magic, flags); joint values the page
    marked missing (NaN) become invalid joints, a hand without a wrist becomes untracked.
    """
    size = len(data)
    if size < WS_HEADER_SIZE:
        raise MessageError(f"web hand frame: {size} bytes, the header needs {WS_HEADER_SIZE}")
    magic, seq, t_ms, flags, *head = _WS_HEADER.unpack_from(data, 0)
    if magic != WS_MAGIC:
        raise MessageError(f"web hand frame: magic {magic!r}, expected {WS_MAGIC!r}")
    if flags & ~3:
        raise MessageError(f"web hand frame: unknown flag bits {flags:#04x} (0x03 are used)")
    sides = [s for s, bit in (("left", 1), ("right", 2)) if flags & bit]
    expected = WS_HEADER_SIZE + len(sides) * WS_HAND_SIZE
    if size != expected:
        raise MessageError(f"web hand frame: {size} bytes, expected {expected} for "
                           f"{len(sides)} hand(s)")
    hands = {}
    for k, side in enumerate(sides):
        j = np.frombuffer(data, "<f4", _HAND_FLOATS, WS_HEADER_SIZE + k * WS_HAND_SIZE)
        j = j.reshape(NUM_WEBXR_JOINTS, 8).astype(float)
        hands[side] = (j[:, :3], j[:, 3:7], j[:, 7])
    head_arr = np.asarray(head, float)
    if not np.isfinite(head_arr).all():
        raise MessageError(f"web hand frame: non-finite head pose {head_arr.tolist()}")
    return hand_frame_from_webxr(int(seq), float(t_ms) * 1e-3, head_arr[:3], head_arr[3:],
                                 hands, receive_time_s=receive_time_s, source=source)
