"""The bridge's ``status`` reply as a type: what ``BridgeControl.status`` answers, locally and
as JSON over the rig's control queryable.

Why its own module: the CLI, the dashboard and the tests read its keys across packages, and a
TypedDict lets the checker hold the producer (:mod:`teleop.bridge.control`) and every reader to
the same keys; ``tests/test_bridge.py`` asserts a live reply has exactly them.
"""

from __future__ import annotations

from typing import TypedDict

__all__ = ["BridgeStatus"]


class BridgeStatus(TypedDict):
    """The ``status`` reply (``BridgeControl.status``, JSON over the control queryable), key by key."""

    ok: bool
    rig: str
    hand: str
    object: str
    counts: dict[str, int]            # frames received, processed, superseded, ... (Counter)
    held: dict[str, int]              # frames the retargeter held, by reason
    recording: str | None             # the session file being written, if any
    last_seq: int | None              # the last hand frame's sequence number
    sim_time_s: float
    view: bool                        # a head-following view is being streamed
    loop_running: bool
    deterministic: bool
    object_mode: str                  # "demo" (held fixed) or "free"
    object_held: bool
    object_rest: int | None           # the resting pose's index (None: upright)
    object_rest_yaw_deg: float | None
