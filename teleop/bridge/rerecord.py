"""Record a session again through the live bridge: raw input in, a full session out.

Why: a session that holds only raw input (a synthetic operator's, a headset capture recorded
elsewhere, or a session recorded with an older retargeter) has no simulated state or contacts,
and demo extraction needs both. Re-recording replays the ``/hands`` bytes over zenoh into a real
:class:`teleop.bridge.bridge.Bridge` (its own loopback peer, deterministic mode: every frame processed
in order with a fixed number of physics steps, so the output depends only on the input) and
records what the bridge does, exactly as a live session would be recorded. Operator
``grasp_mark`` events of the source are re-issued to the bridge at the same input frame, so
explicit marks survive. The object is in the session's mode on the session's table
(:mod:`teleop.bridge.session_mode`: an older session without them ran free). It lives with the
bridge it drives: :mod:`teleop.record` (sessions,
replay, demos) stays below the bridge and never runs one.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path
from typing import Any

import numpy as np

from sim.errors import DexaugError
from sim.io import atomic_path
from sim.transforms import quat_to_mat
from teleop import keys as zkeys
from teleop.bridge.bridge import Bridge
from teleop.bridge.config import BridgeConfig, load_bridge_config
from teleop.bridge.session_mode import session_config, session_object_rest
from teleop.record.replay import hands_publisher, play
from teleop.record.schemas import TOPIC_HANDS
from teleop.record.session import Session, open_session

logger = logging.getLogger(__name__)

__all__ = ["RerecordError", "rerecord"]


class RerecordError(DexaugError):
    """The source session cannot be re-recorded (no input, no hand or object named)."""


def _mark_indices(src: Session, hands_log_ns: np.ndarray) -> list[int]:
    """Counts of ``/hands`` messages (log times ``hands_log_ns``, in order) logged at or before
    each ``grasp_mark`` of the source: the points at which to re-issue the marks."""
    marks = sorted(t for t, e in src.events() if e.get("type") == "grasp_mark")
    counts = np.searchsorted(hands_log_ns, marks, side="right")
    return [int(c) for c in counts if c > 0]


def _placement(cfg: BridgeConfig, meta: dict[str, Any]) -> BridgeConfig:
    """The bridge config with the object where the source session had it: a synthetic
    operator's session records ``object_pos_m`` / ``object_quat_wxyz`` in the operator's
    tracking space, which the bridge maps to its world by ``world_offset_m``; the object rests
    on the table, so only x, y and the yaw carry over."""
    if "object_pos_m" not in meta:
        return cfg
    pos = np.asarray(meta["object_pos_m"], float) + cfg.world_offset_m
    yaw_deg = cfg.object_yaw_deg
    if "object_quat_wxyz" in meta:
        r = quat_to_mat(np.asarray(meta["object_quat_wxyz"], float))
        yaw_deg = math.degrees(math.atan2(r[1, 0], r[0, 0]))
    return dataclasses.replace(cfg, object_pos_m=pos[:2], object_yaw_deg=yaw_deg)


def rerecord(src_path: Path | str, out_path: Path | str, *, hand: str | None = None,
             object_name: str | None = None, object_mode: str | None = None,
             rig: str = "rerecord", view: bool = False, timeout_s: float = 120.0) -> Path:
    """Replay the ``/hands`` of ``src_path`` through a bridge and record to ``out_path``.

    ``hand`` and ``object_name`` default to the source's metadata, and so does the object's
    placement on the table (when recorded); ``object_mode`` ("demo" or "free") to the
    source's, "free" for an older session. The output is written to a
    temporary name and renamed when complete, so an interrupted run leaves nothing behind.

    Raises:
        RerecordError: the source has no ``/hands`` messages or names no hand/object.
    """
    src = open_session(src_path)
    hand = hand or src.metadata.get("hand")
    object_name = object_name or src.metadata.get("object")
    if not hand or not object_name:
        raise RerecordError(f"{src_path}: session metadata names no hand/object "
                            f"(hand={hand!r}, object={object_name!r}); pass them explicitly")
    if not src.counts.get(TOPIC_HANDS):
        raise RerecordError(f"{src_path}: no {TOPIC_HANDS} messages to replay")
    messages = list(src.messages(TOPIC_HANDS, decode=False))
    payloads = [(m.log_time_ns * 1e-9, m.data) for m in messages]
    marks = _mark_indices(src, np.array([m.log_time_ns for m in messages], dtype=np.int64))
    cfg = session_config(_placement(load_bridge_config(), src.metadata), src.metadata,
                         src_path, object_mode)
    cfg = dataclasses.replace(cfg, deterministic=True, view_enabled=view)
    port = zkeys.free_tcp_port()
    out_path = Path(out_path)
    with atomic_path(out_path) as tmp, \
            Bridge(hand, object_name, rig, cfg, listen_port=port) as bridge:
        client = zkeys.open_session(connect_ports=[port])
        try:
            bridge.start()
            if (rest := session_object_rest(src.metadata, src_path)) is not None:
                reply = bridge.control("set_object_rest", rest)   # the object as it lay
                if not reply["ok"]:
                    raise RerecordError(f"{src_path}: cannot place the object as recorded: "
                                        f"{reply['error']}")
            bridge.control("start_recording", {"path": str(tmp), "overwrite": True})
            pub = hands_publisher(client, rig, 5.0)
            try:
                sent = 0
                for stop in [*marks, len(payloads)]:
                    sent += play(pub, payloads[sent:stop], "max")
                    if not bridge.wait_idle(timeout_s, received=sent):
                        raise RerecordError(f"bridge did not process {sent} frames of "
                                            f"{src_path} within {timeout_s} s")
                    if stop != len(payloads):
                        bridge.control("mark_grasp", {"source": "rerecord"})
            finally:
                pub.undeclare()
            bridge.control("stop_recording")
        finally:
            client.close()
    logger.info("re-recorded %s (%d frames, %d marks, object mode %s) to %s", src_path,
                len(payloads), len(marks), cfg.object_mode, out_path)
    return out_path
