"""Live-capture subcommands beside the bridge: the ingest for native streamer apps."""

from __future__ import annotations

import argparse
import contextlib
import threading

from rich.console import Console
from rich.text import Text

from dexaug.commands.argtypes import free_port, port, positive, rig_name
from dexaug.commands.registry import command


def _stream_ingest_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--udp", type=free_port, help="UDP port to listen on (the app's default is 9000)")
    p.add_argument("--tcp", type=free_port, help="TCP port to listen on (the app's default is 8000)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1: this machine, e.g. through "
                        "adb reverse; 0.0.0.0 for an app on the LAN, which anyone there can "
                        "then send hand frames to)")
    p.add_argument("--rig", type=rig_name, default="local",
                   help="zenoh key prefix dexaug/<rig>/… (letters, digits, _ and -)")
    p.add_argument("--connect", type=port, nargs="+", default=[7447],
                   help="bridge port(s) to connect to on 127.0.0.1")
    p.add_argument("--duration", type=positive, help="stop after this many seconds")


@command("stream-ingest", _stream_ingest_args)
def stream_ingest(args: argparse.Namespace, console: Console) -> int:
    """Receive a native hand-tracking streamer app (UDP/TCP text lines) and publish its hands.

    For Quest apps such as Hand Tracking Streamer ("Right wrist:, x, y, z, qx, qy, qz, qw" and
    "Right landmarks:, 63 floats" lines): converted to dexaug hand frames and published on
    dexaug/<rig>/hands for a running `dexaug bridge`. Over USB: `adb reverse tcp:8000 tcp:8000`
    and --tcp 8000. Ctrl-C stops it.
    """
    from teleop.input.stream_ingest import StreamIngest
    from teleop.keys import free_tcp_port

    udp = 9000 if args.udp is None and args.tcp is None else args.udp  # the app's default
    with StreamIngest(args.rig, udp_port=udp, tcp_port=args.tcp, host=args.host,
                      listen_port=free_tcp_port(), connect_ports=tuple(args.connect)) as ingest:
        console.print(Text(f"listening for streamer apps on {args.host} udp {ingest.udp_port}, "
                           f"tcp {ingest.tcp_port}; publishing on {ingest.keys.hands}"))
        with contextlib.suppress(KeyboardInterrupt):
            threading.Event().wait(args.duration)
        console.print(f"received {ingest.counts['frames']} hand frames, "
                      f"{ingest.counts['bad_lines']} bad lines")
    return 0
