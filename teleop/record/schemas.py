"""Channels and schemas of a dexaug session recording (MCAP), defined in one place.

Why one module: the recorder registers these channels, the session reader decodes them, replay
and demo extraction consume them, and Foxglove displays them. If a topic name, a JSON field or a
schema changed in one place only, old recordings would be silently misread; here every channel
is a :class:`ChannelSpec` and :data:`FORMAT_VERSION` is bumped on any incompatible change.

Channels (all registered upfront with a schema; ``/view`` only when view recording is on):

==============  =========================  ===============  =====================================
topic           schema name                message encoding payload
==============  =========================  ===============  =====================================
``/hands``      ``dexaug.HandFrame``       ``dexaug.hand-   raw input: the exact wire bytes of
                (encoding ``dexaug-        frame.v1``       :func:`teleop.messages.encode` (the
                layout``: the layout text)                  schema data is that layout, as text)
``/state``      ``dexaug.State``           ``json``         hand qpos (radians, order of the
                (jsonschema)                                metadata's ``joint_names``), palm and
                                                            object poses in the world
``/contacts``   ``dexaug.Contacts``        ``json``         hand–object contacts in the world,
                (jsonschema)                                object and hand-body frames
``/events``     ``dexaug.Event``           ``json``         recording started/stopped, grasp
                (jsonschema)                                marks, object changes and resets
``/tf``         ``foxglove.FrameTransforms`` ``json``       world→palm, world→object (+ any other
                                                            frame the caller publishes)
``/markers``    ``foxglove.SceneUpdate``   ``json``         contact spheres and force arrows, the
                                                            object model, hand skeletons
``/view``       ``foxglove.CompressedImage`` ``json``       the headset view (JPEG, base64 in
                                                            JSON, as Foxglove's JSON schema says)
==============  =========================  ===============  =====================================

Why these encodings: ``/hands`` keeps the raw bytes the bridge received, so a replay feeds the
bridge bit-identical input (no float64→JSON→float32 round trip). Everything else is JSON with a
JSON Schema: Foxglove decodes it without plugins, ``jq`` reads it, and at teleop rates (≤ 100 Hz,
≤ 2 kB a message) its cost is negligible next to the simulation. The three ``foxglove.*``
schemas are Foxglove's well-known schemas (field names from foxglove/schemas' ``jsonschema``
folder), so a session opens in Foxglove's 3D and Image panels with no configuration.

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

from teleop import messages as hand_messages

__all__ = ["CHANNELS", "CHANNEL_BY_TOPIC", "COMPRESSED_IMAGE_SCHEMA", "CONTACTS_SCHEMA",
           "EVENT_SCHEMA", "EVENT_TYPES", "FORMAT_VERSION", "FRAME_OBJECT", "FRAME_PALM",
           "FRAME_TRANSFORMS_SCHEMA", "FRAME_WORLD", "HANDS_MESSAGE_ENCODING",
           "HANDS_SCHEMA_ENCODING", "HANDS_SCHEMA_NAME", "JSON_KEYS_KEY", "JSON_TOPICS",
           "METADATA_NAME", "SCENE_UPDATE_SCHEMA", "STATE_SCHEMA", "TOPIC_CONTACTS",
           "TOPIC_EVENTS", "TOPIC_HANDS", "TOPIC_MARKERS", "TOPIC_STATE", "TOPIC_TF",
           "TOPIC_VIEW", "ChannelSpec", "dumps", "finite_list"]

#: Version of the session layout (topics, schemas, metadata keys); readers check it.
FORMAT_VERSION = 1
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


# --- Foxglove well-known JSON schemas -------------------------------------------------------------
# Field names follow foxglove/schemas (schemas/jsonschema/*.json): FrameTransforms,
# SceneUpdate (SceneEntity with arrows/cubes/spheres/cylinders/lines/triangles/texts/models),
# CompressedImage. Trimmed of descriptions; Foxglove keys on the schema *name*, the JSON schema
# documents the fields for other tools.

_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_DURATION = {"type": "object", "title": "duration",
             "properties": {"sec": {"type": "integer"},
                            "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_VECTOR3 = _object({k: {"type": "number"} for k in "xyz"}, title="foxglove.Vector3")
_POINT3 = _object({k: {"type": "number"} for k in "xyz"}, title="foxglove.Point3")
_QUATERNION = _object({k: {"type": "number"} for k in "xyzw"}, title="foxglove.Quaternion")
_COLOR = _object({k: {"type": "number"} for k in "rgba"}, title="foxglove.Color")
_POSE = _object({"position": _VECTOR3, "orientation": _QUATERNION}, title="foxglove.Pose")


def _array(items: dict[str, Any]) -> dict[str, Any]:
    return {"type": "array", "items": items}


FRAME_TRANSFORMS_SCHEMA: dict[str, Any] = _object({
    "transforms": _array(_object({
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"},
        "translation": _VECTOR3,
        "rotation": _QUATERNION,
    }, title="foxglove.FrameTransform")),
}, title="foxglove.FrameTransforms", description="An array of FrameTransform messages")

_SCENE_ENTITY = _object({
    "timestamp": _TIME,
    "frame_id": {"type": "string"},
    "id": {"type": "string"},
    "lifetime": _DURATION,
    "frame_locked": {"type": "boolean"},
    "metadata": _array(_object({"key": {"type": "string"}, "value": {"type": "string"}},
                               title="foxglove.KeyValuePair")),
    "arrows": _array(_object({"pose": _POSE, "shaft_length": {"type": "number"},
                              "shaft_diameter": {"type": "number"},
                              "head_length": {"type": "number"},
                              "head_diameter": {"type": "number"}, "color": _COLOR},
                             title="foxglove.ArrowPrimitive")),
    "cubes": _array(_object({"pose": _POSE, "size": _VECTOR3, "color": _COLOR},
                            title="foxglove.CubePrimitive")),
    "spheres": _array(_object({"pose": _POSE, "size": _VECTOR3, "color": _COLOR},
                              title="foxglove.SpherePrimitive")),
    "cylinders": _array(_object({"pose": _POSE, "size": _VECTOR3,
                                 "bottom_scale": {"type": "number"},
                                 "top_scale": {"type": "number"}, "color": _COLOR},
                                title="foxglove.CylinderPrimitive")),
    "lines": _array(_object({"type": {"type": "integer", "description":
                                      "0 LINE_STRIP, 1 LINE_LOOP, 2 LINE_LIST"},
                             "pose": _POSE, "thickness": {"type": "number"},
                             "scale_invariant": {"type": "boolean"},
                             "points": _array(_POINT3), "color": _COLOR,
                             "colors": _array(_COLOR),
                             "indices": _array({"type": "integer", "minimum": 0})},
                            title="foxglove.LinePrimitive")),
    "triangles": _array(_object({"pose": _POSE, "points": _array(_POINT3), "color": _COLOR,
                                 "colors": _array(_COLOR),
                                 "indices": _array({"type": "integer", "minimum": 0})},
                                title="foxglove.TriangleListPrimitive")),
    "texts": _array(_object({"pose": _POSE, "billboard": {"type": "boolean"},
                             "font_size": {"type": "number"},
                             "scale_invariant": {"type": "boolean"}, "color": _COLOR,
                             "text": {"type": "string"}}, title="foxglove.TextPrimitive")),
    "models": _array(_object({"pose": _POSE, "scale": _VECTOR3, "color": _COLOR,
                              "use_embedded_materials": {"type": "boolean"},
                              "url": {"type": "string"}, "media_type": {"type": "string"},
                              "data": {"type": "string", "contentEncoding": "base64"}},
                             title="foxglove.ModelPrimitive")),
}, title="foxglove.SceneEntity")

SCENE_UPDATE_SCHEMA: dict[str, Any] = _object({
    "deletions": _array(_object({
        "timestamp": _TIME,
        "type": {"type": "integer", "description": "0 MATCHING_ID, 1 ALL"},
        "id": {"type": "string"},
    }, title="foxglove.SceneEntityDeletion")),
    "entities": _array(_SCENE_ENTITY),
}, title="foxglove.SceneUpdate", description="An update to the entities displayed in a 3D scene")

COMPRESSED_IMAGE_SCHEMA: dict[str, Any] = _object({
    "timestamp": _TIME,
    "frame_id": {"type": "string"},
    "data": {"type": "string", "contentEncoding": "base64"},
    "format": {"type": "string", "description": "jpeg, png, webp or avif"},
}, title="foxglove.CompressedImage", description="A compressed image")


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


CHANNELS: tuple[ChannelSpec, ...] = (
    ChannelSpec(TOPIC_HANDS, HANDS_SCHEMA_NAME, HANDS_SCHEMA_ENCODING, _hands_layout(),
                HANDS_MESSAGE_ENCODING, "raw hand-tracking input (teleop.messages wire bytes)"),
    ChannelSpec(TOPIC_STATE, "dexaug.State", "jsonschema", _schema_bytes(STATE_SCHEMA), "json",
                "retargeted hand qpos, palm and object poses"),
    ChannelSpec(TOPIC_CONTACTS, "dexaug.Contacts", "jsonschema", _schema_bytes(CONTACTS_SCHEMA),
                "json", "hand-object contacts"),
    ChannelSpec(TOPIC_EVENTS, "dexaug.Event", "jsonschema", _schema_bytes(EVENT_SCHEMA), "json",
                "recording and operator events"),
    ChannelSpec(TOPIC_TF, "foxglove.FrameTransforms", "jsonschema",
                _schema_bytes(FRAME_TRANSFORMS_SCHEMA), "json", "world->palm, world->object"),
    ChannelSpec(TOPIC_MARKERS, "foxglove.SceneUpdate", "jsonschema",
                _schema_bytes(SCENE_UPDATE_SCHEMA), "json", "contacts, object, hand markers"),
    ChannelSpec(TOPIC_VIEW, "foxglove.CompressedImage", "jsonschema",
                _schema_bytes(COMPRESSED_IMAGE_SCHEMA), "json", "headset view (JPEG)",
                optional=True),
)
#: Topic → spec.
CHANNEL_BY_TOPIC: dict[str, ChannelSpec] = {c.topic: c for c in CHANNELS}
#: Topics whose payload is JSON.
JSON_TOPICS: frozenset[str] = frozenset(c.topic for c in CHANNELS if c.message_encoding == "json")


# --- payload helpers ------------------------------------------------------------------------------


def finite_list(values: Any) -> list[float | None]:
    """A flat float list for JSON: non-finite values become ``None`` (JSON has no NaN)."""
    out: list[Any] = np.asarray(values, dtype=float).ravel().tolist()
    return [v if math.isfinite(v) else None for v in out]


def dumps(payload: Mapping[str, Any]) -> bytes:
    """Compact JSON bytes; raises ValueError on NaN/inf (use :func:`finite_list` first), so no
    file ever holds JSON that strict parsers (Foxglove's) reject."""
    return json.dumps(payload, separators=(",", ":"), allow_nan=False).encode("utf-8")
