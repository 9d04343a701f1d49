"""Channels and schemas of a dexaug session recording (MCAP), defined in one place.

Why one module: the recorder registers these channels, the session reader decodes them, replay
and demo extraction consume them, the bridge's live Foxglove server publishes them, and Foxglove
displays them. If a topic name, a JSON field or a schema changed in one place only, old
recordings would be silently misread; here every channel is a :class:`ChannelSpec` and
:data:`FORMAT_VERSION` is bumped on any incompatible change.

Channels (each with its schema; the SDK's writer stores a channel with its first message, and
``/view`` is kept only when view recording is on):

==============  ============================  =============  =================================
topic           schema name                   message enc.   payload
==============  ============================  =============  =================================
``/hands``      ``dexaug.HandFrame``          ``dexaug.hand  raw input: the exact wire bytes of
                (encoding ``dexaug-layout``:  frame.v1``     :func:`teleop.messages.encode`
                the layout text)
``/state``      ``dexaug.State`` (jsonschema) ``json``       hand qpos (radians, order of the
                                                             metadata's ``joint_names``), palm
                                                             and object poses in the world
``/contacts``   ``dexaug.Contacts``           ``json``       hand–object contacts in the world,
                (jsonschema)                                 object and hand-body frames
``/events``     ``dexaug.Event`` (jsonschema) ``json``       recording started/stopped, grasp
                                                             marks, object changes and resets
``/tf``         ``foxglove.FrameTransforms``  ``protobuf``   world→palm, world→object (+ any
                                                             other frame the caller publishes)
``/markers``    ``foxglove.SceneUpdate``      ``protobuf``   contact spheres and force arrows,
                                                             the object model, hand skeletons
``/view``       ``foxglove.CompressedImage``  ``protobuf``   the headset view (JPEG)
==============  ============================  =============  =================================

Why these encodings: ``/hands`` keeps the raw bytes the bridge received, so a replay feeds the
bridge bit-identical input (no float64→JSON→float32 round trip). Our own channels are JSON with
a JSON Schema: Foxglove decodes it without plugins, ``jq`` reads it, demo extraction reads every
recording ever made the same way, and at teleop rates (≤ 120 Hz, ≤ 2 kB a message) its cost is
negligible next to the simulation. The ``foxglove.*`` channels are the official ``foxglove-sdk``'s
messages, its schemas (:func:`foxglove_spec`: protobuf file descriptor sets, taken from the SDK,
never copied) and its encoding, so a session opens in Foxglove's 3D and Image panels as the
app expects and a JPEG is stored as bytes, not base64. Format 1 (older recordings) held the
same three channels as JSON with hand-written copies of Foxglove's JSON schemas; the reader
(:mod:`teleop.record.protobuf_payload`) gives both as the same JSON-shaped dicts.

Conventions of the JSON payloads (DESIGN section 3): SI units with the unit in the field name
(``_m`` metres, ``_s`` seconds, ``_n`` newtons, ``qpos`` radians), quaternions **wxyz** in our
own schemas (field names end in ``_wxyz``) and **xyzw** in Foxglove's (their convention, the
swap happens in :mod:`teleop.record.foxglove`), non-finite numbers written as ``null``
(JSON has no NaN). Every message's MCAP log time is nanoseconds since the Unix epoch unless the
recorder's caller chose another clock (the metadata's ``clock`` key says which).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from foxglove import messages as fm

from teleop import messages as hand_messages

__all__ = ["CHANNELS", "CHANNEL_BY_TOPIC", "CONTACTS_SCHEMA", "EVENT_SCHEMA", "EVENT_TYPES",
           "FORMAT_VERSION", "FOXGLOVE_TOPICS", "FRAME_OBJECT", "FRAME_PALM", "FRAME_WORLD",
           "HANDS_MESSAGE_ENCODING", "HANDS_SCHEMA_ENCODING", "HANDS_SCHEMA_NAME",
           "JSON_KEYS_KEY", "JSON_TOPICS", "METADATA_NAME", "STATE_SCHEMA", "TOPIC_CONTACTS",
           "TOPIC_EVENTS", "TOPIC_HANDS", "TOPIC_MARKERS", "TOPIC_STATE", "TOPIC_TF",
           "TOPIC_VIEW", "ChannelSpec", "dumps", "finite_list",
           "foxglove_spec", "state_payload"]

#: Version of the session layout (topics, schemas, metadata keys); readers check it. 2: the
#: ``foxglove.*`` channels are the SDK's protobuf messages (1: JSON; both are read).
FORMAT_VERSION = 2
#: Name of the session-level MCAP metadata record.
METADATA_NAME = "dexaug.session"
#: Metadata key listing the keys whose values are JSON (all others are plain strings).
JSON_KEYS_KEY = "dexaug.json_keys"

TOPIC_HANDS = "/hands"
TOPIC_STATE = "/state"
TOPIC_CONTACTS = "/contacts"
TOPIC_EVENTS = "/events"
TOPIC_TF = "/tf"
TOPIC_MARKERS = "/markers"
TOPIC_VIEW = "/view"

#: Frame ids used in ``/tf`` and ``/markers`` (Foxglove builds its transform tree from them).
FRAME_WORLD = "world"
FRAME_PALM = "palm"
FRAME_OBJECT = "object"

#: Event types on ``/events``. ``recording_started``/``recording_stopped`` are written by the
#: recorder itself; the others by the bridge (operator actions).
EVENT_TYPES: tuple[str, ...] = ("recording_started", "recording_stopped", "grasp_mark",
                                "object_changed", "object_reset", "scene_restored")

HANDS_SCHEMA_NAME = "dexaug.HandFrame"
HANDS_SCHEMA_ENCODING = "dexaug-layout"
HANDS_MESSAGE_ENCODING = f"dexaug.handframe.v{hand_messages.SCHEMA_VERSION}"


# --- JSON Schema building blocks ----------------------------------------------------------------


def _num(description: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {"type": ["number", "null"]}
    if description:
        out["description"] = description
    return out


def _vec(n: int, description: str) -> dict[str, Any]:
    return {"type": "array", "items": {"type": ["number", "null"]}, "minItems": n, "maxItems": n,
            "description": description}


def _object(properties: dict[str, Any], required: Sequence[str] = (), *, title: str = "",
            description: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {"type": "object", "properties": properties}
    if title:
        out["title"] = title
    if description:
        out["description"] = description
    if required:
        out["required"] = list(required)
    return out


def _schema_bytes(schema: Mapping[str, Any]) -> bytes:
    return json.dumps(schema, indent=1, sort_keys=False).encode("utf-8")


# --- our JSON schemas -----------------------------------------------------------------------------

_T_S = ("clock of the record, seconds: the bridge's simulated time of the step (the same on every "
        "record of one step), else seconds since the recording started")

STATE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    **_object({
        "t_s": _num(_T_S),
        "seq": {"type": ["integer", "null"],
                "description": "seq of the /hands frame this state was computed from"},
        "tracked": {"type": "boolean", "description": "the driving hand was tracked"},
        "qpos": {"type": "array", "items": {"type": ["number", "null"]},
                 "description": "hand joint vector, radians (metres for slide joints), in the "
                                "order of the session metadata's joint_names"},
        "palm_pos_m": _vec(3, "palm frame origin in the world, metres"),
        "palm_quat_wxyz": _vec(4, "palm frame orientation in the world, quaternion wxyz"),
        "object": {"type": ["string", "null"], "description": "current object name"},
        "object_pos_m": _vec(3, "object frame origin in the world, metres"),
        "object_quat_wxyz": _vec(4, "object frame orientation in the world, quaternion wxyz"),
        "extra": {"type": "object", "description": "free-form per-frame values (units in names)"},
    }, ["t_s", "qpos", "palm_pos_m", "palm_quat_wxyz", "object_pos_m", "object_quat_wxyz"],
        title="dexaug.State",
        description="Hand and object state after one bridge step (MuJoCo world, +Z up)."),
}

_CONTACT_ITEM = _object({
    "finger": {"type": ["string", "null"],
               "description": "finger name of the hand config, null for palm/link contacts"},
    "hand_body": {"type": "string", "description": "MuJoCo body of the hand in contact"},
    "pos_world_m": _vec(3, "contact point in the world, metres"),
    "normal_world": _vec(3, "unit normal in the world, from the hand into the object"),
    "pos_object_m": _vec(3, "contact point in the object frame, metres"),
    "normal_object": _vec(3, "unit normal in the object frame"),
    "pos_hand_body_m": _vec(3, "contact point in the hand body's frame (the fingertip frame for "
                               "fingertip contacts), metres"),
    "normal_hand_body": _vec(3, "unit normal in the hand body's frame"),
    "dist_m": _num("signed distance, metres (negative = penetration)"),
    "force_n": _num("normal force, newtons (null when not computed)"),
}, ["hand_body", "pos_world_m", "normal_world", "pos_object_m", "normal_object",
    "pos_hand_body_m", "normal_hand_body", "dist_m"], title="dexaug.Contact")

CONTACTS_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    **_object({
        "t_s": _num(_T_S),
        "seq": {"type": ["integer", "null"],
                "description": "seq of the /state of the same bridge step"},
        "object": {"type": ["string", "null"], "description": "object in contact"},
        "contacts": {"type": "array", "items": _CONTACT_ITEM},
    }, ["t_s", "contacts"], title="dexaug.Contacts",
        description="Hand–object contacts after one bridge step (may be empty)."),
}

EVENT_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    **_object({
        "type": {"type": "string", "enum": list(EVENT_TYPES)},
        "t_s": _num(_T_S),
        "payload": {"type": "object", "description": "event-specific values (e.g. object name)"},
    }, ["type", "t_s", "payload"], title="dexaug.Event",
        description="An operator or recorder event."),
}


# --- channel specs --------------------------------------------------------------------------------


@dataclass(frozen=True)
class ChannelSpec:
    """One MCAP channel and its schema. ``optional`` channels are registered only on request."""

    topic: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    description: str
    optional: bool = False


def _hands_layout() -> bytes:
    doc = hand_messages.__doc__ or ""
    start = doc.find("Wire layout")
    return (f"dexaug.HandFrame schema version {hand_messages.SCHEMA_VERSION}: little-endian binary"
            f" (see teleop/messages.py).\n\n{doc[start:] if start >= 0 else doc}").encode()


def foxglove_spec(topic: str, message: type[Any], description: str, *,
                  optional: bool = False) -> ChannelSpec:
    """The channel of a ``foxglove-sdk`` message class (``foxglove.messages.FrameTransforms``,
    …): its schema exactly as the SDK gives it, and the SDK's encoding (protobuf)."""
    schema = message.get_schema()
    return ChannelSpec(topic, schema.name, schema.encoding, bytes(schema.data), "protobuf",
                       description, optional)


