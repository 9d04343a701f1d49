"""WebXR hand data → :class:`teleop.messages.HandFrame`, and IWER capture files.

Why here: WebXR (the browser page on the Quest) and IWER recordings both speak the WebXR
convention — 25 joints without PALM, xyzw quaternions, +Y up, −Z forward. This module is the
one boundary where that becomes dexaug's convention: 26 OpenXR joints with a synthesised PALM,
MuJoCo world (+Z up), wxyz quaternions (see :mod:`teleop.input.frames` for the rotation).

IWER captures (``cap.min.js``, written by the ``iwer`` npm package's ActionRecorder) are a
minified ES module ``export {capture}`` holding a JavaScript object literal
``{schema: [[index, InputSchema], ...], frames: [row, ...]}``. A frame row is
``[t_ms, head p3, head q4 (xyzw), input...]`` and an input is
``[schema_index, target-ray p3 q4, [grip p3 q4] if hasGrip, [25 × (p3, q4, radius)] if hasHand,
[buttons..., axes...] if hasGamepad]``. Head, target-ray and grip poses are in the session's
reference space (``local-floor``); **hand joint poses are relative to that hand's target-ray
space** (the recorder calls ``fillPoses(joints, targetRaySpace)``), so reference-space joint
poses are ``T_ray ∘ T_joint``. Values are rounded to 1e-3 by the recorder.
"""

from __future__ import annotations

import bisect
import json
import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim import transforms
from sim.errors import DexaugError
from teleop.input import frames
from teleop.messages import NUM_JOINTS, PALM, WRIST, HandFrame, HandState, MessageError

logger = logging.getLogger(__name__)

Array = np.ndarray

#: The 25 WebXR ``XRHandJoint`` names, in the spec's order (= OpenXR order without PALM, so
#: OpenXR index = WebXR index + 1).
WEBXR_JOINTS: tuple[str, ...] = (
    "wrist",
    "thumb-metacarpal", "thumb-phalanx-proximal", "thumb-phalanx-distal", "thumb-tip",
    "index-finger-metacarpal", "index-finger-phalanx-proximal",
    "index-finger-phalanx-intermediate", "index-finger-phalanx-distal", "index-finger-tip",
    "middle-finger-metacarpal", "middle-finger-phalanx-proximal",
    "middle-finger-phalanx-intermediate", "middle-finger-phalanx-distal", "middle-finger-tip",
    "ring-finger-metacarpal", "ring-finger-phalanx-proximal",
    "ring-finger-phalanx-intermediate", "ring-finger-phalanx-distal", "ring-finger-tip",
    "pinky-finger-metacarpal", "pinky-finger-phalanx-proximal",
    "pinky-finger-phalanx-intermediate", "pinky-finger-phalanx-distal", "pinky-finger-tip",
)
NUM_WEBXR_JOINTS = len(WEBXR_JOINTS)
_WEBXR_MIDDLE_METACARPAL = WEBXR_JOINTS.index("middle-finger-metacarpal")
_WEBXR_MIDDLE_PROXIMAL = WEBXR_JOINTS.index("middle-finger-phalanx-proximal")


class CaptureError(DexaugError):
    """A capture file cannot be read or parsed; the message names the file and position."""


# --- WebXR joints → HandState -------------------------------------------------------------------


def _webxr_to_openxr_arrays(positions: Array, quats_xyzw: Array,
                            radii: Array) -> tuple[Array, Array, Array, Array]:
    """Vectorised core of :func:`from_webxr_joints` over leading dims (...,25,·) → (...,26,·)
    arrays (positions, orientations wxyz, radii, valid) in the MuJoCo world."""
    p = frames.xr_to_mujoco_positions(positions)
    q = frames.quat_normalize_wxyz(frames.xr_to_mujoco_quat_wxyz(quats_xyzw))
    r = np.asarray(radii, dtype=float)
    valid = np.isfinite(p).all(-1) & np.isfinite(q).all(-1) & np.isfinite(r) & (r >= 0)
    lead = p.shape[:-2]
    pos = np.full((*lead, NUM_JOINTS, 3), np.nan)
    quat = np.full((*lead, NUM_JOINTS, 4), np.nan)
    rad = np.full((*lead, NUM_JOINTS), np.nan)
    ok = np.zeros((*lead, NUM_JOINTS), dtype=bool)
    pos[..., 1:, :] = p
    quat[..., 1:, :] = q
    rad[..., 1:] = r
    ok[..., 1:] = valid
    # PALM: OpenXR puts it at the centre of the middle-finger metacarpal bone, i.e. halfway
    # between the metacarpal joint (its base) and the proximal phalanx joint (the knuckle);
    # orientation and radius are the middle metacarpal's (the bone it lies on).
    mc, px = _WEBXR_MIDDLE_METACARPAL, _WEBXR_MIDDLE_PROXIMAL
    pos[..., PALM, :] = 0.5 * (p[..., mc, :] + p[..., px, :])
    quat[..., PALM, :] = q[..., mc, :]
    rad[..., PALM] = r[..., mc]
    ok[..., PALM] = valid[..., mc] & valid[..., px]
    pos[~ok] = np.nan
    quat[~ok] = np.nan
    rad[~ok] = np.nan
    return pos, quat, rad, ok


