"""Who may reach a server of this project: the one network-access policy every server applies.

The dashboard (:mod:`dexaug.dashboard.guard`), the headset page and its WebSocket
(:mod:`teleop.input.access`), the streamer ingest (:mod:`teleop.input.stream_ingest`) and the
Foxglove live server (:mod:`teleop.bridge.foxglove_live`) decide with these functions only;
each server words and shapes its own refusals (JSON, text, ValueError).

- **Loopback** (:func:`is_loopback`): ``127.0.0.0/8``, ``::1`` and ``localhost`` reach this
  machine only; wildcards (``0.0.0.0``, ``::``, ``""``) and every other address or name do not.
- **A token beyond loopback** (:func:`token_required`, :func:`new_token`): a server listening
  beyond loopback, or given a token explicitly, refuses clients without its per-start token;
  tokens are compared in constant time (:func:`token_ok`, ``hmac.compare_digest``).
- **Host** (:func:`host_ok`): a request's ``Host`` must name the server (one of its names, or
  the address the connection arrived on), so a DNS-rebinding page's foreign name is refused.
- **Origin** (:func:`origin_ok`): a request with an ``Origin`` must come from the page itself
  (``<scheme>://<Host>``), so a foreign web page cannot drive the server.

Here, not under ``teleop.input``: ``teleop.input`` reaches ``teleop.bridge`` (through
``teleop.synthetic``), so the Foxglove server could not import it without closing a cycle;
this module imports nothing of the project.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
from collections.abc import Collection

__all__ = ["LOOPBACK_NAMES", "WILDCARDS", "host_name", "host_ok", "is_loopback", "new_token",
           "origin_ok", "token_ok", "token_required"]

#: the names of this machine that only it reaches
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
#: listen addresses meaning "every interface"
WILDCARDS = frozenset({"", "0.0.0.0", "::"})


def is_loopback(host: str) -> bool:
    """True for an address only this machine reaches (``127.0.0.0/8``, ``::1``, ``localhost``);
    False for wildcards (``0.0.0.0``, ``::``, ``""``) and every other address or name (a name
    other than ``localhost`` may resolve to any interface)."""
    if host.strip().lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def token_required(host: str, given: str | None = None) -> bool:
    """Whether a server on ``host`` refuses clients without its token: beyond loopback, or
    whenever a token was ``given`` explicitly."""
    return given is not None or not is_loopback(host)


def new_token() -> str:
    """A fresh random per-start token."""
    return secrets.token_urlsafe(24)


def token_ok(presented: object, token: str | None) -> bool:
    """Whether ``presented`` is ``token`` (constant-time comparison; False when either is
    missing)."""
    return (isinstance(presented, str) and token is not None
            and hmac.compare_digest(presented.encode(), token.encode()))


def host_name(host_header: str | None) -> str:
    """The lower-case host part of a ``Host`` header (``[::1]:8443`` → ``::1``, ``a:1`` → ``a``;
    ``""`` when there is none)."""
    h = (host_header or "").strip().lower()
    if h.startswith("["):
        return h[1:h.find("]")] if "]" in h else h
    return h.rsplit(":", 1)[0] if h.count(":") == 1 else h


def _ip(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        addr = ipaddress.ip_address(text.strip("[]"))
    except ValueError:
        return None
    if isinstance(addr, ipaddress.IPv6Address) and addr.ipv4_mapped is not None:
        return addr.ipv4_mapped   # a dual-stack socket reports IPv4 clients as ::ffff:a.b.c.d
    return addr


def host_ok(host_header: str | None, names: Collection[str], arrived_on: str | None = None) -> bool:
    """Whether a ``Host`` header names this server: one of ``names`` (lower case, IPv6 without
    brackets), or the address ``arrived_on`` the connection came in on (not a rebound name)."""
    name = host_name(host_header)
    if not name:
        return False
    if name in names:
        return True
    ip = _ip(name)
    return ip is not None and arrived_on is not None and ip == _ip(arrived_on)


def origin_ok(origin: str | None, scheme: str, host_header: str | None) -> bool:
    """Whether an ``Origin`` header is absent or the page's own (``<scheme>://<Host>``)."""
    if origin is None:
        return True
    return origin.strip().lower() == f"{scheme}://{host_header or ''}".lower()
