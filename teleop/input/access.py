"""Who may use the headset page: the listen address, the per-start token, Host and Origin checks.

Why: the page's WebSocket publishes hand frames and runs control commands (start a recording,
mark a grasp) on the bridge, so anyone who can open it drives the rig. The rules:

- **Loopback by default.** The page listens on ``127.0.0.1`` unless a host is given
  (``adb reverse`` brings a USB headset there).
- **A token per start.** :func:`access_policy` makes a random ``secrets.token_urlsafe`` token
  every start (or takes the one given); the printed URL carries it (``?token=…``), the page
  (``app.js``) sends it on the WebSocket handshake and with every control message. It is
  *required* when the server listens on a non-loopback address or a token was given explicitly;
  on loopback without one a tokenless client is admitted but holds the rig only until a client
  with the token (the real headset, opened from the printed URL) takes it over.
- **Host and Origin.** Every request's ``Host`` must name this machine (``localhost``, its host
  name, its addresses, or ``extra_hosts``) — a DNS-rebinding page's Host names the attacker's
  domain — and a request with an ``Origin`` (a browser's WebSocket always has one) must come
  from the page itself (``<scheme>://<Host>``), so a foreign web page cannot open the socket.

The rules themselves (loopback, token required, constant-time compare, Host, Origin) are the
project's one network-access policy, :mod:`teleop.net_access`, which the dashboard applies too;
this module adds the page's flags, token paths and refusals.

:func:`access_middleware` applies the Host/Origin checks to every request and the token to the
page and ``/ws``; refusals are one-line ``text/plain`` answers (421 wrong Host, 403 foreign
Origin, 401 missing or wrong token) and a log line.
"""

from __future__ import annotations

import argparse
import logging
import socket
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass

from aiohttp import web
from aiohttp.typedefs import Middleware

from teleop.input.background_server import WebIngestError
from teleop.input.tls import local_addresses
from teleop.net_access import (
    LOOPBACK_NAMES,
    WILDCARDS,
    host_ok,
    is_loopback,
    new_token,
    origin_ok,
    token_ok,
    token_required,
)

__all__ = ["AccessPolicy", "access_middleware", "access_policy", "add_listen_args", "clean_text",
           "is_loopback"]

logger = logging.getLogger(__name__)

LOOPBACK_HOST = "127.0.0.1"
#: paths that need the token when it is required (the page and its WebSocket; the static
#: scripts are public code and hold no secret)
TOKEN_PATHS = ("/", "/ws")

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


def clean_text(text: object, max_chars: int = 200) -> str:
    """``text`` safe for one log line or counter name: control characters (newlines included)
    replaced by ``?``, at most ``max_chars`` characters (``…`` marks a cut). A client's text
    must not forge log lines or grow the counters without bound."""
    s = "".join(ch if ch.isprintable() else "?" for ch in str(text))
    return s if len(s) <= max_chars else s[:max_chars - 1] + "…"


@dataclass(frozen=True)
class AccessPolicy:
    """What :func:`access_middleware` enforces. ``token``: this start's token (always set; sent in
    the page URL); ``required``: clients without it are refused (else admitted, but displaceable
    by a token holder); ``hosts``: lower-case host names/addresses a ``Host`` header may name."""

    token: str
    required: bool
    hosts: frozenset[str]

    def token_ok(self, presented: object) -> bool:
        """Whether ``presented`` is this start's token (constant-time comparison)."""
        return token_ok(presented, self.token)

    def host_error(self, host_header: str | None) -> str | None:
        """Why a ``Host`` header is refused (None when it names this machine)."""
        if host_ok(host_header, self.hosts):
            return None
        return (f"Host {clean_text(host_header, 80)!r} does not name this machine (expected one "
                f"of {', '.join(sorted(self.hosts))})")

    def origin_error(self, origin: str | None, scheme: str, host_header: str | None) -> str | None:
        """Why an ``Origin`` header is refused (None when absent or the page's own origin)."""
        if origin_ok(origin, scheme, host_header):
            return None
        own = f"{scheme}://{host_header or ''}".lower()
        return f"Origin {clean_text(origin, 80)!r} is not this page's ({own})"


def access_policy(host: str, token: str | None = None,
                  extra_hosts: Iterable[str] = ()) -> AccessPolicy:
    """The policy for a server on ``host``: ``token`` if given (then required), else a fresh
    random one, required unless ``host`` is loopback. The allowed Host names are localhost,
    this machine's names and addresses, ``host`` itself (unless a wildcard) and ``extra_hosts``
    (e.g. a DNS name the headset uses)."""
    if token is not None and (len(token) < 8 or not token.isprintable() or " " in token):
        raise WebIngestError(f"token: expected at least 8 printable characters without spaces, "
                             f"got {len(token)} characters")
    names = {*LOOPBACK_NAMES, socket.gethostname(), *local_addresses(), *extra_hosts}
    if host not in WILDCARDS:
        names.add(host)
    return AccessPolicy(token=token or new_token(), required=token_required(host, token),
                        hosts=frozenset(n.lower().strip("[]") for n in names if n))


def access_middleware(policy: AccessPolicy) -> Middleware:
    """An aiohttp middleware refusing requests with a wrong Host (421), a foreign Origin (403)
    or, on :data:`TOKEN_PATHS` when the token is required, no or a wrong ``token`` (401)."""

    @web.middleware
    async def check(request: web.Request, handler: Handler) -> web.StreamResponse:
        host = request.headers.get("Host")
        why = policy.host_error(host)
        status = 421
        if why is None:
            why, status = policy.origin_error(request.headers.get("Origin"), request.scheme,
                                              host), 403
        if why is None and policy.required and request.path in TOKEN_PATHS and \
                not policy.token_ok(request.query.get("token")):
            why, status = ("no or a wrong token: open the page from the URL the bridge printed "
                           "(…/?token=…)"), 401
        if why is not None:
            logger.warning("refused %s %s from %s: %s", request.method,
                           clean_text(request.path, 80), request.remote, why)
            return web.Response(status=status, text=f"refused: {why}\n")
        return await handler(request)

    return check


def add_listen_args(p: argparse.ArgumentParser, *, prefix: str = "",
                    what: str = "the headset page") -> None:
    """``--<prefix>host`` (default 127.0.0.1) and ``--<prefix>token`` for a command serving
    ``what`` (e.g. ``prefix="web-"``: ``--web-host``, ``--web-token``, read back as
    ``args.web_host``, ``args.web_token``): the same flags and help wherever a server may leave
    loopback; pass them to :class:`teleop.input.web_ingest.WebIngestConfig` ``host``/``token``."""
    p.add_argument(f"--{prefix}host", default=LOOPBACK_HOST,
                   help=f"address {what} listens on (default {LOOPBACK_HOST}: this machine only; "
                        "0.0.0.0 for a headset on the LAN, which then needs the printed token)")
    p.add_argument(f"--{prefix}token", default=None,
                   help="access token to require instead of a random one per start "
                        "(at least 8 characters)")
