"""The dashboard's web server (aiohttp): the page, a small JSON API, thumbnails and reports.

Routes::

    GET  /                      the page (static/index.html, app.js)
    GET  /api/sessions          sessions, their demos (or why none), finished results, options
    GET  /api/jobs              every job: state, pipeline stage and progress, result or error
    POST /api/augment           {"demo": KEY} → queue KEY's augmentation; the job as JSON;
                                optional "n", "time_budget_s", "workers", "gallery" for this
                                job, each within a ceiling (dashboard.jobs_bounds; else 400)
    POST /api/settings          {"n": N, "table": "demo"|"on"|"off", "validate": P|"none"}
                                → the settings later augmentations use (dashboard.settings)
    GET  /api/results           every result folder under the output folder (dashboard.results)
    POST /api/arm               {"demo": KEY, "arm": ARM, "placements": N} → queue putting
                                KEY's finished result on ARM (arm_<ARM>.h5 in its folder)
    GET  /thumbnails/KEY.png    the demo grasp (a placeholder SVG without OpenGL)
    GET  /results/...           the output folder: each demo's report.html and its images

Every request passes :class:`~dexaug.dashboard.guard.Guard` first (Host check against DNS
rebinding, JSON plus a custom header and a same-origin ``Origin`` for a POST, the per-start token
when listening beyond loopback): the page's JS sends ``X-Dexaug: 1`` and, when its URL carries a
token, ``X-Dexaug-Token``.

The page polls ``/api/jobs`` for live progress: polling needs no connection state on either
side, survives a restarted server, and at a few requests per second costs nothing here.

Nothing slow runs on the event loop: session scans go to the default thread pool, renders to
one dedicated render thread (:mod:`dexaug.dashboard.catalog`), augmentations and arm runs to
the job thread (:mod:`dexaug.dashboard.jobs`; the pipeline runs its own process pools). The server runs
its loop in a background thread (:meth:`Dashboard.start`), so tests and the CLI drive it the
same way.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import html
import logging
import socket
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from aiohttp import web

from dexaug.dashboard.arm_jobs import ArmJob, parse_arm_request, run_arm_job
from dexaug.dashboard.catalog import Catalog, result_view
from dexaug.dashboard.guard import WILDCARDS, Guard
from dexaug.dashboard.jobs import JobQueue, JobQueueFull, JobTarget, run_augmentation
from dexaug.dashboard.jobs_bounds import parse_augment_request
from dexaug.dashboard.results import list_results
from dexaug.dashboard.settings import SettingsError, apply_settings, settings_json
from dexaug.pipeline.arm_stage import DEFAULT_PLACEMENTS, MAX_PLACEMENTS
from dexaug.pipeline.options import AugmentOptions
from sim.errors import DexaugError

__all__ = ["Dashboard", "DashboardConfig", "DashboardError"]

log = logging.getLogger(__name__)


class DashboardError(DexaugError):
    """The dashboard cannot start (port taken, page assets missing)."""


@dataclass
class DashboardConfig:
    """Where the sessions are, where results go, what an augmentation does, where to listen
    (port 0 picks a free one; an address beyond loopback makes a per-start token required),
    and how many jobs the list keeps (``max_queued`` waiting, ``max_finished`` done or failed)."""

    sessions_dir: Path = Path("recordings")
    out_root: Path = Path("datasets")
    options: AugmentOptions = field(default_factory=AugmentOptions)
    host: str = "127.0.0.1"
    port: int = 8770   # not 8765: Foxglove's (bridge --foxglove), so both can run
    max_queued: int = 20
    max_finished: int = 100


class Dashboard:
    """The dashboard (module docstring). ``target`` replaces the augmentation run in a job,
    ``arm_target`` the arm run (tests); :meth:`start` serves and returns the URL,
    :meth:`close` stops everything."""

    def __init__(self, config: DashboardConfig | None = None, *,
                 target: JobTarget = run_augmentation,
                 arm_target: JobTarget = run_arm_job) -> None:
        cfg = config or DashboardConfig()
        # absolute: summaries store dataset paths, and the report links are made relative to it
        self.config = dataclasses.replace(cfg, sessions_dir=Path(cfg.sessions_dir).resolve(),
                                          out_root=Path(cfg.out_root).resolve())
        self.catalog = Catalog(self.config.sessions_dir, self.config.out_root,
                               self.config.options)
        self.guard = Guard(self.config.host)
        self.jobs = JobQueue(target, max_queued=self.config.max_queued,
                             max_finished=self.config.max_finished)
        self._arm_target = arm_target
        self._render = ThreadPoolExecutor(1, thread_name_prefix="dexaug-render")
        self._static = Path(str(resources.files("dexaug.dashboard") / "static"))
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self.port: int | None = None
        self.url: str | None = None

    # ------------------------------------------------------------------------------ lifecycle

    def _app(self) -> web.Application:
        if not (self._static / "index.html").is_file():
            raise DashboardError(f"{self._static}: the page assets (index.html, app.js) are "
                                 "missing; reinstall dexaug")
        self.config.out_root.mkdir(parents=True, exist_ok=True)
        app = web.Application(middlewares=[self.guard.middleware])
        app.add_routes([web.get("/", self._index), web.get("/favicon.ico", self._icon),
                        web.get("/api/sessions", self._sessions), web.get("/api/jobs", self._jobs),
                        web.post("/api/augment", self._augment), web.post("/api/arm", self._arm),
                        web.post("/api/settings", self._settings),
                        web.get("/api/results", self._results),
                        web.get("/thumbnails/{key}.png", self._thumbnail),
                        web.static("/static/", self._static),
                        web.static("/results/", self.config.out_root)])
        return app

    async def _serve(self, app: web.Application, started: Future[int]) -> None:
        """The server thread's whole life: listen, report the port (or the error) through
        ``started``, run until :meth:`close` sets the stop event, clean up."""
        self._loop, self._stop = asyncio.get_running_loop(), asyncio.Event()
        runner = web.AppRunner(app, access_log=None, handle_signals=False)
        await runner.setup()
        try:
            site = web.TCPSite(runner, self.config.host, self.config.port)
            await site.start()
            sock = site._server.sockets[0]  # type: ignore[union-attr]  # aiohttp keeps it here
            self.guard.port = int(sock.getsockname()[1])
            started.set_result(self.guard.port)
            await self._stop.wait()
        except OSError as exc:
            started.set_exception(exc)
        finally:
            await runner.cleanup()

    @property
    def token(self) -> str | None:
        """The per-start token every request needs (None on a loopback address)."""
        return self.guard.token

    def start(self, timeout_s: float = 10.0) -> str:
        """Serve in a background thread; returns the page URL (with the token, if any)."""
        app = self._app()
        started: Future[int] = Future()

        def run() -> None:
            try:
                asyncio.run(self._serve(app, started))
            except BaseException as exc:  # reported to start()'s caller, not lost in a thread
                if not started.done():
                    started.set_exception(exc)

        self._thread = threading.Thread(target=run, name="dexaug-dashboard", daemon=True)
        self._thread.start()
        try:
            self.port = started.result(timeout_s)
        except TimeoutError:
            raise DashboardError(f"the dashboard did not start within {timeout_s} s") from None
        except Exception as exc:
            raise DashboardError(f"cannot serve on {self.config.host}:{self.config.port}: "
                                 f"{exc}") from exc
        base = f"http://{_url_host(self.config.host)}:{self.port}/"
        self.url = base + (f"?token={self.token}" if self.token else "")
        log.info("dashboard on %s (sessions %s, results %s)", base,   # the token stays out of logs
                 self.config.sessions_dir, self.config.out_root)
        if self.token:
            log.warning("the dashboard listens beyond this machine (%s): anyone with its URL "
                        "can start augmentations", self.config.host)
        return self.url

    def close(self) -> None:
        """Stop serving, stop taking jobs, and stop the render thread."""
        if self._thread is not None and self._loop is not None and self._stop is not None:
            # a RuntimeError: the loop is closed, a failed start() ended it already
            with contextlib.suppress(RuntimeError):
                self._loop.call_soon_threadsafe(self._stop.set)
            self._thread.join(10.0)
        self._thread = None
        self.jobs.close()
        self._render.shutdown(wait=False, cancel_futures=True)

    def __enter__(self) -> Dashboard:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -------------------------------------------------------------------------------- handlers

    def _options_json(self) -> dict[str, Any]:
        from sim.arm.config import arm_names

        o = self.config.options
        return {"n": o.n, "validate": o.validate, "workers": o.workers, "gallery": o.gallery,
                "seed": o.seed, "time_budget_s": o.time_budget_s, "table": o.table,
                "link_penetration": o.link_penetration,
                "sessions_dir": str(self.config.sessions_dir),
                "out_root": str(self.config.out_root), "arms": arm_names(),
                "arm_placements": DEFAULT_PLACEMENTS, "arm_placements_max": MAX_PLACEMENTS,
                "settings": settings_json(o)}

    def _job_json(self, job: dict[str, Any]) -> dict[str, Any]:
        # an arm job's result is already the page's view (run_arm_job)
        if job.get("result") is not None and job.get("kind") != "arm":
            job = {**job, "result": result_view(job["result"], self.config.out_root)}
        return job

    async def _index(self, _request: web.Request) -> web.FileResponse:
        return web.FileResponse(self._static / "index.html")

    async def _icon(self, _request: web.Request) -> web.Response:
        return web.Response(status=204)   # no icon, and no 404 in the browser console

    async def _sessions(self, _request: web.Request) -> web.Response:
        try:
            sessions = await asyncio.to_thread(self.catalog.to_json)
        except DexaugError as exc:
            return web.json_response({"error": str(exc), "sessions": [],
                                      "options": self._options_json()})
        return web.json_response({"error": None, "sessions": sessions,
                                  "options": self._options_json()})

    async def _jobs(self, _request: web.Request) -> web.Response:
        return web.json_response({"jobs": [self._job_json(j) for j in self.jobs.snapshot()]})

    async def _settings(self, request: web.Request) -> web.Response:
        """Change n, table mode or protocol for the augmentations queued from now on (jobs
        already queued keep theirs); the listing then compares results with the new ones."""
        try:
            opts = apply_settings(await request.json(), self.config.options)
        except ValueError:
            return web.json_response({"error": "the body is not JSON"}, status=400)
        except SettingsError as exc:
            return web.json_response({"error": str(exc)}, status=400)
        self.config = dataclasses.replace(self.config, options=opts)
        self.catalog.opts = opts
        log.info("dashboard settings: n %d, table %s, validate %s", opts.n, opts.table,
                 opts.validate)
        return web.json_response({"options": self._options_json()})

    async def _results(self, _request: web.Request) -> web.Response:
        results = await asyncio.to_thread(list_results, self.config.out_root)
        return web.json_response({"results": results})

    async def _augment(self, request: web.Request) -> web.Response:
        # every size is checked before anything is looked up or queued (jobs_bounds)
        try:
            key, opts = parse_augment_request(await request.json(), self.config.options)
        except ValueError:
            return web.json_response({"error": 'expected JSON {"demo": KEY}'}, status=400)
        except DexaugError as exc:
            return web.json_response({"error": str(exc)}, status=400)
        entry = self.catalog.demo(key)
        if entry is None:
            return web.json_response({"error": f"no demo {key!r} (reload the page)"},
                                     status=404)
        if entry.error:
            return web.json_response({"error": entry.error}, status=409)
        try:
            job = self.jobs.submit(key, entry.demo.id,
                                   (entry.demo, str(self.config.out_root), opts))
        except JobQueueFull as exc:
            return web.json_response({"error": str(exc)}, status=429)
        return web.json_response({"job": self._job_json(job.to_json())})

    async def _arm(self, request: web.Request) -> web.Response:
        """Queue putting a listed demo's finished result on an arm. The body names the demo
        by its catalog key only; the grasps file is the catalog's (module docstring of
        :mod:`dexaug.dashboard.arm_jobs`)."""
        try:
            key, arm, placements = parse_arm_request(await request.json())
        except ValueError:
            return web.json_response({"error": "the body is not JSON"}, status=400)
        except DexaugError as exc:
            return web.json_response({"error": str(exc)}, status=400)
        entry = self.catalog.demo(key)
        if entry is None:
            return web.json_response({"error": f"no demo {key!r} (reload the page)"},
                                     status=404)
        data = None if entry.error else await asyncio.to_thread(self.catalog.result_dataset, entry)
        if data is None:
            return web.json_response({"error": entry.error or f"demo {entry.demo.id} has no "
                                      "finished result to put on an arm: augment it first"},
                                     status=409)
        try:
            job = self.jobs.submit(f"arm:{key}:{arm}", f"{entry.demo.id} on {arm}",
                                   ArmJob(key, data, arm, placements), kind="arm", demo=key,
                                   target=self._arm_target)
        except JobQueueFull as exc:
            return web.json_response({"error": str(exc)}, status=429)
        return web.json_response({"job": self._job_json(job.to_json())})

    async def _thumbnail(self, request: web.Request) -> web.StreamResponse:
        key = request.match_info["key"]
        loop = asyncio.get_running_loop()
        try:
            path, why = await loop.run_in_executor(self._render, self.catalog.thumbnail, key)
        except RuntimeError:   # the render thread is shut down: closing
            path, why = None, "the dashboard is shutting down"
        if path is not None:
            return web.FileResponse(path)
        return web.Response(body=_placeholder(why or "no image"), content_type="image/svg+xml",
                            headers={"X-Dexaug-Placeholder": "1", "Cache-Control": "no-store"})


def _url_host(bind: str) -> str:
    """The host part of the printed URL: ``localhost`` for 127.0.0.1, this machine's name on a
    wildcard bind (the Host check accepts both), else the bound address (IPv6 bracketed)."""
    host = bind.strip("[]")
    if host in ("127.0.0.1", "localhost"):
        return "localhost"
    if host in WILDCARDS:
        return socket.gethostname()
    return f"[{host}]" if ":" in host else host


def _placeholder(why: str) -> bytes:
    """A 320×240 grey SVG saying why there is no picture (the reason, wrapped)."""
    words, lines, line = why.split(), [], ""
    for w in words:
        if len(line) + len(w) > 40 and line:
            lines.append(line)
            line = ""
        line = f"{line} {w}".strip()
    lines.append(line)
    text = "".join(f"<tspan x='160' dy='1.3em'>{html.escape(t)}</tspan>" for t in lines[:6])
    return (f"<svg xmlns='http://www.w3.org/2000/svg' width='320' height='240'>"
            f"<rect width='320' height='240' fill='#e6e6e6'/><text x='160' y='80' "
            f"font-family='sans-serif' font-size='13' fill='#555' text-anchor='middle'>"
            f"<tspan x='160' dy='0'>no preview</tspan>{text}</text></svg>").encode()
