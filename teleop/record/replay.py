"""Publish recorded hand tracking back onto zenoh, so recordings exercise the live bridge path.

Why raw bytes: a session's ``/hands`` channel stores the exact wire bytes the bridge received
(:mod:`teleop.record.schemas`), and :func:`replay` republishes those bytes unchanged, so a replayed
session is bit-identical input and the bridge cannot tell replay from live. IWER captures (the
real Quest recordings) are lists of :class:`HandFrame` and go through
:func:`replay_capture`, which encodes them exactly as ingest would.

Timing: ``rate=1.0`` keeps the original spacing (MCAP log times, or the frames' device times),
``rate=2.0`` plays twice as fast, ``rate="max"`` publishes back to back. The publisher uses
reliable, blocking congestion control, so "as fast as possible" never silently drops frames on
the sender side (the bridge itself keeps only the latest unless it runs in deterministic mode).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

import zenoh

from sim.errors import ConfigError
from teleop import keys as zkeys
from teleop.messages import HandFrame, encode
from teleop.record.schemas import TOPIC_HANDS
from teleop.record.session import SessionError, open_session

logger = logging.getLogger(__name__)


def hands_publisher(session: zenoh.Session, rig: str, wait_for_subscriber_s: float
               ) -> zenoh.Publisher:
    """A blocking, reliable publisher on the rig's ``/hands``; waits (up to the limit) until
    some subscriber matches, so the first frames are not published into the void."""
    pub = session.declare_publisher(zkeys.RigKeys(rig).hands,
                                    congestion_control=zenoh.CongestionControl.BLOCK,
                                    reliability=zenoh.Reliability.RELIABLE)
    t_end = time.perf_counter() + wait_for_subscriber_s
    # zenoh's stub types matching_status as bool; it is a MatchingStatus (.matching)
    while not pub.matching_status.matching:  # type: ignore[attr-defined]
        if time.perf_counter() >= t_end:
            logger.warning("replay: no subscriber on %s after %.1f s; publishing anyway",
                           pub.key_expr, wait_for_subscriber_s)
            break
        time.sleep(0.01)
    return pub


def check_rate(rate: float | str) -> None:
    """Raise :class:`ConfigError` unless ``rate`` is ``"max"`` or a finite number > 0 (checked
    before anything connects or loads, so a bad ``--rate`` is a one-line error)."""
    if rate == "max":
        return
    if isinstance(rate, bool) or not isinstance(rate, int | float) or not (
            math.isfinite(rate) and rate > 0):
        raise ConfigError(f"replay rate: expected a finite number > 0 (1.0: original speed) or "
                          f"'max', got {rate!r}")


def play(pub: zenoh.Publisher, items: Iterable[tuple[float, bytes]], rate: float | str) -> int:
    """Publish (time_s, payload) pairs with the timing of ``rate``; returns the count."""
    check_rate(rate)
    n = 0
    t0_wall: float | None = None   # the first frame's wall and message times (s)
    t0_msg = 0.0
    for t_s, payload in items:
        if rate != "max":
            if t0_wall is None:
                t0_wall, t0_msg = time.perf_counter(), t_s
            delay = t0_wall + (t_s - t0_msg) / float(rate) - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        pub.put(payload)
        n += 1
    return n


def replay(path: Path | str, session: zenoh.Session, rig: str, rate: float | str = 1.0, *,
           wait_for_subscriber_s: float = 5.0) -> int:
    """Publish the ``/hands`` messages of the recording at ``path`` on ``dexaug/<rig>/hands``
    (raw bytes, original order; timing from the MCAP log times scaled by ``rate``, or ``"max"``).
    Returns the number of messages published.

    Raises:
        ConfigError: ``rate`` is not a number > 0 or "max".
        SessionError: the recording cannot be read or holds no ``/hands`` message (nothing to
            replay: a session written by a script or a trajectory import has only ``/state``;
            for a truncated file the message says where it was cut).
    """
    check_rate(rate)
    sess = open_session(path)
    if not sess.counts.get(TOPIC_HANDS):
        cut = f"; the file is {sess.cut_note}" if sess.truncated else (
            " (it was not recorded from hand tracking: nothing to replay)")
        raise SessionError(f"{path}: no {TOPIC_HANDS} messages{cut}")
    items = ((m.log_time_ns * 1e-9, m.data)
             for m in sess.messages(TOPIC_HANDS, decode=False))
    pub = hands_publisher(session, rig, wait_for_subscriber_s)
    try:
        n = play(pub, items, rate)
    finally:
        pub.undeclare()
    logger.info("replayed %d /hands messages of %s", n, path)
    return n


def replay_capture(frames: Sequence[HandFrame], session: zenoh.Session, rig: str,
                   rate: float | str = 1.0, *, wait_for_subscriber_s: float = 5.0) -> int:
    """Publish a list of frames (e.g. :func:`teleop.input.iwer.iwer_hand_frames` of a Quest capture),
    encoded as ingest would, timed by their ``device_time_s``. Returns the count."""
    payloads = [(f.device_time_s, encode(f)) for f in frames]
    pub = hands_publisher(session, rig, wait_for_subscriber_s)
    try:
        return play(pub, payloads, rate)
    finally:
        pub.undeclare()
