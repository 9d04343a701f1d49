"""Who may talk to the dashboard: the Host, token and cross-site checks on every request.

The dashboard starts augmentations and lists the sessions on disk, so three attacks matter:

- **Cross-site requests (CSRF).** Any web page the user visits can POST to a local port; a
  ``text/plain`` body needs no CORS preflight. A state-changing request (anything but GET, HEAD,
  OPTIONS) therefore needs a JSON body (``Content-Type: application/json``) *and* a custom
  header (``X-Dexaug: 1``, or the token header): a browser sends a custom header cross-origin only
  after a preflight, which this server never grants (it sends no ``Access-Control-*`` header).
  Its ``Origin``, when there is one, must be the page's own.
- **DNS rebinding.** A foreign name pointed at 127.0.0.1 makes the browser treat the server as
  that name's origin and read its answers. Every request's ``Host`` must be a name the server is
  bound for (localhost, 127.0.0.1, [::1], the bound address or, on a wildcard bind, this machine's
  name or the address the connection arrived on); others get 421.
- **Other machines.** Listening beyond loopback, every request needs the per-start token: the
  ``X-Dexaug-Token`` header (the page's fetches), the ``token`` query parameter (the printed URL),
  or the cookie the server sets when the query carried it (images, scripts and report links,
  which cannot carry headers). The cookie is ``HttpOnly`` and ``SameSite=Strict``, so another
  site's request never carries it.

Refusals are JSON ``{"error": ...}`` with 421 or 403, and one warning in the log.

The loopback, token, Host and Origin rules are the project's one network-access policy,
:mod:`teleop.net_access` (the headset page applies it too); this class words the refusals
and adds the cookie and the CSRF checks.
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Awaitable, Callable

from aiohttp import web

from teleop.net_access import (
    LOOPBACK_NAMES,
    WILDCARDS,
    host_name,
    host_ok,
    is_loopback,
    new_token,
    origin_ok,
    token_ok,
    token_required,
)

__all__ = ["Guard", "is_loopback"]

log = logging.getLogger(__name__)

#: Methods that change nothing; every other one is checked for cross-site use.
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
#: The custom header the dashboard's own page sends with every request.
CSRF_HEADER, CSRF_VALUE = "X-Dexaug", "1"
TOKEN_HEADER, TOKEN_QUERY = "X-Dexaug-Token", "token"

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]


class Guard:
    """The checks of the module docstring for a server bound to ``bind_host``. A token is made
    (``token``) when that address is not loopback; ``port`` is set once the server listens (it
    names the cookie, since cookies do not tell ports apart)."""

    def __init__(self, bind_host: str) -> None:
        host = bind_host.strip("[]").lower()
        names = set(LOOPBACK_NAMES) | {host}
        if host in WILDCARDS:
            names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
        self.names = frozenset(names - {""})
        self.token: str | None = new_token() if token_required(host) else None
        self.port: int | None = None

    @property
    def cookie(self) -> str:
        return f"dexaug_token_{self.port}"

    @web.middleware
    async def middleware(self, request: web.Request, handler: Handler) -> web.StreamResponse:
        """Refuse a request failing a check; set the token cookie when the query carried it."""
        host_error = self._host_error(request)
        if host_error:
            return self._refuse(request, 421, host_error)
        via_query = False
        if self.token is not None:
            via_query = self._matches(request.query.get(TOKEN_QUERY))
            if not (via_query or self._matches(request.headers.get(TOKEN_HEADER))
                    or self._matches(request.cookies.get(self.cookie))):
                return self._refuse(request, 403, "this dashboard listens beyond this machine: "
                                    "open the URL it printed, with its token")
        if request.method not in SAFE_METHODS:
            csrf_error = self._csrf_error(request)
            if csrf_error:
                return self._refuse(request, 403, csrf_error)
        response = await handler(request)
        if via_query and self.token is not None:
            response.set_cookie(self.cookie, self.token, path="/", httponly=True,
                                samesite="Strict")
        return response

    # ---------------------------------------------------------------------------- the checks

    def _host_error(self, request: web.Request) -> str | None:
        header = request.headers.get("Host", "")
        name = host_name(header)
        if not name:
            return "a Host header naming this dashboard is required"
        sock = request.transport.get_extra_info("sockname") if request.transport else None
        if host_ok(header, self.names, str(sock[0]) if sock else None):
            return None
        return f"Host {name!r} is not a name this dashboard is served under"

    def _csrf_error(self, request: web.Request) -> str | None:
        origin = request.headers.get("Origin")
        if not origin_ok(origin, request.scheme, request.headers.get("Host")):
            return f"cross-site request refused (Origin {origin!r})"
        if request.content_type != "application/json":
            return f"expected a JSON body (Content-Type application/json), got {request.content_type!r}"
        if request.headers.get(CSRF_HEADER) != CSRF_VALUE and TOKEN_HEADER not in request.headers:
            return f"missing the {CSRF_HEADER}: {CSRF_VALUE} header the dashboard page sends"
        return None

    def _matches(self, given: str | None) -> bool:
        return token_ok(given, self.token)

    @staticmethod
    def _refuse(request: web.Request, status: int, error: str) -> web.Response:
        log.warning("refused %s %r from %s: %s", request.method, request.path, request.remote,
                    error)
        return web.json_response({"error": error}, status=status)