def from_webxr_joints(positions: Array, quats_xyzw: Array, radii: Array) -> HandState:
    """One hand's 25 WebXR joints in the XR reference space → a 26-joint :class:`HandState`
    in the MuJoCo world.

    positions: (25,3) metres; quats_xyzw: (25,4); radii: (25,) metres, all in WebXR joint order
    (:data:`WEBXR_JOINTS`). Joints with NaN/inf values, a zero quaternion or a negative radius
    (how a sender marks a joint the runtime did not report) become ``valid=False`` with NaN
    values; PALM is synthesised from the middle metacarpal (valid only when that bone's two
    joints are); ``tracked`` is False when the wrist is missing. Quaternions are normalised
    (the IWER recorder rounds them to 1e-3).
    """
    p = np.asarray(positions, dtype=float)
    q = np.asarray(quats_xyzw, dtype=float)
    r = np.asarray(radii, dtype=float)
    for name, arr, shape in (("positions", p, (NUM_WEBXR_JOINTS, 3)),
                             ("quats_xyzw", q, (NUM_WEBXR_JOINTS, 4)),
                             ("radii", r, (NUM_WEBXR_JOINTS,))):
        if arr.shape != shape:
            raise MessageError(f"WebXR {name}: expected shape {shape} (25 WebXR joints), "
                               f"got {arr.shape}")
    pos, quat, rad, ok = _webxr_to_openxr_arrays(p, q, r)
    return HandState(pos, quat, rad, ok, tracked=bool(ok[WRIST]))


# --- minimal JavaScript object-literal reader -----------------------------------------------------

# Only the JSON-incompatible bits of a minified JS literal are matched (strings are matched
# whole so nothing inside them is touched); everything else is already JSON and passes through.
# The leading look-ahead lets the scanner skip digits (the bulk of a capture) without trying
# the alternatives: a 2.5 MB capture converts in about 0.3 s instead of 1 s.
_JS_TOKEN = re.compile(r"""
  (?=['"/!A-Za-z_$,{.])
  (?:
    (?P<str>'(?:[^'\\\n]|\\.)*'|"(?:[^"\\\n]|\\.)*")
  | (?P<comment>//[^\n]*|/\*.*?\*/)
  | (?P<bang>!\s*[01](?![\w.]))
  | (?P<void>(?<![\w$.])void\s+0(?![\w.]))
  | (?P<key>(?<![\w$.])[A-Za-z_$][\w$]*(?=\s*:))
  | (?P<ident>(?<![\w$.])[A-Za-z_$][\w$]*)
  | (?P<numkey>[{,]\s*\d+(?=\s*:))
  | (?P<trail>,(?=\s*[\]}]))
  | (?P<dotend>(?<=\d)\.(?!\d))
  | (?P<dotstart>(?<!\d)\.(?=\d))
  )
""", re.S | re.X)
_JS_IDENT_VALUES = {"true": "true", "false": "false", "null": "null", "undefined": "null",
                    "NaN": "NaN", "Infinity": "Infinity"}
_JS_ESCAPE = re.compile(r"\\(u\{[0-9a-fA-F]+\}|u[0-9a-fA-F]{4}|x[0-9a-fA-F]{2}|\r\n|.)", re.S)
_JS_SIMPLE_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "b": "\b", "f": "\f", "v": "\v",
                      "0": "\0", "\n": "", "\r": "", "\r\n": ""}


def _js_unescape(m: re.Match[str]) -> str:
    e = m.group(1)
    if e[0] in "ux" and len(e) > 1:
        return chr(int(e[2:-1] if e[1] == "{" else e[1:], 16))
    return _JS_SIMPLE_ESCAPES.get(e, e)


def _js_string_to_json(token: str) -> str:
    """A JS string literal (either quote) as a JSON string literal."""
    body = token[1:-1]
    if "\\" in body:
        body = _JS_ESCAPE.sub(_js_unescape, body)
    # ensure_ascii keeps lone surrogates (from "\ud83d\ude00") escaped, so JSON re-pairs them
    return json.dumps(body)