CHANNELS: tuple[ChannelSpec, ...] = (
    ChannelSpec(TOPIC_HANDS, HANDS_SCHEMA_NAME, HANDS_SCHEMA_ENCODING, _hands_layout(),
                HANDS_MESSAGE_ENCODING, "raw hand-tracking input (teleop.messages wire bytes)"),
    ChannelSpec(TOPIC_STATE, "dexaug.State", "jsonschema", _schema_bytes(STATE_SCHEMA), "json",
                "retargeted hand qpos, palm and object poses"),
    ChannelSpec(TOPIC_CONTACTS, "dexaug.Contacts", "jsonschema", _schema_bytes(CONTACTS_SCHEMA),
                "json", "hand-object contacts"),
    ChannelSpec(TOPIC_EVENTS, "dexaug.Event", "jsonschema", _schema_bytes(EVENT_SCHEMA), "json",
                "recording and operator events"),
    foxglove_spec(TOPIC_TF, fm.FrameTransforms, "world->palm, world->object"),
    foxglove_spec(TOPIC_MARKERS, fm.SceneUpdate, "contacts, object, hand markers"),
    foxglove_spec(TOPIC_VIEW, fm.CompressedImage, "headset view (JPEG)", optional=True),
)
#: Topic → spec.
CHANNEL_BY_TOPIC: dict[str, ChannelSpec] = {c.topic: c for c in CHANNELS}
#: Topics of Foxglove's well-known messages.
FOXGLOVE_TOPICS: frozenset[str] = frozenset(c.topic for c in CHANNELS
                                            if c.schema_name.startswith("foxglove."))
