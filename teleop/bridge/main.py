"""``dexaug bridge``: run one :class:`teleop.bridge.bridge.Bridge` in the foreground.

Why a module of its own: the command-line entry point owns the process-level choices (the
config file, the listening port, the object mode, recording from the start, a hook after each
recording, the live Foxglove server) and the Ctrl-C handling, none of which a bridge used as a
library (rerecording, tests) wants.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from pathlib import Path

from teleop.bridge.bridge import Bridge
from teleop.bridge.config import check_object_mode, load_bridge_config
from teleop.bridge.foxglove_live import FoxgloveLive

__all__ = ["bridge_main"]

logger = logging.getLogger(__name__)


def bridge_main(hand: str, obj: str | None = None, rig: str = "local", *,
                config_path: Path | str | None = None, listen_port: int | None = 7447,
                connect_ports: tuple[int, ...] = (), duration_s: float | None = None,
                record: Path | str | None = None, view: bool | None = None,
                object_mode: str | None = None, object_rest: int | None = None,
                object_yaw_deg: float | None = None,
                on_recording_closed: Callable[[Path], None] | None = None,
                foxglove: tuple[str, int] | None = None,
                on_foxglove: Callable[[FoxgloveLive], None] | None = None) -> int:
    """``dexaug bridge``: run a bridge until Ctrl-C (or ``duration_s``); ``object_mode``
    ("demo" or "free") overrides the config's; ``object_rest`` lays the object in that resting
    pose (:mod:`sim.world.resting`, best first; ``object_yaw_deg`` about the table normal);
    ``record`` starts a recording at that path right away; ``on_recording_closed(path)`` runs
    after each recording is closed (e.g. to augment it); ``foxglove`` (host, port) serves the
    live state on a Foxglove WebSocket server (:mod:`teleop.bridge.foxglove_live`, loopback
    only), handed to ``on_foxglove`` once it listens. Returns a process exit code."""
    cfg = load_bridge_config(config_path)
    if view is not None:
        cfg.view_enabled = view
    if object_mode is not None:
        cfg.object_mode = check_object_mode(object_mode, "--object-mode")
    with Bridge(hand, obj, rig, cfg, listen_port=listen_port, connect_ports=tuple(connect_ports),
                on_recording_closed=on_recording_closed) as bridge, \
            contextlib.ExitStack() as opened:   # the live server stops before the bridge closes
        if foxglove is not None:
            bridge.live = FoxgloveLive(host=foxglove[0], port=foxglove[1], name=f"dexaug {rig}",
                                       fingers=bridge.hand.finger_names,
                                       world_offset_m=cfg.world_offset_m)
            opened.callback(bridge.live.close)
            logger.info("Foxglove live server on %s", bridge.live.url)
            if on_foxglove is not None:
                on_foxglove(bridge.live)
        if object_rest is not None:
            rest = {"rest": object_rest, **({} if object_yaw_deg is None
                                            else {"yaw_deg": object_yaw_deg})}
            reply = bridge.control("set_object_rest", rest)
            if not reply["ok"]:
                logger.error("--object-rest %d: %s", object_rest, reply["error"])
                return 2
        if record is not None:
            bridge.control("start_recording", {"path": str(record)})
        logger.info("bridge %s: hands on %s, state on %s, control on %s, object mode %s", rig,
                    bridge.keys.hands, bridge.keys.state, bridge.keys.control, bridge.object_mode)
        try:
            bridge.run(duration_s=duration_s)
        except KeyboardInterrupt:
            logger.info("interrupted")
    return 0