class _JsToJson:
    """Rewrites the JS-only syntax of a data literal into JSON and remembers where it changed
    lengths, so a JSON error position can be reported in the original file."""

    def __init__(self) -> None:
        self.conv_ends: list[int] = []
        self.deltas: list[int] = []
        self._delta = 0

    def _replace(self, m: re.Match[str]) -> str:
        kind, tok = m.lastgroup, m.group()
        if kind == "str":
            out = tok if tok[0] == '"' and "\\" not in tok else _js_string_to_json(tok)
        elif kind == "comment":
            out = " "
        elif kind == "bang":
            out = "true" if tok[-1] == "0" else "false"
        elif kind == "void":
            out = "null"
        elif kind == "key":
            out = f'"{tok}"'
        elif kind == "ident":
            out = _JS_IDENT_VALUES.get(tok, tok)  # unknown names stay; JSON reports them
        elif kind == "numkey":
            digits = tok.lstrip("{,").lstrip()
            out = f'{tok[: len(tok) - len(digits)]}"{digits}"'
        elif kind == "dotend":  # "5." → "5.0"
            out = ".0"
        elif kind == "dotstart":  # ".5" → "0.5"
            out = "0."
        else:  # trailing comma
            out = ""
        if len(out) != len(tok):
            conv_start = m.start() + self._delta
            self._delta += len(out) - len(tok)
            self.conv_ends.append(conv_start + len(out))
            self.deltas.append(self._delta)
        return out

    def convert(self, text: str) -> str:
        return _JS_TOKEN.sub(self._replace, text)

    def source_pos(self, conv_pos: int) -> int:
        """Position in the original text of position ``conv_pos`` of the converted text."""
        k = bisect.bisect_right(self.conv_ends, conv_pos)
        return conv_pos - (self.deltas[k - 1] if k else 0)


def _literal_start(text: str, name: str) -> int:
    """Offset of the object literal exported as ``name`` (``export{a as capture}`` →
    ``var a=…``; or ``capture=…``; or ``export default …``; or a bare JSON file)."""
    candidates = []
    for m in re.finditer(r"export\s*\{([^}]*)\}", text):
        for spec in m.group(1).split(","):
            words = spec.split()
            if words and words[-1] == name:
                candidates.append(words[0])
    candidates.append(name)
    for local in candidates:
        m = re.search(rf"(?<![\w$.]){re.escape(local)}\s*=(?![=>])\s*", text)
        if m:
            return m.end()
    m = re.search(r"export\s+default\s*", text)
    if m:
        return m.end()
    stripped = len(text) - len(text.lstrip())
    if text[stripped:stripped + 1] in ("{", "["):
        return stripped
    raise ValueError(f"no `{name}` object literal found (expected `export {{{name}}}` with "
                     f"`var <x> = {{...}}`, `{name} = {{...}}` or a JSON object)")


def parse_js_literal(text: str, name: str = "capture", *, path: str = "<string>") -> Any:
    """The JSON-like value of the object literal exported as ``name`` from a (minified) ES
    module; :class:`CaptureError` names ``path``, line, column and the text there on failure."""
    try:
        start = _literal_start(text, name)
    except ValueError as exc:
        raise CaptureError(f"{path}: {exc}") from None
    conv = _JsToJson()
    converted = conv.convert(text[start:])
    try:
        value, _ = json.JSONDecoder().raw_decode(converted)
    except json.JSONDecodeError as exc:
        pos = start + conv.source_pos(exc.pos)
        line = text.count("\n", 0, pos) + 1
        col = pos - (text.rfind("\n", 0, pos) + 1) + 1
        near = text[max(0, pos - 30):pos + 30].replace("\n", "\\n")
        raise CaptureError(f"{path}: cannot parse the `{name}` literal at line {line}, column "
                           f"{col} (char {pos}): {exc.msg}; near {near!r}") from None
    return value


# --- IWER captures ------------------------------------------------------------------------------


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
        q_ray = frames.quat_normalize_wxyz(frames.quat_xyzw_to_wxyz(ray[..., 3:7]))
        q_j = frames.quat_xyzw_to_wxyz(jl[..., 3:7])
        p_xr, q_xr = transforms.pose_mul(ray[..., :3], q_ray, jl[..., :3], q_j)
        pos, quat, rad, ok = _webxr_to_openxr_arrays(
            p_xr, frames.quat_wxyz_to_xyzw(q_xr), jl[..., 7])
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


def hand_frame_from_webxr(seq: int, time_s: float, head_position_xr: Sequence[float],
                           head_quat_xyzw: Sequence[float],
                           hands_xr: dict[str, tuple[Array, Array, Array]],
                           *, receive_time_s: float | None = None,
                           source: str = "webxr") -> HandFrame:
    """Build a :class:`HandFrame` from one WebXR frame as a page sends it: head pose and, per
    side, (positions (25,3), quats_xyzw (25,4), radii (25,)) in the reference space (the
    page already asked for joint poses relative to the reference space, not the ray)."""
    head_p, head_q = frames.xr_to_mujoco_pose(np.asarray(head_position_xr, dtype=float),
                                              np.asarray(head_quat_xyzw, dtype=float))
    sides = {}
    for side, (p, q, r) in hands_xr.items():
        if side not in ("left", "right"):
            raise MessageError(f"hand side must be 'left' or 'right', got {side!r}")
        sides[side] = from_webxr_joints(p, q, r)
    return HandFrame(seq=seq, device_time_s=time_s,
                     receive_time_s=time_s if receive_time_s is None else receive_time_s,
                     head_position=head_p,
                     head_orientation_wxyz=frames.quat_normalize_wxyz(head_q),
                     left=sides.get("left"), right=sides.get("right"), source=source)
