"""IWER capture files: recorded WebXR sessions as :class:`teleop.messages.HandFrame` lists.

IWER captures (``cap.min.js``, written by the ``iwer`` npm package's ActionRecorder) are a
minified ES module ``export {capture}`` holding a JavaScript object literal
``{schema: [[index, InputSchema], ...], frames: [row, ...]}`` (read by
:func:`teleop.input.js_literal.parse_js_literal`). A frame row is
``[t_ms, head p3, head q4 (xyzw), input...]`` and an input is
``[schema_index, target-ray p3 q4, [grip p3 q4] if hasGrip, [25 × (p3, q4, radius)] if hasHand,
[buttons..., axes...] if hasGamepad]``. Head, target-ray and grip poses are in the session's
reference space (``local-floor``); **hand joint poses are relative to that hand's target-ray
space** (the recorder calls ``fillPoses(joints, targetRaySpace)``), so reference-space joint
poses are ``T_ray ∘ T_joint``. Values are rounded to 1e-3 by the recorder. Units: metres,
seconds (``time_s``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim import transforms
from teleop.input import frames
from teleop.input.js_literal import CaptureError, parse_js_literal
from teleop.input.webxr import NUM_WEBXR_JOINTS, WEBXR_JOINTS, webxr_to_openxr_arrays
from teleop.messages import WRIST, HandFrame, HandState

__all__ = ["IwerCapture", "IwerFrame", "IwerInput", "IwerInputSchema", "iwer_hand_frames",
           "load_iwer_capture"]

logger = logging.getLogger(__name__)

Array = np.ndarray


@dataclass(frozen=True)
class IwerInputSchema:
    """One input source as the recorder first saw it (``InputSchema`` in IWER)."""

    index: int
    handedness: str
    target_ray_mode: str
    profiles: tuple[str, ...]
    has_grip: bool
    has_hand: bool
    has_gamepad: bool
    joint_sequence: tuple[str, ...] = ()
    num_buttons: int = 0
    num_axes: int = 0


@dataclass
class IwerInput:
    """One input's data in one frame, XR convention (local-floor space, +Y up, xyzw).

    joints_local: (25, 8) rows ``[p3 (m), q4 xyzw, radius (m)]`` in WebXR joint order, poses
    relative to the target-ray space; None for controllers (or a hand the runtime lost).
    """

    schema_index: int
    target_ray_position: Array
    target_ray_quat_xyzw: Array
    grip_position: Array | None = None
    grip_quat_xyzw: Array | None = None
    joints_local: Array | None = None
    gamepad: list[Any] | None = None


@dataclass
class IwerFrame:
    """One recorded frame: capture row ``index``, time in seconds (the page's
    ``performance.now()`` clock), head pose in local-floor (xyzw), and the inputs seen."""

    index: int
    time_s: float
    head_position: Array
    head_quat_xyzw: Array
    inputs: tuple[IwerInput, ...]


@dataclass
class IwerCapture:
    """A parsed IWER ActionRecorder capture: input schemas by index, and the frames."""

    path: Path
    schema: dict[int, IwerInputSchema]
    frames: list[IwerFrame]

    @property
    def duration_s(self) -> float:
        return self.frames[-1].time_s - self.frames[0].time_s if self.frames else 0.0


def _parse_schema(entries: Any, where: str) -> dict[int, IwerInputSchema]:
    if not isinstance(entries, list):
        raise CaptureError(f"{where}: `schema` must be a list of [index, InputSchema] pairs")
    out: dict[int, IwerInputSchema] = {}
    for k, entry in enumerate(entries):
        try:
            index, s = entry
            joints = tuple(s.get("jointSequence") or ())
            if s.get("hasHand") and len(joints) != NUM_WEBXR_JOINTS:
                raise ValueError(f"jointSequence has {len(joints)} joints, expected 25")
            unknown = set(joints) - set(WEBXR_JOINTS)
            if unknown:
                raise ValueError(f"unknown WebXR joints {sorted(unknown)}")
            out[int(index)] = IwerInputSchema(
                index=int(index), handedness=str(s.get("handedness", "none")),
                target_ray_mode=str(s.get("targetRayMode", "")),
                profiles=tuple(s.get("profiles") or ()), has_grip=bool(s.get("hasGrip")),
                has_hand=bool(s.get("hasHand")), has_gamepad=bool(s.get("hasGamepad")),
                joint_sequence=joints, num_buttons=int(s.get("numButtons") or 0),
                num_axes=int(s.get("numAxes") or 0))
        except (TypeError, ValueError, AttributeError) as exc:
            raise CaptureError(f"{where}: schema entry {k} is malformed: {exc}") from None
    return out


def _parse_input(raw: Any, schema: dict[int, IwerInputSchema], where: str) -> IwerInput:
    if not isinstance(raw, list) or len(raw) < 8:
        raise CaptureError(f"{where}: expected [index, ray p3 q4, ...], got "
                           f"{str(raw)[:60]}")
    index = int(raw[0])
    if index not in schema:
        raise CaptureError(f"{where}: input index {index} is not in the schema "
                           f"(known: {sorted(schema)})")
    s = schema[index]
    ray = np.asarray(raw[1:8], dtype=float)
    inp = IwerInput(index, ray[:3], ray[3:])
    rest = list(raw[8:])
    expected = int(s.has_grip) + int(s.has_hand) + int(s.has_gamepad)
    if len(rest) != expected:
        raise CaptureError(f"{where}: input {index} has {len(rest)} trailing fields, its schema "
                           f"(grip={s.has_grip}, hand={s.has_hand}, gamepad={s.has_gamepad}) "
                           f"says {expected}")
    if s.has_grip:
        grip = rest.pop(0)
        if grip:
            g = np.asarray(grip, dtype=float)
            if g.shape != (7,):
                raise CaptureError(f"{where}: grip pose has {g.size} values, expected 7")
            inp.grip_position, inp.grip_quat_xyzw = g[:3], g[3:]
    if s.has_hand:
        hand = rest.pop(0)
        if hand:
            j = np.asarray(hand, dtype=float)
            if j.shape != (8 * NUM_WEBXR_JOINTS,):
                raise CaptureError(f"{where}: hand joints have {j.size} values, expected "
                                   f"{8 * NUM_WEBXR_JOINTS} (25 × p3 q4 radius)")
            j = j.reshape(NUM_WEBXR_JOINTS, 8)
            if s.joint_sequence != WEBXR_JOINTS:
                order = [s.joint_sequence.index(n) for n in WEBXR_JOINTS]
                j = j[order]
            inp.joints_local = j
    if s.has_gamepad:
        inp.gamepad = rest.pop(0)
    return inp


def load_iwer_capture(path: str | Path) -> IwerCapture:
    """Parse an IWER ActionRecorder capture (``cap.min.js`` or its JSON form).

    Raises :class:`CaptureError` naming the file and, for syntax errors, the line and column;
    for structural errors, the frame and input.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CaptureError(f"{path}: cannot read the capture: {exc}") from None
    data = parse_js_literal(text, "capture", path=str(path))
    if not isinstance(data, dict) or "schema" not in data or "frames" not in data:
        keys = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise CaptureError(f"{path}: the capture must be an object with `schema` and `frames`, "
                           f"got {keys}")
    schema = _parse_schema(data["schema"], str(path))
    rows = data["frames"]
    if not isinstance(rows, list):
        raise CaptureError(f"{path}: `frames` must be a list")
    out: list[IwerFrame] = []
    for i, row in enumerate(rows):
        where = f"{path}: frame {i}"
        if not isinstance(row, list) or len(row) < 8:
            raise CaptureError(f"{where}: expected [t_ms, head p3 q4, inputs...], got "
                               f"{str(row)[:60]}")
        try:
            head = np.asarray(row[1:8], dtype=float)
            inputs = tuple(_parse_input(raw, schema, f"{where}, input {k}")
                           for k, raw in enumerate(row[8:]))
            out.append(IwerFrame(i, float(row[0]) * 1e-3, head[:3], head[3:], inputs))
        except (TypeError, ValueError) as exc:
            raise CaptureError(f"{where}: {exc}") from None
    logger.debug("loaded IWER capture %s: %d frames, %d input schemas", path, len(out),
                 len(schema))
    return IwerCapture(path, schema, out)


