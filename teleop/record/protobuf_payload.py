"""Protobuf messages of a recording, decoded with the schema stored in the file itself.

Why: since session format 2 the ``foxglove.*`` channels (``/tf``, ``/markers``, ``/view``) are
the ``foxglove-sdk``'s protobuf messages; their schema records hold the protobuf file descriptor
set, so any reader (Foxglove, the ``mcap`` tools, this module) decodes them without generated
code, and a schema that does not describe the bytes is an error, not a guess. The session
reader gives every Foxglove message in its **JSON form** (:func:`to_json_form`: every field
present, times as ``{"sec", "nsec"}``, enums as numbers, bytes as base64) — exactly what format 1
stored as JSON — so consumers read old and new recordings alike.
"""

from __future__ import annotations

import base64
import functools
import hashlib
from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.descriptor import Descriptor, FieldDescriptor
from google.protobuf.message import DecodeError, Message
from google.protobuf.unknown_fields import UnknownFieldSet

__all__ = ["decode", "message_class", "to_json_form", "unknown_fields"]

#: protobuf well-known types that Foxglove's JSON form writes as {"sec", "nsec"}
_TIME_TYPES = frozenset({"google.protobuf.Timestamp", "google.protobuf.Duration"})


@functools.lru_cache(maxsize=64)
def _message_class(name: str, digest: str, schema_data: bytes) -> type[Message]:
    del digest   # part of the cache key only
    files = descriptor_pb2.FileDescriptorSet.FromString(schema_data)
    pool = descriptor_pool.DescriptorPool()   # one per schema: no clash with other versions
    for f in files.file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def message_class(schema_name: str, schema_data: bytes) -> type[Message]:
    """The message class that a ``protobuf`` schema record (name, file descriptor set)
    describes; cached per schema. Raises ValueError when the descriptor set does not parse or
    lacks the message."""
    try:
        return _message_class(schema_name, hashlib.sha256(schema_data).hexdigest(),
                              bytes(schema_data))
    except (DecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"protobuf schema {schema_name!r} is unusable: {exc}") from None


def decode(schema_name: str, schema_data: bytes, data: bytes) -> Message:
    """Parse ``data`` as the schema's message; ValueError when the bytes do not parse."""
    cls = message_class(schema_name, schema_data)
    try:
        return cls.FromString(data)
    except DecodeError as exc:
        raise ValueError(f"not a valid {schema_name} message: {exc}") from None


def _repeated(field: FieldDescriptor) -> bool:
    if hasattr(field, "is_repeated"):   # protobuf ≥ 6.30 (``label`` is gone in 7)
        return bool(field.is_repeated)
    return field.label == FieldDescriptor.LABEL_REPEATED  # pragma: no cover (older protobuf)


def _value(field: FieldDescriptor, value: Any) -> Any:
    if field.type == FieldDescriptor.TYPE_MESSAGE:
        return to_json_form(value)
    if field.type == FieldDescriptor.TYPE_BYTES:
        return base64.b64encode(value).decode("ascii")
    return value   # numbers, strings, bools; enums as their numbers


def to_json_form(msg: Message) -> dict[str, Any]:
    """The message as Foxglove's JSON schema spells it: every field present (defaults filled),
    ``Timestamp``/``Duration`` as ``{"sec", "nsec"}``, enums as numbers, bytes as base64."""
    desc: Descriptor = msg.DESCRIPTOR
    if desc.full_name in _TIME_TYPES:
        return {"sec": int(msg.seconds), "nsec": int(msg.nanos)}
    out: dict[str, Any] = {}
    for field in desc.fields:
        value = getattr(msg, field.name)
        if _repeated(field):
            out[field.name] = [_value(field, v) for v in value]
        else:
            out[field.name] = _value(field, value)
    return out


def unknown_fields(msg: Message, path: str = "") -> list[str]:
    """Where ``msg`` holds bytes its schema does not describe (field paths, empty when none):
    a strict validation of a message against the schema it was decoded with."""
    found = [path or msg.DESCRIPTOR.full_name] if len(UnknownFieldSet(msg)) else []
    for field, value in msg.ListFields():
        if field.type != FieldDescriptor.TYPE_MESSAGE:
            continue
        items = value if _repeated(field) else [value]
        for i, item in enumerate(items):
            found += unknown_fields(item, f"{path}{field.name}[{i}].")
    return found
