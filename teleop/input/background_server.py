"""An aiohttp application served from a daemon thread with its own asyncio event loop.

The web ingest lives inside a synchronous process (the bridge, a CLI command, a test), so its
page server cannot own the main thread: :class:`BackgroundServer` starts the loop in a thread,
reports a failure to bind (port taken, bad address) to :meth:`~BackgroundServer.start`'s
caller as a :class:`WebIngestError`, runs one background task next to the server, and stops
cleanly from any thread. Units: seconds.
"""

from __future__ import annotations

import asyncio
import contextlib
import ssl
import threading
from collections.abc import Callable, Coroutine
from typing import Any

from aiohttp import web

from sim.errors import DexaugError

__all__ = ["BackgroundServer", "WebIngestError"]

Task = Callable[[], Coroutine[Any, Any, None]]


class WebIngestError(DexaugError):
    """The web ingest cannot start (port taken, certificate unreadable, page assets missing)."""


class BackgroundServer:
    """Serves ``app`` on ``host``:``port`` (0 picks a free port; HTTPS with ``ssl_context``)
    from a daemon thread named ``thread_name``; ``task`` runs on the same loop while it serves
    and is cancelled when it stops. ``loop`` and ``port`` are set once :meth:`start` returned."""

    def __init__(self, app: web.Application, host: str, port: int,
                 ssl_context: ssl.SSLContext | None, *, task: Task,
                 thread_name: str = "dexaug-web") -> None:
        self.app, self.host, self.requested_port = app, host, port
        self.ssl_context = ssl_context
        self.loop: asyncio.AbstractEventLoop | None = None
        self.port: int | None = None
        self._task = task
        self._thread_name = thread_name
        self._runner: web.AppRunner | None = None
        self._thread: threading.Thread | None = None

    def start(self, timeout_s: float) -> None:
        """Serve in the background thread; returns once it listens (``port``), or raises."""
        ready = threading.Event()
        errors: list[BaseException] = []

        def serve() -> None:
            loop = asyncio.new_event_loop()
            self.loop = loop
            asyncio.set_event_loop(loop)
            try:
                self._runner = web.AppRunner(self.app, access_log=None, handle_signals=False)
                loop.run_until_complete(self._runner.setup())
                site = web.TCPSite(self._runner, self.host, self.requested_port,
                                   ssl_context=self.ssl_context)
                loop.run_until_complete(site.start())
                server = site._server  # aiohttp keeps the asyncio server here
                self.port = int(server.sockets[0].getsockname()[1])  # type: ignore[union-attr]
                poller = loop.create_task(self._task())
            except BaseException as exc:  # reported to start()'s caller
                errors.append(exc)
                if self._runner is not None:
                    with contextlib.suppress(Exception):
                        loop.run_until_complete(self._runner.cleanup())
                loop.close()
                self.loop = None   # nothing serves: stop() has nothing to stop
                ready.set()
                return
            ready.set()
            try:
                loop.run_forever()
            finally:
                poller.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    loop.run_until_complete(poller)
                loop.run_until_complete(self._runner.cleanup())
                loop.close()

        self._thread = threading.Thread(target=serve, name=self._thread_name, daemon=True)
        self._thread.start()
        if not ready.wait(timeout_s):
            raise WebIngestError(f"the web server did not start within {timeout_s} s")
        if errors:
            exc = errors[0]
            raise WebIngestError(f"cannot serve on {self.host}:{self.requested_port}: "
                                 f"{exc}") from exc

    def stop(self, before: Task) -> None:
        """Run ``before`` on the loop (up to 5 s; its errors are ignored), then stop the loop and
        join the thread (up to 10 s). Does nothing when not serving."""
        loop = self.loop
        if loop is not None and self._thread is not None:
            with contextlib.suppress(Exception):
                asyncio.run_coroutine_threadsafe(before(), loop).result(5.0)
            loop.call_soon_threadsafe(loop.stop)
            self._thread.join(10.0)
            self._thread = None
