"""The ``replay`` subcommand: a recorded session's hand tracking published back onto zenoh,
once a bridge listens.

Why a module of its own: replay is the headset-free half of every test and recipe, and its
one guard — refusing to publish into a network where no bridge subscribes, which used to exit
0 having done nothing — is a zenoh matching-status wait that the live commands do not need.
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console

from dexaug.commands.argtypes import port, positive, rate, rig_name
from dexaug.commands.registry import command
from sim.errors import NetworkError, UsageError

if TYPE_CHECKING:
    import zenoh

#: ``replay --wait-bridge-s``: how long replay waits for a bridge (any subscriber of the rig's
#: hands) before it gives up; generous, as a bridge loading its hand and scene takes seconds
WAIT_BRIDGE_S = 30.0
#: a committed session that replays, named when a session cannot (recordings/README.md)
_REPLAYABLE_SAMPLE = "recordings/bridge_043_phillips_screwdriver.mcap"


def _replay_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="MCAP session to replay")
    p.add_argument("--rate", type=rate, default=1.0,
                   help="playback speed factor (> 0), or 'max'; default %(default)s")
    p.add_argument("--rig", type=rig_name, default="local", help="zenoh key prefix "
                   "dexaug/<rig>/… (letters, digits, _ and -)")
    p.add_argument("--connect", type=port, nargs="+", default=[7447],
                   help="bridge port(s) to connect to on 127.0.0.1")
    p.add_argument("--object", metavar="ID",
                   help="put this object on the bridge's table first (default: the session's "
                   "object, so its grasps meet what they were made on; none: keep the "
                   "bridge's)")
    p.add_argument("--object-mode", choices=("demo", "free"),
                   help="set the bridge's object mode first (default: the session's; free for "
                   "an older session that records none)")
    p.add_argument("--wait-bridge-s", type=positive, default=WAIT_BRIDGE_S, metavar="SECONDS",
                   help="how long to wait for a bridge (a subscriber of dexaug/<rig>/hands, "
                   "found through zenoh's matching status) before giving up with exit status "
                   "2 and nothing published; default %(default)g s")


@command("replay", _replay_args)
def replay(args: argparse.Namespace, console: Console) -> int:
    """Publish a recorded session's hand tracking back onto zenoh (dexaug/<rig>/hands).

    With original timing (--rate 1.0), scaled, or as fast as possible (--rate max); the bridge
    cannot tell a replay from a live headset. The bridge is first given the session's object
    (or --object's; exit status 2 when it refuses it) and put in the session's object mode (or
    --object-mode's). A session without hand frames is refused (exit status 2), and so is a
    replay no bridge listens to within --wait-bridge-s (nothing is published).
    """
    from teleop.bridge.session_mode import session_object_mode, tell_bridge
    from teleop.keys import free_tcp_port, open_session
    from teleop.record.replay import replay as replay_session
    from teleop.record.schemas import TOPIC_HANDS
    from teleop.record.session import open_session as open_recording

    recording = open_recording(args.file)
    if not recording.counts.get(TOPIC_HANDS):
        held = ", ".join(f"{t} {n}" for t, n in recording.counts.items() if n) or "no messages"
        what = ("a scripted demonstration (`dexaug demo script`): the robot's states, no "
                "person's hand frames" if recording.metadata.get("scripted") is True
                else f"no hand frames ({TOPIC_HANDS})")
        raise UsageError(f"{args.file}: {what} to replay; it holds {held}. Sessions with "
                         f"hand tracking replay: a headset's, `dexaug synth`'s, or a bridge "
                         f"recording of either (e.g. {_REPLAYABLE_SAMPLE})")
    mode = session_object_mode(recording.metadata, args.file, args.object_mode)
    session = open_session(free_tcp_port(), tuple(args.connect))
    try:
        _wait_for_bridge(session, args.rig, args.wait_bridge_s, args.connect)
        obj = args.object or recording.metadata.get("object")
        if obj:
            _choose_object(session, args.rig, str(obj), console)
        if tell_bridge(session, args.rig, mode) is not None:
            console.print(f"bridge object mode: {mode}")
        sent = replay_session(args.file, session, args.rig, rate=args.rate)
    finally:
        session.close()
    console.print(f"replayed {sent} hand-tracking messages from {args.file}")
    return 0


log = logging.getLogger(__name__)

#: how long replay waits for the bridge to build the session's object's scene (seconds)
CHOOSE_OBJECT_S = 120.0


def _choose_object(session: zenoh.Session, rig: str, obj: str, console: Console) -> None:
    """Put ``obj`` on the bridge's table (``choose_object``, unless its ``status`` says it is
    there already); UsageError (exit status 2) when the bridge refuses it, since hand frames
    replayed onto another object record grasps of nothing. A subscriber that answers no
    control (no bridge: a recorder, a viewer) is told nothing, and that is logged."""
    from teleop.bridge.session_mode import ask_bridge

    status = ask_bridge(session, rig, "status", {})
    if status is None:
        log.warning("nothing on rig %r answers bridge controls: the object is left as it is", rig)
        return
    if status.get("object") != obj:
        reply = ask_bridge(session, rig, "choose_object", {"object": obj},
                           wait_s=CHOOSE_OBJECT_S, reply_s=CHOOSE_OBJECT_S)
        if reply is None or not reply.get("ok"):
            why = "no reply" if reply is None else reply.get("error")
            raise UsageError(f"the bridge of rig {rig!r} did not take the session's object "
                             f"{obj!r}: {why} (--object picks another)")
    console.print(f"bridge object: {obj}")


def _wait_for_bridge(session: zenoh.Session, rig: str, wait_s: float, ports: Sequence[int]) -> None:
    """Wait until something subscribes to the rig's hands (zenoh's matching status of a
    publisher on that key, an event, not a poll of the network), at most ``wait_s`` seconds;
    NetworkError (exit status 2) naming the key, the ports and what to do when nothing did."""
    import threading

    from teleop import keys as zkeys

    key = zkeys.RigKeys(rig).hands
    matched = threading.Event()
    pub = session.declare_publisher(key)
    listener = pub.declare_matching_listener(
        lambda status: matched.set() if status.matching else None)
    try:
        # zenoh's stub types matching_status as bool; it is a MatchingStatus (.matching)
        if not (pub.matching_status.matching or matched.wait(wait_s)):  # type: ignore[attr-defined]
            where = ", ".join(f"tcp/127.0.0.1:{p}" for p in ports)
            raise NetworkError(f"no bridge subscribed to {key} within {wait_s:g} s (connecting "
                               f"to {where}): start `dexaug bridge` first (same --rig), or "
                               f"raise --wait-bridge-s; nothing was published")
    finally:
        listener.undeclare()
        pub.undeclare()