#: Topics whose payload the session reader gives as a JSON-shaped dict: our JSON channels, and the
#: Foxglove ones (JSON in format 1, protobuf decoded to Foxglove's JSON form since format 2).
JSON_TOPICS: frozenset[str] = frozenset(c.topic for c in CHANNELS if c.topic != TOPIC_HANDS)


# --- payload helpers ------------------------------------------------------------------------------


def finite_list(values: Any) -> list[float | None]:
    """A flat float list for JSON: non-finite values become ``None`` (JSON has no NaN)."""
    out: list[Any] = np.asarray(values, dtype=float).ravel().tolist()
    return [v if math.isfinite(v) else None for v in out]


def dumps(payload: Mapping[str, Any]) -> bytes:
    """Compact JSON bytes; raises ValueError on NaN/inf (use :func:`finite_list` first), so no
    file ever holds JSON that strict parsers (Foxglove's) reject."""
    return json.dumps(payload, separators=(",", ":"), allow_nan=False).encode("utf-8")


def state_payload(qpos: Any, palm_pos_m: Any, palm_quat_wxyz: Any, object_pos_m: Any,
                  object_quat_wxyz: Any, *, t_s: float, seq: int | None, tracked: bool,
                  object_name: str | None, extra: Mapping[str, Any] | None,
                  joint_names: Sequence[str] | None = None) -> dict[str, Any]:
    """A ``/state`` payload (:data:`STATE_SCHEMA`); shared by the recorder and the bridge's live
    Foxglove server so a layout's plots read a recording and the live bridge alike. Raises
    ValueError when a pose has the wrong length or qpos does not match ``joint_names``."""
    q = np.asarray(qpos, dtype=float).ravel()
    if joint_names is not None and len(q) != len(joint_names):
        raise ValueError(f"qpos has {len(q)} values, metadata joint_names has {len(joint_names)}")
    poses = {"palm_pos_m": (palm_pos_m, 3), "palm_quat_wxyz": (palm_quat_wxyz, 4),
             "object_pos_m": (object_pos_m, 3), "object_quat_wxyz": (object_quat_wxyz, 4)}
    payload: dict[str, Any] = {}
    for key, (value, n) in poses.items():
        arr = np.asarray(value, dtype=float).ravel()
        if arr.shape != (n,):
            raise ValueError(f"{key} must have {n} values, got shape {np.shape(value)}")
        payload[key] = finite_list(arr)
    payload.update(t_s=float(t_s), seq=None if seq is None else int(seq), tracked=bool(tracked),
                   qpos=finite_list(q), object=object_name, extra=dict(extra) if extra else {})
    return payload

