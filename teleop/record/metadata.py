"""The ``dexaug.session`` metadata record of a recording: what goes in it and how it is stored.

Why one module for both directions: MCAP metadata values are strings, so the recorder encodes
every non-string value as JSON and lists those keys under :data:`schemas.JSON_KEYS_KEY`; the
session reader must undo exactly that. Writing (:func:`session_metadata`,
:func:`encode_metadata`) and reading (:func:`decode_metadata`) side by side keeps the round trip
exact. Plain strings stay plain, so the record stays readable in any MCAP viewer.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import platform
from collections.abc import Mapping
from importlib import metadata as _importlib_metadata
from pathlib import Path
from typing import Any

import numpy as np

from teleop.record import schemas

__all__ = ["decode_metadata", "encode_metadata", "session_metadata"]

log = logging.getLogger(__name__)


def _package_version(name: str) -> str:
    try:
        return _importlib_metadata.version(name)
    except _importlib_metadata.PackageNotFoundError:
        return "not installed"


def session_metadata(user: Mapping[str, Any], *, start_time_ns: int, own_clock: bool
                     ) -> dict[str, Any]:
    """The recorder's keys (``format_version``, software versions, ``created_utc``,
    ``start_time_ns``, ``clock``: ``unix_ns`` for the recorder's own clock, else ``caller``)
    updated with the caller's ``user`` keys. Raises ValueError when ``user`` sets a key only the
    recorder may set."""
    reserved = {"format_version", schemas.JSON_KEYS_KEY}
    clash = reserved & set(user)
    if clash:
        raise ValueError(f"metadata keys {sorted(clash)} are set by the recorder")
    meta: dict[str, Any] = {
        "format_version": schemas.FORMAT_VERSION,
        "dexaug_version": _package_version("dexaug"),
        "mcap_version": _package_version("mcap"),
        "foxglove_sdk_version": _package_version("foxglove-sdk"),   # the writer (recorder)
        "numpy_version": np.__version__,
        "mujoco_version": _package_version("mujoco"),
        "python_version": platform.python_version(),
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "start_time_ns": start_time_ns,
        "clock": "unix_ns" if own_clock else "caller",
    }
    meta.update(user)
    return meta


def encode_metadata(meta: Mapping[str, Any]) -> dict[str, str]:
    """MCAP metadata values are strings: plain strings stay readable in any viewer, other
    values are JSON and listed under :data:`schemas.JSON_KEYS_KEY` for exact round trips."""
    record: dict[str, str] = {}
    json_keys = []
    for key, value in meta.items():
        if isinstance(value, str):
            record[key] = value
        else:
            try:
                record[key] = json.dumps(value, allow_nan=False, default=_json_default)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"metadata[{key!r}] is not JSON-serialisable: {exc}"
                                 ) from None
            json_keys.append(key)
    record[schemas.JSON_KEYS_KEY] = json.dumps(sorted(json_keys))
    return record


def decode_metadata(record: dict[str, str]) -> dict[str, Any]:
    """Inverse of :func:`encode_metadata` (values that do not decode stay strings, with a
    warning)."""
    json_keys = set()
    if schemas.JSON_KEYS_KEY in record:
        try:
            json_keys = set(json.loads(record[schemas.JSON_KEYS_KEY]))
        except ValueError:
            log.warning("metadata key %s is not a JSON list; values left as strings",
                        schemas.JSON_KEYS_KEY)
    out: dict[str, Any] = {}
    for key, value in record.items():
        if key == schemas.JSON_KEYS_KEY:
            continue
        if key in json_keys:
            try:
                out[key] = json.loads(value)
                continue
            except ValueError:
                log.warning("metadata %s is not valid JSON; kept as a string", key)
        out[key] = value
    return out


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")
