"""Live ingest from a headset browser: the WebXR page, served over HTTPS, and its WebSocket.

Why a web page and not an app: the Quest Browser speaks WebXR with hand tracking, so opening
``https://<this machine>:8443/`` on the headset is the whole installation. The page
(``teleop/input/web/``) sends both hands' 25 WebXR joint poses every XR frame over a WebSocket; this
module converts them once with :func:`teleop.input.web_protocol.parse_ws_frame` (XR → MuJoCo, PALM
synthesised) and publishes :func:`teleop.messages.encode` bytes on ``dexaug/<rig>/hands``, so the
bridge cannot tell a headset from a replay. The other way, it forwards the bridge's ``/view``
JPEGs, a throttled summary of ``/state`` (contacts, held), ``/events`` and a 1 Hz ``status``
(recording or not) to the page, and runs the page's control requests (start/stop recording,
mark grasp) as ``dexaug/<rig>/control/<cmd>`` queries.

Access (:mod:`teleop.input.access`): the page listens on 127.0.0.1 unless ``host`` says
otherwise; each start makes a random token that the page URL carries (``?token=…``) and the page
sends on the WebSocket handshake and with every control message. Off loopback (or with a
``token`` given) it is required; every request's Host must name this machine and a browser's
Origin must be the page's own. The page's control requests are untrusted: only
:data:`PAGE_COMMANDS` with the arguments of :data:`PAGE_ARGS` (a recording ``name``, never a
``path`` or ``overwrite``) are forwarded, and the bridge checks them again.

One headset at a time: the first WebSocket that says ``hello`` owns the rig; a second one gets a
``refused`` message (shown on its page) and is closed, and the bridge logs it — unless the
newcomer presents the token and the holder did not (a tokenless client admitted on loopback):
then the newcomer takes the rig over and the holder gets ``replaced``, so the real headset,
opened from the printed URL, can always take the rig back from a squatter. A reconnect with
the same ``client_id`` (the page keeps it in sessionStorage) replaces a half-dead old socket
instead of being refused (a tokenless one never replaces a token holder's). A lost socket is
noticed by aiohttp's heartbeat; the page shows "disconnected, reconnecting" and retries.

The hand-frame wire format (page → ingest) is :mod:`teleop.input.web_protocol`'s.

Latency: each frame's ``receive_time_s`` is this process's wall clock (``time.time()``) when the
WebSocket message arrived, so a subscriber on the same machine measures the ingest's added
latency as ``time.time() − receive_time_s`` (``benchmarks/bench_web_ingest.py``).

TLS: the page is served over HTTPS with :func:`teleop.input.tls.ensure_certificate`'s
self-signed certificate (or plain HTTP to ``localhost`` through ``adb reverse``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import ssl
import threading
import time
import urllib.parse
import uuid
from collections import Counter, deque
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, cast

import numpy as np
import zenoh
from aiohttp import WSMsgType, web

from teleop import keys as zkeys
from teleop.input.access import AccessPolicy, access_middleware, access_policy, clean_text, is_loopback
from teleop.input.background_server import BackgroundServer, WebIngestError
from teleop.input.tls import ensure_certificate, local_addresses
from teleop.input.web_protocol import parse_ws_frame
from teleop.messages import MessageError, encode

__all__ = ["PAGE_ARGS", "PAGE_COMMANDS", "WebIngest", "WebIngestConfig"]

logger = logging.getLogger(__name__)

#: Control commands the page may send (the rest of the control API stays on zenoh).
PAGE_COMMANDS = ("start_recording", "stop_recording", "mark_grasp", "reset_object",
                 "next_object_rest", "recalibrate_scale")
#: the arguments each page command may carry (anything else is refused, never forwarded): a
#: remote caller names a recording, it never chooses a path or overwrites a file
PAGE_ARGS: dict[str, tuple[str, ...]] = {"start_recording": ("name",)}
#: the page's notice kinds (``app.js``) counted by name; any other is counted as ``other``
NOTICE_KINDS = ("session_failed", "no_hand_tracking", "no_hands_tracked", "no_webxr",
                "no_immersive_vr")
_LOG_EVERY = 100


@dataclass
class WebIngestConfig:
    """Where and how the page is served.

    ``host``/``port``: the HTTPS (or HTTP) listen address (port 0 picks a free one; the
    default host is loopback, ``0.0.0.0`` serves the LAN). ``token``: the access token to
    require (None: a random one per start, required only off loopback; see
    :mod:`teleop.input.access`). ``extra_hosts``: more names a request's Host header may use
    (a DNS name of this machine the headset opens). ``tls``:
    serve HTTPS with ``cert_dir``'s certificate (:func:`ensure_certificate`). ``dev_static``:
    extra static folders served under ``/dev/<name>/`` — development and tests only (the IWER
    bundle and a capture for the emulated headset); empty in normal use. ``state_rate_hz``: how
    often a ``/state`` summary goes to the page. ``status_period_s``: how often the bridge's
    status (recording or not) is polled for the page. ``heartbeat_s``: WebSocket ping period;
    a headset silent for about twice that is considered gone.
    """

    host: str = "127.0.0.1"
    port: int = 8443
    token: str | None = None
    extra_hosts: tuple[str, ...] = ()
    tls: bool = True
    cert_dir: Path | None = None
    dev_static: dict[str, Path] = field(default_factory=dict)
    state_rate_hz: float = 15.0
    status_period_s: float = 1.0
    heartbeat_s: float = 5.0
    hello_timeout_s: float = 5.0


class _Client:
    """The connected headset: its socket and what is waiting to be sent to it. Only the newest
    view JPEG is kept (a slow link skips frames instead of queueing seconds of video)."""

    def __init__(self, ws: web.WebSocketResponse, client_id: str, peer: str,
                 has_token: bool) -> None:
        self.ws, self.client_id, self.peer, self.has_token = ws, client_id, peer, has_token
        self.view: bytes | None = None
        self.texts: deque[str] = deque(maxlen=64)
        self.wake = asyncio.Event()


class WebIngest:
    """The page server + WebSocket ↔ zenoh; see the module docstring.

    ``session``: a zenoh session to use (the caller closes it); otherwise a loopback peer is
    opened listening on ``listen_port`` and connecting to ``connect_ports`` and closed in
    :meth:`close`. :meth:`start` serves in a background thread and returns the page URL.
    """

    def __init__(self, rig: str = "local", config: WebIngestConfig | None = None, *,
                 session: zenoh.Session | None = None, listen_port: int | None = None,
                 connect_ports: tuple[int, ...] = ()) -> None:
        self.config = config or WebIngestConfig()
        self.keys = zkeys.RigKeys(rig)
        self.counts: Counter[str] = Counter()
        #: seconds from the WebSocket message's arrival to ``put`` returning, per frame
        self.ingest_latency_s: deque[float] = deque(maxlen=100_000)
        self._lock = threading.Lock()
        self._client: _Client | None = None
        self._server: BackgroundServer | None = None
        self._stopped = threading.Event()
        self._next_state_s = 0.0
        self.port: int | None = None
        self.url: str | None = None
        self._scheme = "https" if self.config.tls else "http"
        #: this start's token and checks (module docstring)
        self.access: AccessPolicy = access_policy(self.config.host, self.config.token,
                                                  self.config.extra_hosts)
        self._own_session = session is None
        self.session = session or zkeys.open_session(listen_port, list(connect_ports))
        # reliable and blocking as replay: a recording must not lose frames to a busy moment
        # (on loopback "blocking" is microseconds); express: no batching delay
        self._pub = self.session.declare_publisher(
            self.keys.hands, congestion_control=zenoh.CongestionControl.BLOCK,
            reliability=zenoh.Reliability.RELIABLE, express=True)
        self._subs = [self.session.declare_subscriber(self.keys.view, self._on_view),
                      self.session.declare_subscriber(self.keys.state, self._on_state),
                      self.session.declare_subscriber(self.keys.events, self._on_event)]

    # ------------------------------------------------------------------------------ lifecycle

    def _app(self) -> web.Application:
        app = web.Application(middlewares=[access_middleware(self.access)])
        web_dir = resources.files("teleop.input") / "web"
        page = Path(str(web_dir))
        if not (page / "index.html").is_file():
            raise WebIngestError(f"{page}: the page assets (index.html, app.js) are missing; "
                                 "reinstall dexaug")
        app.router.add_get("/ws", self._ws_handler)
        async def index(_request: web.Request) -> web.FileResponse:
            return web.FileResponse(page / "index.html")

        async def no_icon(_request: web.Request) -> web.Response:
            return web.Response(status=204)

        app.router.add_get("/", index)
        app.router.add_get("/favicon.ico", no_icon)
        for name, path in self.config.dev_static.items():
            if not Path(path).is_dir():
                raise WebIngestError(f"dev_static[{name!r}]: {path} is not a folder")
            app.router.add_static(f"/dev/{name}/", Path(path), follow_symlinks=True)
        app.router.add_static("/static/", page)
        return app

    def _ssl_context(self) -> ssl.SSLContext | None:
        if not self.config.tls:
            return None
        cert, key = ensure_certificate(self.config.cert_dir)
        ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
        try:
            ctx.load_cert_chain(cert, key)
        except (OSError, ssl.SSLError) as exc:
            raise WebIngestError(f"{cert}: cannot load the certificate/key: {exc}") from None
        return ctx

    def start(self, timeout_s: float = 10.0) -> str:
        """Serve in a background thread; returns the page URL with this start's token
        (``https://localhost:<port>/?token=…``; :meth:`page_urls` lists the LAN ones)."""
        ssl_ctx = self._ssl_context()
        app = self._app()
        self._server = BackgroundServer(app, self.config.host, self.config.port, ssl_ctx,
                                        task=self._status_poller)
        self._server.start(timeout_s)
        self.port = self._server.port
        self._scheme = "https" if ssl_ctx is not None else "http"
        self.url = self.page_url()
        if ssl_ctx is None and not is_loopback(self.config.host):
            logger.warning("the headset page is plain HTTP on %s: its token crosses the network "
                           "unencrypted (and a headset grants WebXR only to HTTPS or localhost)",
                           self.config.host)
        logger.info("headset page on %s (WebSocket /ws) for rig %s%s", " or ".join(self.page_urls()),
                    self.keys.rig, "; the token is required" if self.access.required else "")
        return self.url

    def page_url(self, host: str = "localhost", **params: str) -> str:
        """The page's URL on ``host`` with this start's token and ``params`` (e.g.
        ``emulate="quest3"``) in the query; only once :meth:`start` returned."""
        if self.port is None:
            raise WebIngestError("page_url: the page is not served yet (call start() first)")
        query = urllib.parse.urlencode({"token": self.access.token, **params})
        netloc = f"[{host}]" if ":" in host else host
        return f"{self._scheme}://{netloc}:{self.port}/?{query}"

    def page_urls(self) -> list[str]:
        """Every URL a headset may open: localhost, and off loopback this machine's LAN
        addresses (or the one address listened on), each with the token."""
        host = self.config.host
        if is_loopback(host):
            hosts = ["localhost"]
        elif host in ("", "0.0.0.0", "::"):
            hosts = ["localhost", *(a for a in local_addresses() if not is_loopback(a))]
        else:
            hosts = [host]
        return [self.page_url(h) for h in hosts]

    def close(self) -> None:
        """Stop serving (closing the headset's socket), undeclare, close an owned session."""
        self._stopped.set()
        if self._server is not None:
            async def shutdown() -> None:
                c = self._client
                if c is not None:
                    await c.ws.close(code=1001, message=b"bridge shutting down")
            self._server.stop(shutdown)
        for ent in cast("list[zenoh.Subscriber | zenoh.Publisher]", [*self._subs, self._pub]):
            with contextlib.suppress(Exception):
                ent.undeclare()
        if self._own_session:
            self.session.close()

    def __enter__(self) -> WebIngest:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def stats(self) -> dict[str, Any]:
        """Counters and the ingest latency (median/p99, ms) so far."""
        with self._lock:
            counts = dict(self.counts)
            lat = np.array(self.ingest_latency_s) * 1e3
        out: dict[str, Any] = {"counts": counts, "connected": self._client is not None}
        if lat.size:
            out["ingest_latency_ms"] = {"median": float(np.median(lat)),
                                        "p99": float(np.percentile(lat, 99))}
        return out

    # ------------------------------------------------------------------------- zenoh → page

    def _push(self, text: str | None = None, view: bytes | None = None) -> None:
        """Queue a message for the headset (from any thread); dropped when none is connected."""
        loop = self._server.loop if self._server is not None else None
        c = self._client
        if loop is None or c is None:
            return

        def put() -> None:
            if text is not None:
                c.texts.append(text)
            if view is not None:
                c.view = view
            c.wake.set()
        loop.call_soon_threadsafe(put)

    def _on_view(self, sample: zenoh.Sample) -> None:
        with self._lock:
            self.counts["views_in"] += 1
        self._push(view=sample.payload.to_bytes())

    def _on_state(self, sample: zenoh.Sample) -> None:
        now = time.perf_counter()
        if self._client is None or now < self._next_state_s:
            return
        self._next_state_s = now + 1.0 / self.config.state_rate_hz
        try:
            st = json.loads(sample.payload.to_bytes())
            contacts = st.get("contacts") or []
            summary = {"type": "state", "seq": st.get("seq"), "held": st.get("held"),
                       "object": st.get("object"),
                       "contact_fingers": sorted({c.get("finger") for c in contacts
                                                  if c.get("finger")}),
                       "n_contacts": len(contacts),
                       "grasp_stable": bool(st.get("grasp_stable")),
                       "grasp_held_s": st.get("grasp_held_s"), "assist": st.get("assist")}
        except (ValueError, AttributeError, TypeError) as exc:
            logger.warning("%s: unreadable state message: %s", self.keys.state, exc)
            return
        self._push(text=json.dumps(summary))

    def _on_event(self, sample: zenoh.Sample) -> None:
        try:
            event = json.loads(sample.payload.to_bytes())
        except ValueError:
            return
        self._push(text=json.dumps({"type": "event", "event": event}))

    async def _query(self, command: str, args: dict[str, Any] | None = None,
                     timeout_s: float = 5.0) -> dict[str, Any]:
        """A control query, off the event loop (zenoh's get blocks)."""
        key = self.keys.control_cmd(command)
        try:
            return await asyncio.to_thread(zkeys.query_json, self.session, key, args or {},
                                           timeout_s=timeout_s)
        except RuntimeError as exc:
            return {"ok": False, "error": f"no bridge answered ({exc})"}

    async def _status_poller(self) -> None:
        """Tell the page every ``status_period_s`` whether the bridge runs and records."""
        while not self._stopped.is_set():
            await asyncio.sleep(self.config.status_period_s)
            if self._client is None:
                continue
            st = await self._query("status", timeout_s=min(2.0, self.config.status_period_s * 2))
            msg = {"type": "status", "bridge": bool(st.get("ok")),
                   "recording": st.get("recording"), "object": st.get("object"),
                   "view": st.get("view"), "error": st.get("error")}
            self._push(text=json.dumps(msg))

    # ---------------------------------------------------------------------------- WebSocket

    async def _sender(self, c: _Client) -> None:
        while not c.ws.closed:
            await c.wake.wait()
            c.wake.clear()
            while c.texts:
                await c.ws.send_str(c.texts.popleft())
            if c.view is not None:
                jpeg, c.view = c.view, None
                await c.ws.send_bytes(jpeg)
                with self._lock:
                    self.counts["views_out"] += 1

    async def _hello(self, ws: web.WebSocketResponse, peer: str) -> str | None:
        """Wait for the page's ``hello``; its ``client_id`` (or None if it never says hello)."""
        try:
            msg = await ws.receive(timeout=self.config.hello_timeout_s)
        except TimeoutError:
            msg = None
        if msg is None or msg.type != WSMsgType.TEXT:
            logger.warning("web client %s sent no hello within %.0f s; closing", peer,
                           self.config.hello_timeout_s)
            return None
        try:
            hello = json.loads(msg.data)
            if hello.get("type") != "hello":
                raise ValueError(f"expected a hello, got type {hello.get('type')!r}")
        except (ValueError, AttributeError) as exc:
            logger.warning("web client %s: bad hello (%s); closing", peer, exc)
            return None
        return clean_text(hello.get("client_id") or uuid.uuid4(), 64)

    async def _ws_handler(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(heartbeat=self.config.heartbeat_s, max_msg_size=1 << 20)
        await ws.prepare(request)
        peer = str(request.remote)
        client_id = await self._hello(ws, peer)
        if client_id is None:
            await ws.close(code=4400, message=b"no hello")
            return ws
        has_token = self.access.token_ok(request.query.get("token"))
        old = self._client
        if old is not None:
            if has_token and not old.has_token:
                await self._take_over(old, peer)
            elif old.client_id == client_id and (has_token or not old.has_token):
                logger.info("headset %s reconnected; closing its previous socket", peer)
                await old.ws.close(code=4000, message=b"replaced by a new connection")
            else:
                await self._refuse(ws, old, peer)
                return ws
        c = _Client(ws, client_id, peer, has_token)
        self._client = c
        with self._lock:
            self.counts["connections"] += 1
        logger.info("headset connected from %s (client %s)", peer, client_id[:8])
        await ws.send_str(json.dumps({"type": "welcome", "rig": self.keys.rig,
                                      "commands": list(PAGE_COMMANDS)}))
        sender = asyncio.create_task(self._sender(c))
        try:
            async for msg in ws:
                if msg.type == WSMsgType.BINARY:
                    self._on_frame(msg.data)
                elif msg.type == WSMsgType.TEXT:
                    await self._on_text(c, msg.data)
                elif msg.type == WSMsgType.ERROR:
                    logger.warning("headset %s: WebSocket error %s", peer, ws.exception())
        finally:
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, ConnectionError):
                await sender
            if self._client is c:
                self._client = None
            logger.info("headset %s disconnected (close code %s)", peer, ws.close_code)
        return ws

    async def _refuse(self, ws: web.WebSocketResponse, old: _Client, peer: str) -> None:
        """Tell a second headset the rig is taken, and close it."""
        with self._lock:
            self.counts["refused"] += 1
        reason = (f"another headset ({old.peer}) is already connected to rig "
                  f"{self.keys.rig!r}; only one at a time")
        logger.warning("refused a second headset from %s: %s", peer, reason)
        await ws.send_str(json.dumps({"type": "refused", "reason": reason}))
        await ws.close(code=4409, message=b"another headset is connected")

    async def _take_over(self, old: _Client, peer: str) -> None:
        """A client with the token displaces a tokenless holder (module docstring)."""
        with self._lock:
            self.counts["taken_over"] += 1
        reason = (f"a headset with the access token ({peer}) took rig {self.keys.rig!r} over; "
                  "open the URL the bridge printed to use it")
        logger.warning("headset %s (with the token) took the rig over from %s (without it)",
                       peer, old.peer)
        with contextlib.suppress(ConnectionError, RuntimeError):
            await old.ws.send_str(json.dumps({"type": "replaced", "reason": reason}))
        await old.ws.close(code=4001, message=b"taken over by a headset with the token")

    def _on_frame(self, data: bytes) -> None:
        t0 = time.perf_counter()
        t_rx = time.time()
        try:
            payload = encode(parse_ws_frame(data, t_rx))
        except MessageError as exc:
            with self._lock:
                self.counts["bad_frames"] += 1
                n = self.counts["bad_frames"]
            if n <= 3 or n % _LOG_EVERY == 0:
                logger.warning("skipped bad web hand frame #%d: %s", n, exc)
            return
        self._pub.put(payload)
        dt_s = time.perf_counter() - t0
        with self._lock:
            self.counts["frames"] += 1
            self.ingest_latency_s.append(dt_s)

    async def _on_text(self, c: _Client, text: str) -> None:
        try:
            msg = json.loads(text)
            kind = msg.get("type")
        except (ValueError, AttributeError):
            logger.warning("headset %s: unreadable text message %r", c.peer, text[:80])
            return
        if kind == "control":
            command = clean_text(msg.get("command"), 40)
            why = self._control_error(command, msg)
            if why is not None:
                result = {"ok": False, "error": why}
                logger.warning("headset %s: refused control request: %s", c.peer, why)
            else:
                result = await self._query(command, msg.get("args") or {})
                logger.info("headset %s: %s → %s", c.peer, command,
                            "ok" if result.get("ok") else clean_text(result.get("error")))
            await c.ws.send_str(json.dumps({"type": "control_reply", "command": command,
                                            "id": msg.get("id"), "result": result}))
        elif kind == "notice":
            what = msg.get("what")
            logger.warning("headset %s: %s", c.peer, clean_text(msg.get("message"), 300))
            with self._lock:
                self.counts[f"notice_{what if what in NOTICE_KINDS else 'other'}"] += 1
        elif kind == "stats":
            with self._lock:
                self.counts["page_stats"] += 1
        else:
            logger.warning("headset %s: unknown message type %r", c.peer, clean_text(kind, 40))

    def _control_error(self, command: str, msg: dict[str, Any]) -> str | None:
        """Why the page's control request is not forwarded (None: forward it). Untrusted: the
        token when required, a page command, only its :data:`PAGE_ARGS` (string values)."""
        if self.access.required and not self.access.token_ok(msg.get("token")):
            return f"{command}: no or a wrong access token"
        if command not in PAGE_COMMANDS:
            return f"unknown command {command!r}; one of {list(PAGE_COMMANDS)}"
        args = msg.get("args") or {}
        if not isinstance(args, dict):
            return f"{command}: args must be a JSON object"
        allowed = PAGE_ARGS.get(command, ())
        extra = sorted(clean_text(k, 40) for k in args if k not in allowed)
        if extra:
            return f"{command}: argument(s) {extra} not accepted from the page (allowed: {list(allowed)})"
        if not all(isinstance(v, str) for v in args.values()):
            return f"{command}: argument values must be strings"
        return None
