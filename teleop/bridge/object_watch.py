"""An object that leaves the table is put back on its spot, with an event.

Why: in free mode a pushed or dropped object went over the table's edge and, with nothing
below, fell for the rest of the session. The bridge's scene has a floor now (at the operator's
floor, ``world_offset_m`` z: :class:`sim.world.scene.Scene` ``floor_z_m``), so a fallen object
lands, and after each batch of physics steps the bridge looks where the object's centre of mass
is: more than ``object_reset_below_m`` below the table top, or more than
``object_reset_beyond_m`` past its edge (horizontally; metres), it has left the table. Once it
has been off for ``object_reset_after_s`` of simulated time (the operator sees where it went
and that it landed; a brief dip over the edge of a carried object does not count) it is placed
on its spot for the current mode (``_place_object``: demo mode drops, settles and holds it),
with ``object_reset`` (``object``, ``reason``, the placement) on ``/events`` and in the
recording, ``counts["object_left_table"]`` and a DEBUG log line. The placement starts a hand entry
(:mod:`teleop.bridge.entry`): the object may reappear inside the operator's hand, and contacts
come back only once the hand is clear of it.

A scene without a table has no "on the table": nothing is checked. Cost: a few array reads a
tick.

:class:`ObjectWatch` is a mixin of :class:`teleop.bridge.bridge.Bridge` (through
:class:`teleop.bridge.faults.BridgeFaults`); the attributes annotated on it are the bridge's.
"""

from __future__ import annotations

import logging
import threading
from collections import Counter
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from sim.world.scene import Scene
from teleop.bridge.config import BridgeConfig
from teleop.bridge.object_mode import Placement, table_record

__all__ = ["ObjectWatch", "left_table"]

logger = logging.getLogger(__name__)


def left_table(scene: Scene, below_m: float, beyond_m: float) -> str | None:
    """Why the scene's object is off its table, in words (module docstring); None while it is
    on it, and in a scene without a table."""
    table = table_record(scene)
    if table is None:
        return None
    centre = scene.data.xipos[scene.obj_body]
    drop_m = table["top_z_m"] - float(centre[2])
    if drop_m > below_m:
        return f"left the table: its centre is {drop_m:.3f} m below the table top"
    past_m = float(np.max(np.abs(centre[:2] - table["center_m"]) - table["half_extents_m"]))
    if past_m > beyond_m:
        return f"left the table: its centre is {past_m:.3f} m past the table's edge"
    return None


class ObjectWatch:
    """Puts an object that left the table back (module docstring)."""

    config: BridgeConfig
    scene: Scene
    object_name: str
    counts: Counter[str]
    _lock: threading.Lock
    if TYPE_CHECKING:   # the host's read-only property (Bridge.sim_time_s), typed for this mixin
        @property
        def sim_time_s(self) -> float: ...
    _place_object: Callable[[], Placement]
    _notify: Callable[[str, dict[str, Any]], None]

    def _init_object_watch(self) -> None:
        self._off_table_since_s: float | None = None   # simulated time it was first seen off

    def _watch_object(self) -> None:
        """After physics steps: place the object again once it has been off the table for
        ``object_reset_after_s``."""
        cfg = self.config
        why = left_table(self.scene, cfg.object_reset_below_m, cfg.object_reset_beyond_m)
        t_s = self.sim_time_s
        if why is None or self._off_table_since_s is None or t_s < self._off_table_since_s:
            self._off_table_since_s = None if why is None else t_s
            return
        if t_s - self._off_table_since_s < cfg.object_reset_after_s:
            return
        self._off_table_since_s = None
        placement = self._place_object()   # the hand enters again (BridgeControl)
        with self._lock:
            self.counts["object_left_table"] += 1
        # DEBUG: it happens in most runs after the release (the hand lets go above the table,
        # the object falls), which is no news; the object_reset event and counts say it too
        logger.debug("%s %s: placed on its spot again", self.object_name, why)
        self._notify("object_reset", {"object": self.object_name, "reason": why,
                                      **placement.to_json()})
