"""A recorded session's object mode and table, for running its input through a bridge again.

Why: a session recorded since the demonstration mode names the bridge's ``object_mode`` and
its ``table`` in its metadata (:mod:`teleop.bridge.control`); replaying or re-recording it
should put the object in the same situation, or the operator's input meets a different world.
Older sessions, and raw-input ones that never went through a bridge (a synthetic operator's, a
capture), name neither: they ran with a free object, so they are treated as ``"free"`` with the
table of the bridge's config, and that is logged. An explicit mode (``--object-mode``, the
``object_mode`` argument) wins over the session's.

The resting pose (:func:`session_object_rest`): a session recorded since resting poses names
the ``object_rest`` it started with; its index and yaw are the ``set_object_rest`` arguments
that put the object back that way (the index names a pose of the same computation when its
``poses_key`` matches the bridge's, :class:`teleop.bridge.object_mode.RestChoice`). A session
without it, or with the upright home pose (index null), needs nothing.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path
from typing import Any

import zenoh

from sim.errors import ConfigError
from teleop import keys as zkeys
from teleop.bridge.config import BridgeConfig, check_object_mode

__all__ = ["ask_bridge", "session_config", "session_object_mode", "session_object_rest",
           "tell_bridge"]

logger = logging.getLogger(__name__)

_OLD_MODE = "free"  # what a session without an object_mode key ran in


def session_object_mode(meta: dict[str, Any], source: Path | str,
                        object_mode: str | None = None) -> str:
    """``object_mode`` if given, else the session's, else ``"free"`` (an older session)."""
    if object_mode is not None:
        return check_object_mode(object_mode, "object_mode")
    if "object_mode" not in meta:
        logger.info("%s: no object_mode in its metadata (an older or raw-input session): "
                    "treated as %r", source, _OLD_MODE)
        return _OLD_MODE
    return check_object_mode(meta["object_mode"], f"{source}: metadata object_mode")


def session_object_rest(meta: dict[str, Any], source: Path | str) -> dict[str, Any] | None:
    """The ``set_object_rest`` arguments (``rest``, ``yaw_deg``) of the session's resting pose,
    None when it started upright at the home pose or predates resting poses; ConfigError naming
    ``source`` when the record is malformed."""
    rest = meta.get("object_rest")
    if rest is None or (isinstance(rest, dict) and rest.get("index") is None):
        return None
    index = rest.get("index") if isinstance(rest, dict) else None
    yaw = rest.get("yaw_deg") if isinstance(rest, dict) else None
    if isinstance(index, bool) or not isinstance(index, int) or index < 0 or \
            isinstance(yaw, bool) or not isinstance(yaw, int | float):
        raise ConfigError(f"{source}: metadata object_rest: expected null or an object with an "
                          f"integer index >= 0 and a number yaw_deg, got {rest!r}")
    return {"rest": index, "yaw_deg": float(yaw)}


def _session_table(meta: dict[str, Any], source: Path | str, cfg: BridgeConfig) -> bool:
    """Whether the session had a table (its ``table`` record), else the config's choice."""
    if "table" not in meta:
        logger.info("%s: no table in its metadata: the bridge config's (table = %s)", source,
                    str(cfg.table).lower())
        return cfg.table
    table = meta["table"]
    if table is not None and not (isinstance(table, dict) and "top_z_m" in table):
        raise ConfigError(f"{source}: metadata table: expected null or an object with top_z_m, "
                          f"center_m, half_extents_m, got {table!r}")
    return table is not None


def session_config(cfg: BridgeConfig, meta: dict[str, Any], source: Path | str,
                   object_mode: str | None = None) -> BridgeConfig:
    """``cfg`` with the session's object mode (:func:`session_object_mode`) and table."""
    return dataclasses.replace(cfg, object_mode=session_object_mode(meta, source, object_mode),
                               table=_session_table(meta, source, cfg))


def ask_bridge(client: zenoh.Session, rig: str, command: str, payload: dict[str, Any], *,
               wait_s: float = 5.0, reply_s: float = 1.0) -> dict[str, Any] | None:
    """Send the control ``command`` with ``payload`` to the bridge of ``rig``; its reply (``ok``
    False and ``error`` when it refused), or None when no bridge answered within ``wait_s``
    seconds (a freshly opened peer sees the bridge's queryable only once the routes are up; a
    subscriber that is no bridge has none). ``reply_s``: how long one query waits for its
    answer — long enough for the command to finish, as a query that times out is sent again."""
    key = zkeys.RigKeys(rig).control_cmd(command)
    t_end = time.perf_counter() + wait_s
    while True:
        try:
            return zkeys.query_json(client, key, payload, timeout_s=reply_s)
        except RuntimeError as exc:
            if time.perf_counter() >= t_end:
                logger.debug("no bridge answered %s: %s", key, exc)
                return None
            time.sleep(0.1)


def tell_bridge(client: zenoh.Session, rig: str, mode: str, *, wait_s: float = 5.0
                ) -> dict[str, Any] | None:
    """Ask the bridge of ``rig`` to switch to ``mode`` (``set_object_mode``); its reply, or
    None with a warning when no bridge answered within ``wait_s`` seconds or it refused."""
    reply = ask_bridge(client, rig, "set_object_mode", {"object_mode": mode}, wait_s=wait_s)
    if reply is None or not reply.get("ok"):
        logger.warning("the bridge of rig %r did not set object mode %r: %s", rig, mode,
                       "no bridge answered" if reply is None else reply.get("error"))
        return None
    return reply
