"""Guards the guides claim (docs/quest-capture.md, "Security and faults") that no test pinned
before ``scripts/mutation_check.py`` looked for the test of each: everything listens on loopback
unless asked — the dashboard's default, the `ui`, `stream-ingest` and `bridge --web` command
lines, the zenoh peers.

Checked on the listening sockets themselves (``/proc/net/tcp``, ``/proc/net/tcp6``), not on a
config field, so a default that is right on paper but not on the wire fails too.
"""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from dexaug.pipeline.options import AugmentOptions
from teleop import keys

pytestmark = pytest.mark.skipif(not Path("/proc/net/tcp").is_file(),
                                reason="no /proc/net/tcp (Linux) to read listening sockets from")

_LISTEN = "0A"   # TCP state LISTEN in /proc/net/tcp


def _listening_on(port: int) -> set[str]:
    """The local addresses of the TCP sockets listening on ``port`` (every process's)."""
    found = set()
    for table, family in (("/proc/net/tcp", socket.AF_INET), ("/proc/net/tcp6", socket.AF_INET6)):
        try:
            rows = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for row in rows:
            local, state = row.split()[1], row.split()[3]
            addr_hex, port_hex = local.split(":")
            if state != _LISTEN or int(port_hex, 16) != port:
                continue
            raw = bytes.fromhex(addr_hex)
            # the kernel prints each 32-bit word in host (little-endian) order
            raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
            found.add(socket.inet_ntop(family, raw))
    return found


def _loopback_only(addresses: set[str]) -> bool:
    return bool(addresses) and all(a.startswith("127.") or a == "::1" for a in addresses)


def test_the_dashboard_listens_on_loopback_by_default(tmp_path: Path) -> None:
    from dexaug.dashboard.server import Dashboard, DashboardConfig

    (tmp_path / "sessions").mkdir()
    cfg = DashboardConfig(tmp_path / "sessions", tmp_path / "out",
                          AugmentOptions(n=5, workers=1, gallery=0), port=0)   # host: default
    with Dashboard(cfg, target=lambda payload, progress: {}) as dash:
        dash.start()
        where = _listening_on(dash.port)
        assert _loopback_only(where), where
        assert dash.token is None   # on loopback no token is needed (beyond it one is made)


@pytest.mark.parametrize(("argv", "dest"), [(["ui"], "host"), (["stream-ingest"], "host"),
                                            (["bridge"], "web_host")],
                         ids=["ui", "stream-ingest", "bridge"])
def test_the_servers_command_lines_default_to_loopback(argv: list[str], dest: str) -> None:
    from dexaug.cli import build_parser

    args = build_parser(only=argv[0]).parse_args(argv)
    assert getattr(args, dest) == "127.0.0.1"


def test_a_zenoh_peer_listens_on_loopback_only() -> None:
    port = keys.free_tcp_port()
    session = keys.open_session(port)
    try:
        where = _listening_on(port)
        assert _loopback_only(where), where
    finally:
        session.close()
