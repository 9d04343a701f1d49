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
swap happens in :func:`frame_transforms`/:func:`pose`), non-finite numbers written as ``null``
(JSON has no NaN). Every message's MCAP log time is nanoseconds since the Unix epoch unless the
recorder's caller chose another clock (the metadata's ``clock`` key says which).
"""

from __future__ import annotations

import base64
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim import transforms
from teleop import messages as hand_messages

Array = np.ndarray

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
                                "object_changed", "object_reset")

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

STATE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    **_object({
        "t_s": _num("bridge clock, seconds since the recording started"),
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
        "t_s": _num("bridge clock, seconds since the recording started"),
        "object": {"type": ["string", "null"], "description": "object in contact"},
        "contacts": {"type": "array", "items": _CONTACT_ITEM},
    }, ["t_s", "contacts"], title="dexaug.Contacts",
        description="Hand–object contacts after one bridge step (may be empty)."),
}

EVENT_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    **_object({
        "type": {"type": "string", "enum": list(EVENT_TYPES)},
        "t_s": _num("bridge clock, seconds since the recording started"),
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


def time_dict(t_ns: int) -> dict[str, int]:
    """Foxglove ``time`` {sec, nsec} of a timestamp in nanoseconds."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def pose(pos_m: Any, quat_wxyz: Any) -> dict[str, Any]:
    """Foxglove ``Pose`` (position metres, orientation **xyzw**) from a wxyz quaternion."""
    px, py, pz = (float(v) for v in pos_m)
    qw, qx, qy, qz = (float(v) for v in quat_wxyz)
    return {"position": {"x": px, "y": py, "z": pz},
            "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}


def color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    """Foxglove ``Color``, components in [0, 1]."""
    return {"r": float(r), "g": float(g), "b": float(b), "a": float(a)}


@dataclass(frozen=True)
class FrameTransform:
    """A transform for ``/tf``: ``child`` frame pose in ``parent`` (metres, quaternion wxyz)."""

    parent: str
    child: str
    pos_m: Any
    quat_wxyz: Any


def frame_transforms(transforms: Iterable[FrameTransform], t_ns: int) -> dict[str, Any]:
    """A ``foxglove.FrameTransforms`` payload (quaternions converted to xyzw)."""
    stamp = time_dict(t_ns)
    out = []
    for tf in transforms:
        p = pose(tf.pos_m, tf.quat_wxyz)
        out.append({"timestamp": stamp, "parent_frame_id": tf.parent,
                    "child_frame_id": tf.child, "translation": p["position"],
                    "rotation": p["orientation"]})
    return {"transforms": out}


def scene_entity(entity_id: str, t_ns: int, *, frame_id: str = FRAME_WORLD,
                 **primitives: list[dict[str, Any]]) -> dict[str, Any]:
    """A ``foxglove.SceneEntity`` with every primitive list present (empty unless given), so
    strict decoders never meet a missing field. ``primitives``: arrows=, spheres=, lines=, …"""
    kinds = ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models")
    unknown = set(primitives) - set(kinds)
    if unknown:
        raise ValueError(f"unknown SceneEntity primitive list(s): {sorted(unknown)}")
    entity: dict[str, Any] = {"timestamp": time_dict(t_ns), "frame_id": frame_id,
                              "id": entity_id, "lifetime": {"sec": 0, "nsec": 0},
                              "frame_locked": False, "metadata": []}
    for kind in kinds:
        entity[kind] = list(primitives.get(kind, ()))
    return entity


def scene_update(entities: Sequence[dict[str, Any]] = (),
                 deletions: Sequence[dict[str, Any]] = ()) -> dict[str, Any]:
    """A ``foxglove.SceneUpdate`` payload."""
    return {"deletions": list(deletions), "entities": list(entities)}


def sphere(pos_m: Any, diameter_m: float, rgba: dict[str, float]) -> dict[str, Any]:
    """A ``SpherePrimitive`` at ``pos_m`` (metres) of the given diameter (metres)."""
    return {"pose": pose(pos_m, (1.0, 0.0, 0.0, 0.0)),
            "size": {"x": diameter_m, "y": diameter_m, "z": diameter_m}, "color": rgba}


def arrow(tail_m: Any, direction: Any, length_m: float, rgba: dict[str, float], *,
          shaft_diameter_m: float = 0.002) -> dict[str, Any] | None:
    """An ``ArrowPrimitive`` from ``tail_m`` along ``direction`` (any length), ``length_m`` long;
    None when the direction is zero or not finite."""
    dx, dy, dz = (float(v) for v in direction)
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not math.isfinite(n) or n < 1e-12 or not math.isfinite(length_m) or length_m <= 0:
        return None
    dx, dy, dz = dx / n, dy / n, dz / n
    # shortest rotation taking +x (Foxglove's arrow axis) onto d: q ∝ (1 + x·d, x × d)
    w, ax, ay, az = 1.0 + dx, 0.0, -dz, dy
    qn = math.sqrt(w * w + ay * ay + az * az)
    q = (0.0, 0.0, 0.0, 1.0) if qn < 1e-9 else (w / qn, ax, ay / qn, az / qn)
    head = min(0.3 * length_m, 0.01)
    return {"pose": pose(tail_m, q), "shaft_length": max(length_m - head, 0.0),
            "shaft_diameter": shaft_diameter_m, "head_length": head,
            "head_diameter": 2.5 * shaft_diameter_m, "color": rgba}


def model(url: str, pos_m: Any, quat_wxyz: Any, *, scale: float = 1.0,
          media_type: str = "", rgba: dict[str, float] | None = None) -> dict[str, Any]:
    """A ``ModelPrimitive`` referencing a mesh by URL (e.g. ``file:///…/textured.obj`` or
    ``package://…``); Foxglove loads glTF/GLB, STL, OBJ and DAE."""
    return {"pose": pose(pos_m, quat_wxyz), "scale": {"x": scale, "y": scale, "z": scale},
            "color": rgba or color(0.7, 0.7, 0.7, 1.0), "use_embedded_materials": rgba is None,
            "url": url, "media_type": media_type, "data": ""}


def line_list(points_m: Any, rgba: dict[str, float], *, thickness_m: float = 0.003
              ) -> dict[str, Any]:
    """A ``LinePrimitive`` of type LINE_LIST (pairs of points, metres, world frame)."""
    pts = np.asarray(points_m, dtype=float).reshape(-1, 3)
    return {"type": 2, "pose": pose((0, 0, 0), (1, 0, 0, 0)), "thickness": thickness_m,
            "scale_invariant": False,
            "points": [{"x": p[0], "y": p[1], "z": p[2]} for p in pts.tolist()],
            "color": rgba, "colors": [], "indices": []}


def compressed_image(jpeg: bytes, t_ns: int, *, frame_id: str = "view",
                     image_format: str = "jpeg") -> dict[str, Any]:
    """A ``foxglove.CompressedImage`` payload (JSON encoding: data is base64)."""
    return {"timestamp": time_dict(t_ns), "frame_id": frame_id,
            "data": base64.b64encode(jpeg).decode("ascii"), "format": image_format}


# --- contacts ---------------------------------------------------------------------------------------


@dataclass
class ContactRecord:
    """One hand–object contact as recorded on ``/contacts``.

    Positions metres, normals unit vectors from the hand into the object (the direction of the
    force the hand applies, as :mod:`sim.world.contacts`), each expressed in the world, in the object
    frame (``frame_obj``) and in the frame of ``hand_body`` (the fingertip body for fingertip
    contacts: what AutoWS needs). ``dist_m`` is the signed distance (negative = penetration),
    ``force_n`` the normal force in newtons (NaN when not computed).
    """

    finger: str | None
    hand_body: str
    pos_world_m: Array
    normal_world: Array
    pos_object_m: Array
    normal_object: Array
    pos_hand_body_m: Array
    normal_hand_body: Array
    dist_m: float
    force_n: float = float("nan")

    @classmethod
    def from_world(cls, *, finger: str | None, hand_body: str, pos_world_m: Any,
                   normal_world: Any, dist_m: float, object_pos_m: Any, object_quat_wxyz: Any,
                   body_pos_m: Any, body_quat_wxyz: Any,
                   force_n: float = float("nan")) -> ContactRecord:
        """Express a world contact in the object and hand-body frames, given both frames'
        world poses (metres, quaternions wxyz)."""
        p = np.asarray(pos_world_m, dtype=float)
        n = np.asarray(normal_world, dtype=float)
        inv_obj_p, inv_obj_q = transforms.pose_inv(np.asarray(object_pos_m, float),
                                                        np.asarray(object_quat_wxyz, float))
        inv_body_p, inv_body_q = transforms.pose_inv(np.asarray(body_pos_m, float),
                                                          np.asarray(body_quat_wxyz, float))
        return cls(finger=finger, hand_body=hand_body, pos_world_m=p, normal_world=n,
                   pos_object_m=inv_obj_p + transforms.rotate(inv_obj_q, p),
                   normal_object=transforms.rotate(inv_obj_q, n),
                   pos_hand_body_m=inv_body_p + transforms.rotate(inv_body_q, p),
                   normal_hand_body=transforms.rotate(inv_body_q, n),
                   dist_m=float(dist_m), force_n=float(force_n))

    def to_json(self) -> dict[str, Any]:
        """The ``dexaug.Contact`` JSON object."""
        force = float(self.force_n)
        dist = float(self.dist_m)
        return {"finger": self.finger, "hand_body": self.hand_body,
                "pos_world_m": finite_list(self.pos_world_m),
                "normal_world": finite_list(self.normal_world),
                "pos_object_m": finite_list(self.pos_object_m),
                "normal_object": finite_list(self.normal_object),
                "pos_hand_body_m": finite_list(self.pos_hand_body_m),
                "normal_hand_body": finite_list(self.normal_hand_body),
                "dist_m": dist if np.isfinite(dist) else None,
                "force_n": force if np.isfinite(force) else None}

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> ContactRecord:
        """Inverse of :meth:`to_json` (``None`` numbers come back as NaN)."""
        def arr(key: str) -> Array:
            return np.array([np.nan if v is None else v for v in obj[key]], dtype=float)

        def num(key: str) -> float:
            v = obj.get(key)
            return float("nan") if v is None else float(v)

        return cls(finger=obj.get("finger"), hand_body=obj["hand_body"],
                   pos_world_m=arr("pos_world_m"), normal_world=arr("normal_world"),
                   pos_object_m=arr("pos_object_m"), normal_object=arr("normal_object"),
                   pos_hand_body_m=arr("pos_hand_body_m"),
                   normal_hand_body=arr("normal_hand_body"), dist_m=num("dist_m"),
                   force_n=num("force_n"))


#: Marker colours: thumb red, then the other fingers, grey for palm/link contacts.
_FINGER_COLORS = (color(0.9, 0.2, 0.2), color(0.2, 0.7, 0.2), color(0.2, 0.4, 0.9),
                  color(0.9, 0.7, 0.1), color(0.7, 0.3, 0.8), color(0.2, 0.8, 0.8))
_OTHER_COLOR = color(0.6, 0.6, 0.6)


def contact_entity(contacts: Sequence[ContactRecord], t_ns: int, *,
                   fingers: Sequence[str] = (), sphere_diameter_m: float = 0.006,
                   arrow_m_per_n: float = 0.01, arrow_length_m: float = 0.03) -> dict[str, Any]:
    """The ``contacts`` SceneEntity (world frame): a sphere per contact coloured by finger (order
    of ``fingers``; grey when not a fingertip) and an arrow along the normal, into the object,
    ``arrow_m_per_n`` metres per newton of normal force (``arrow_length_m`` when the force is
    unknown)."""
    index = {f: i for i, f in enumerate(fingers)}
    spheres, arrows = [], []
    for c in contacts:
        i = index.get(c.finger) if c.finger is not None else None
        rgba = _FINGER_COLORS[i % len(_FINGER_COLORS)] if i is not None else _OTHER_COLOR
        if not np.isfinite(np.asarray(c.pos_world_m, dtype=float)).all():
            continue
        spheres.append(sphere(c.pos_world_m, sphere_diameter_m, rgba))
        length = (min(max(arrow_m_per_n * c.force_n, 0.005), 0.1) if np.isfinite(c.force_n)
                  else arrow_length_m)
        a = arrow(c.pos_world_m, c.normal_world, length, rgba)
        if a is not None:
            arrows.append(a)
    return scene_entity("contacts", t_ns, spheres=spheres, arrows=arrows)


#: Bones of the OpenXR hand skeleton (joint index pairs) for :func:`hand_skeleton_entity`.
OPENXR_BONES: tuple[tuple[int, int], ...] = tuple(
    (hand_messages.JOINT_INDEX[a], hand_messages.JOINT_INDEX[b])
    for finger, chain in (("thumb", ("metacarpal", "proximal", "distal", "tip")),
                          ("index", ("metacarpal", "proximal", "intermediate", "distal", "tip")),
                          ("middle", ("metacarpal", "proximal", "intermediate", "distal", "tip")),
                          ("ring", ("metacarpal", "proximal", "intermediate", "distal", "tip")),
                          ("little", ("metacarpal", "proximal", "intermediate", "distal", "tip")))
    for a, b in zip(("wrist", *(f"{finger}_{j}" for j in chain[:-1])),
                    (f"{finger}_{j}" for j in chain), strict=True)
)


def hand_skeleton_entity(hand: hand_messages.HandState, t_ns: int, *, entity_id: str,
                         rgba: dict[str, float] | None = None) -> dict[str, Any]:
    """The operator's tracked hand (raw input) as spheres at the valid joints (their radius)
    and lines along the bones, world frame."""
    rgba = rgba or color(1.0, 0.8, 0.6, 0.8)
    valid = np.asarray(hand.valid, dtype=bool)
    spheres = [sphere(hand.positions[i], 2.0 * float(hand.radii[i]), rgba)
               for i in np.flatnonzero(valid)]
    pts = [hand.positions[k] for a, b in OPENXR_BONES if valid[a] and valid[b] for k in (a, b)]
    lines = [line_list(np.array(pts), rgba)] if pts else []
    return scene_entity(entity_id, t_ns, spheres=spheres, lines=lines)
