"""Network failures of the long-running commands as one clear line.

Why: the bridge loads its hand and scene (seconds) before zenoh opens its listener, so a taken
``--listen`` port would be reported only then, after the log of the loading, in zenoh's words
(a Rust source location included). :func:`require_free_port` finds a taken port first;
:func:`zenoh_message` cleans zenoh's own refusal for the rare case where another process takes
the port in between.
"""

from __future__ import annotations

import re
import socket

from sim.errors import NetworkError

__all__ = ["require_free_port", "zenoh_message"]

#: "… at /root/.cargo/git/checkouts/zenoh-…/io/zenoh-links/…/unicast.rs:338." in zenoh errors
_RUST_LOCATION = re.compile(r"\s+at\s+\S+\.rs:\d+\.?")


def require_free_port(option: str, port: int, host: str = "127.0.0.1") -> None:
    """Raise :class:`NetworkError` naming ``option`` when ``host``:``port`` cannot be bound
    now (another process listens there, or the address is not this machine's). The probe
    uses SO_REUSEADDR, as the real listeners do, so a port a previous run left in TIME_WAIT is
    not refused."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            raise NetworkError(f"{option} {port}: cannot listen on tcp/{host}:{port}: "
                               f"{exc.strerror or exc}") from None


def zenoh_message(exc: BaseException) -> str:
    """A zenoh error's text without the Rust source locations it carries."""
    return _RUST_LOCATION.sub("", str(exc)).strip()