def iwer_hand_frames(capture: IwerCapture, *, keep_handless: bool = False) -> list[HandFrame]:
    """The capture's hand-tracking frames as :class:`HandFrame` (MuJoCo world, wxyz).

    Joint poses are taken from the target-ray space to local-floor (``T_ray ∘ T_joint``), then
    converted once with :data:`teleop.input.frames.XR_TO_MUJOCO`. Only inputs whose schema has a
    hand count (``hasHand``; schema indices 2 and 3 in the Quest 3 sample); controllers are
    ignored. Frames without any hand input (controller segments, the empty frames while the
    runtime switches) are skipped unless ``keep_handless``, which yields them with no hands so
    timing stays continuous. A side absent from a frame is None. ``seq`` is the capture row
    index, both timestamps are the recorder's clock (a capture has no separate receive time),
    ``source`` is ``"iwer:<file name>"``.
    """
    source = f"iwer:{capture.path.name}"
    # gather every hand input, convert them in one vectorised pass
    slots: list[tuple[int, str]] = []
    rays, joints = [], []
    for k, fr in enumerate(capture.frames):
        seen: set[str] = set()
        for inp in fr.inputs:
            s = capture.schema[inp.schema_index]
            if not s.has_hand or inp.joints_local is None or s.handedness in seen:
                continue
            if s.handedness not in ("left", "right"):
                continue
            seen.add(s.handedness)
            slots.append((k, s.handedness))
            rays.append(np.concatenate([inp.target_ray_position, inp.target_ray_quat_xyzw]))
            joints.append(inp.joints_local)
    hands_by_frame: dict[int, dict[str, HandState]] = {}
    if slots:
        ray = np.stack(rays)[:, None, :]  # (N,1,7)
        jl = np.stack(joints)  # (N,25,8)
        q_ray = frames.quat_normalize_wxyz(transforms.quat_xyzw_to_wxyz(ray[..., 3:7]))
        q_j = transforms.quat_xyzw_to_wxyz(jl[..., 3:7])
        p_xr, q_xr = transforms.pose_mul(ray[..., :3], q_ray, jl[..., :3], q_j)
        pos, quat, rad, ok = webxr_to_openxr_arrays(
            p_xr, transforms.quat_wxyz_to_xyzw(q_xr), jl[..., 7])
        for n, (k, side) in enumerate(slots):
            hands_by_frame.setdefault(k, {})[side] = HandState(
                pos[n], quat[n], rad[n], ok[n], tracked=bool(ok[n, WRIST]))
    out: list[HandFrame] = []
    for k, fr in enumerate(capture.frames):
        hands = hands_by_frame.get(k)
        if hands is None and not keep_handless:
            continue
        hands = hands or {}
        head_p, head_q = frames.xr_to_mujoco_pose(fr.head_position, fr.head_quat_xyzw)
        out.append(HandFrame(seq=fr.index, device_time_s=fr.time_s, receive_time_s=fr.time_s,
                             head_position=head_p,
                             head_orientation_wxyz=frames.quat_normalize_wxyz(head_q),
                             left=hands.get("left"), right=hands.get("right"), source=source))
    return out
