"""The dashboard refuses what another web page, a rebound DNS name or another machine could ask
of it, and still does what its own page asks; the auto-augment queue runs one process at a time.

Every attack goes to a real dashboard server on loopback over real HTTP (urllib), and the ones a
browser makes are made by headless Chromium from a page of a foreign origin (Playwright serves
``http://evil.example/`` itself; its requests to the dashboard are real): a ``text/plain`` POST
(the CSRF confirmed in Chromium), a form POST, a foreign ``Origin``, a foreign ``Host`` (DNS
rebinding, also on the session list), no token beyond loopback. Each refusal is checked on the
answer (status and JSON error) and on what matters: no job was queued and the job target never
ran. The positive tests are the dashboard's own page queuing a job, on loopback and, bound
beyond loopback, with the token of its printed URL. The arm endpoint (``/api/arm``) gets the same
refusals, and it takes no path: a demo key, arm or placements that is not one the page offers is
refused, and a path sent beside a valid request never reaches the job. The jobs are a gate (no pipeline): they
report progress and wait for the test. The queue tests run ``python -c "sleep"`` processes that
write their own start and end times, so the concurrency is measured on the processes.
"""

from __future__ import annotations

import contextlib
import http.server
import json
import logging
import shutil
import sys
import threading
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from dexaug.dashboard.jobs import JobQueue, JobQueueFull
from dexaug.dashboard.server import Dashboard, DashboardConfig
from dexaug.pipeline.augment_queue import AugmentQueue
from dexaug.pipeline.options import AugmentOptions
from sim.paths import REPO_ROOT
from tests.browser import new_page
from tests.conftest import HANG_S, SOON_S, needs_menagerie, needs_ycb, wait_for
from tests.fake_results import fake_result

pytestmark = pytest.mark.slow

DICE = REPO_ROOT / "recordings" / "demo_062_dice.mcap"
EVIL = "http://evil.example"
OWN = {"Content-Type": "application/json", "X-Dexaug": "1"}   # what the page's JS sends


class Gate:
    """A job target that records each call, reports progress and waits until opened."""

    def __init__(self) -> None:
        self.calls: list[Any] = []
        self.open = threading.Event()

    def __call__(self, payload: Any, progress: Callable[[str, int, int], None]) -> dict[str, Any]:
        self.calls.append(payload)
        progress("fsg", 1, 2)
        self.open.wait(HANG_S)   # every test opens it (the fixture at its end)
        return {"generated": 2, "passed": 1, "report": None}


def _request(url: str, body: bytes | None = None, headers: dict[str, str] | None = None,
             method: str | None = None) -> tuple[int, Any, Any]:
    """(status, JSON body or raw bytes, headers) of one real HTTP request."""
    req = urllib.request.Request(url, body, headers or {}, method=method)
    try:
        with urllib.request.urlopen(req, timeout=SOON_S) as r:
            status, raw, hdrs = r.status, r.read(), r.headers
    except urllib.error.HTTPError as exc:
        status, raw, hdrs = exc.code, exc.read(), exc.headers
    if "json" in hdrs.get("Content-Type", ""):
        return status, json.loads(raw), hdrs
    return status, raw, hdrs


@pytest.fixture
def serve(tmp_path: Path) -> Iterator[Callable[..., tuple[Dashboard, str, Gate]]]:
    """``serve(host=..., copies=..., **config)`` → (dashboard, its base URL on 127.0.0.1, gate):
    a real dashboard over ``copies`` copies of the dice session, its jobs behind a gate."""
    started: list[tuple[Dashboard, Gate]] = []

    def start(host: str = "127.0.0.1", copies: int = 1, **config: Any) -> tuple[Dashboard, str, Gate]:
        sessions = tmp_path / f"sessions{len(started)}"
        sessions.mkdir()
        for k in range(copies):
            shutil.copy(DICE, sessions / f"dice{k}.mcap")
        cfg = DashboardConfig(sessions, tmp_path / "out", AugmentOptions(n=5, workers=1, gallery=0),
                              host=host, port=0, **config)
        gate = Gate()
        dash = Dashboard(cfg, target=gate, arm_target=gate)
        started.append((dash, gate))
        dash.start()
        return dash, f"http://127.0.0.1:{dash.port}/", gate

    yield start
    for dash, gate in started:
        gate.open.set()
        dash.close()


@contextlib.contextmanager
def _page_server(html: str) -> Iterator[str]:
    """A real HTTP server on another loopback port serving ``html`` (the attacker's page);
    yields its URL."""
    class Page(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = html.encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: Any) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Page)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def _demo_keys(base: str, headers: dict[str, str] | None = None) -> list[str]:
    status, doc, _ = _request(base + "api/sessions", headers=headers or {"X-Dexaug": "1"})
    assert status == 200 and doc["error"] is None, doc
    keys = [d["key"] for s in doc["sessions"] for d in s["demos"] if not d["error"]]
    assert keys, doc
    return keys


def _augment(base: str, key: str, headers: dict[str, str]) -> tuple[int, Any, Any]:
    return _request(base + "api/augment", json.dumps({"demo": key}).encode(), headers)


def _wait(check: Callable[[], bool], what: str) -> None:
    wait_for(check, SOON_S, what)


# ------------------------------------------------------------------------------- the dashboard

@needs_menagerie
@needs_ycb
def test_cross_site_posts_are_refused_and_start_nothing(serve) -> None:
    """A ``text/plain`` body (with or without a foreign Origin), a JSON body without the custom
    header, and a foreign or ``null`` Origin are refused with 403 and a JSON error."""
    dash, base, gate = serve()
    (key,) = _demo_keys(base)
    body = json.dumps({"demo": key}).encode()
    attempts = {
        "text/plain from a foreign origin": {"Content-Type": "text/plain", "Origin": EVIL},
        "text/plain": {"Content-Type": "text/plain", "X-Dexaug": "1"},
        "form-encoded": {"Content-Type": "application/x-www-form-urlencoded", "X-Dexaug": "1"},
        "JSON without the custom header": {"Content-Type": "application/json"},
        "JSON from a foreign origin": {**OWN, "Origin": EVIL},
        "JSON from a null origin": {**OWN, "Origin": "null"},
        "JSON from another port": {**OWN, "Origin": f"http://127.0.0.1:{dash.port + 1}"},
    }
    for what, headers in attempts.items():
        status, doc, _ = _request(base + "api/augment", body, headers)
        assert status == 403 and doc["error"], (what, status, doc)
    # no sleep: each refusal was answered after the server decided, and a job is queued
    # before its request is answered, so none of them can queue one from now on
    assert dash.jobs.snapshot() == [] and gate.calls == []
    # no CORS preflight is granted: a page may not send the custom header cross-origin
    status, _, hdrs = _request(base + "api/augment", method="OPTIONS", headers={
        "Origin": EVIL, "Access-Control-Request-Method": "POST",
        "Access-Control-Request-Headers": "content-type,x-dexaug"})
    assert status >= 400 and not [h for h in hdrs if h.lower().startswith("access-control-")]
    # the page's own request, same-origin: queued
    status, doc, _ = _augment(base, key, {**OWN, "Origin": base.rstrip("/")})
    assert status == 200 and doc["job"]["state"] in ("queued", "running")
    _wait(lambda: len(gate.calls) == 1, "the job's start")


@needs_menagerie
@needs_ycb
def test_a_foreign_host_is_refused_even_for_reading(serve) -> None:
    """DNS rebinding: with a Host the server is not bound for, the session list, the page and
    a POST are refused (421, no session in the answer); the loopback names are accepted."""
    dash, base, gate = serve()
    (key,) = _demo_keys(base)
    evil_host = {"Host": f"evil.example:{dash.port}", "X-Dexaug": "1"}
    for path in ("api/sessions", "api/jobs", "", "static/app.js"):
        status, doc, _ = _request(base + path, headers=evil_host)
        assert status == 421 and "evil.example" in doc["error"] and "sessions" not in doc, path
    status, doc, _ = _augment(base, key, {**OWN, **evil_host})
    assert status == 421
    for name in ("localhost", "127.0.0.1", "[::1]"):
        status, doc, _ = _request(base + "api/sessions", headers={"Host": f"{name}:{dash.port}"})
        assert status == 200 and doc["sessions"], name
    # no sleep: each refusal was answered after the server decided, and a job is queued
    # before its request is answered, so none of them can queue one from now on
    assert dash.jobs.snapshot() == [] and gate.calls == []


@needs_menagerie
@needs_ycb
def test_chromium_on_a_foreign_page_cannot_start_a_job(serve, chromium, caplog) -> None:
    """The attack as a browser makes it: a page of another origin (another local server's port)
    POSTs ``text/plain`` (no-cors fetch), tries the custom header (blocked by the preflight) and
    submits a text/plain form. The two POSTs that reach the server are refused; no job is
    queued."""
    dash, base, gate = serve()
    (key,) = _demo_keys(base)
    field = json.dumps({"demo": key, "x": ""})[:-2]   # the form sends name=value: '{"demo":…"x":"="}'
    html = f"""<!doctype html><body><form id="f" method="POST" enctype="text/plain"
      action="{base}api/augment"><input name='{field}' value='"}}'></form></body>"""
    page = new_page(chromium, https=False)
    with _page_server(html) as evil:
        page.goto(evil)
    caplog.set_level(logging.WARNING, logger="dexaug.dashboard.guard")
    body = json.dumps({"demo": key})
    page.evaluate("""async ([url, body]) => {
        await fetch(url, {method: "POST", mode: "no-cors", headers: {"Content-Type": "text/plain"},
                          body});
        try { await fetch(url, {method: "POST", headers: {"X-Dexaug": "1"}, body}); }
        catch (e) { }   // the preflight fails: nothing is sent
    }""", [base + "api/augment", body])
    with page.expect_navigation():
        page.evaluate("() => document.getElementById('f').submit()")
    assert "403" in page.title() or "error" in page.content()
    page.context.close()
    # no sleep: both fetches and the form's navigation ended on the server's answers, and a job
    # is queued (and a refusal logged) before the answer
    assert dash.jobs.snapshot() == [] and gate.calls == []
    refused = [r for r in caplog.records if "refused POST '/api/augment'" in r.getMessage()]
    assert len(refused) == 2, [r.getMessage() for r in caplog.records]   # they reached it


@needs_menagerie
@needs_ycb
@pytest.mark.parametrize("host", ["127.0.0.1", "0.0.0.0"])
def test_the_dashboards_own_page_queues_a_job(serve, chromium, host: str) -> None:
    """The page's "Augment" still works: on loopback with no token, and bound beyond loopback
    with the token of the printed URL (its thumbnail too, through the cookie)."""
    dash, base, gate = serve(host=host)
    assert (dash.token is None) == (host == "127.0.0.1")
    query = f"?token={dash.token}" if dash.token else ""
    assert dash.url.endswith(f":{dash.port}/{query}")
    console: list[str] = []
    page = new_page(chromium, https=False, console=console)
    thumbs: list[int] = []
    page.on("response", lambda r: thumbs.append(r.status) if "/thumbnails/" in r.url else None)
    page.goto(base + query)
    page.set_default_timeout(SOON_S * 1000)
    page.wait_for_function("() => document.body.dataset.loaded === '1'", timeout=SOON_S * 1000)
    page.locator("button.augment").click()
    page.locator(".progress-text").filter(has_text="FSG sampling: 1 / 2").wait_for(
        timeout=SOON_S * 1000)
    assert len(gate.calls) == 1 and [j["state"] for j in dash.jobs.snapshot()] == ["running"]
    gate.open.set()
    page.locator(".n-passed").wait_for(timeout=SOON_S * 1000)
    page.wait_for_function("() => [...document.images].every(i => i.complete)",
                           timeout=SOON_S * 1000)
    assert page.locator(".n-passed").inner_text() == "1"
    assert thumbs and all(s == 200 for s in thumbs), thumbs
    assert not [c for c in console if c.startswith(("error", "pageerror"))], console
    page.goto("about:blank")
    page.context.close()


@needs_menagerie
@needs_ycb
def test_beyond_loopback_every_request_needs_the_token(serve) -> None:
    """Bound to all interfaces: without the token (or with a wrong one) the page, the API and
    the static files are refused; the header, the query and the cookie set from the query are
    accepted, and a POST with the token header queues a job. The Host may also be the address
    the connection arrived on (127.0.0.2 here), but no other address."""
    dash, base, gate = serve(host="0.0.0.0")
    token = dash.token
    assert token and len(token) >= 24
    for path in ("", "api/sessions", "api/jobs", "static/app.js"):
        assert _request(base + path)[0] == 403, path
        assert _request(base + path, headers={"X-Dexaug-Token": _wrong(token)})[0] == 403
    status, _, hdrs = _request(base + f"?token={token}")
    cookie = hdrs.get("Set-Cookie", "")
    assert status == 200 and token in cookie and "HttpOnly" in cookie and "Strict" in cookie
    jar = cookie.split(";")[0]
    assert _request(base + "static/app.js", headers={"Cookie": jar})[0] == 200
    (key,) = _demo_keys(base, {"X-Dexaug-Token": token})
    # an address literal is accepted as Host where the connection arrived on it, not elsewhere
    other = f"http://127.0.0.2:{dash.port}/api/jobs"
    assert _request(other, headers={"X-Dexaug-Token": token})[0] == 200
    assert _request(other, headers={"X-Dexaug-Token": token, "Host": f"127.0.0.3:{dash.port}"}
                    )[0] == 421
    assert _augment(base, key, {"Content-Type": "application/json"})[0] == 403   # no token
    status, doc, _ = _augment(base, key, {"Content-Type": "application/json",
                                          "X-Dexaug-Token": token})
    assert status == 200 and doc["job"]["state"] in ("queued", "running")
    _wait(lambda: len(gate.calls) == 1, "the job's start")


@needs_menagerie
@needs_ycb
def test_the_api_refuses_jobs_beyond_the_queue_bound(serve) -> None:
    """With one job running and ``max_queued`` (1) waiting, the next is refused with 429 and a
    clear error; the queue is unchanged."""
    dash, base, gate = serve(copies=3, max_queued=1)
    keys = _demo_keys(base)
    assert len(keys) == 3
    assert _augment(base, keys[0], OWN)[0] == 200
    _wait(lambda: len(gate.calls) == 1, "the first job's start")
    assert _augment(base, keys[1], OWN)[0] == 200
    status, doc, _ = _augment(base, keys[2], OWN)
    assert status == 429 and "already waiting" in doc["error"]
    assert [j["key"] for j in dash.jobs.snapshot()] == keys[:2]


def test_the_job_list_is_bounded() -> None:
    """Waiting jobs beyond ``max_queued`` are refused; finished ones beyond ``max_finished`` are
    forgotten oldest first."""
    gate = Gate()
    q = JobQueue(gate, max_queued=3, max_finished=2)
    try:
        q.submit("run", "running", 0)
        _wait(lambda: len(gate.calls) == 1, "the first job's start")
        for k in range(3):
            q.submit(f"q{k}", f"queued {k}", k, kind="arm" if k == 1 else "augment")
        # the message names what waits: arm runs are not called augmentations
        with pytest.raises(JobQueueFull, match="1 arm run and 2 augmentations are already waiting"):
            q.submit("late", "one too many", 9)
        gate.open.set()
        _wait(lambda: all(j["state"] == "done" for j in q.snapshot()), "the jobs' end")
        assert [j["key"] for j in q.snapshot()] == ["q1", "q2"]
        q.submit("late", "now there is room", 9)   # the bound counts waiting jobs only
        _wait(lambda: [j["key"] for j in q.snapshot()] == ["q2", "late"]
              and q.snapshot()[-1]["state"] == "done", "the late job's end")
    finally:
        gate.open.set()
        q.close()


@needs_menagerie
@needs_ycb
def test_the_arm_endpoint_takes_no_path_and_needs_the_token(serve) -> None:
    """``POST /api/arm`` bound beyond loopback: without the token, with a wrong one, cross-site
    or text/plain it is refused (403); a demo key that is a path (404), an arm that is a path or
    placements out of bounds (400), a demo without a result (409) start nothing. A path sent
    beside a valid request is ignored: the job gets the catalog's result file."""
    dash, base, gate = serve(host="0.0.0.0")
    token = dash.token
    auth = {"Content-Type": "application/json", "X-Dexaug-Token": token}
    (key,) = _demo_keys(base, {"X-Dexaug-Token": token})
    good = {"demo": key, "arm": "ur5e", "placements": 2}

    def arm(body: Any, headers: dict[str, str]) -> tuple[int, Any]:
        status, doc, _ = _request(base + "api/arm", json.dumps(body).encode(), headers)
        return status, doc

    assert arm(good, auth)[0] == 409                # no result yet: nothing to put on an arm
    data = fake_result(dash.config.out_root, dash.catalog.demo(key).demo)
    refused = {
        "no token": (good, OWN, 403),
        "a wrong token": (good, {**auth, "X-Dexaug-Token": _wrong(token)}, 403),
        "text/plain": (good, {"Content-Type": "text/plain", "X-Dexaug-Token": token}, 403),
        "a foreign origin": (good, {**auth, "Origin": EVIL}, 403),
        "a relative path as the demo": ({**good, "demo": "../../etc/passwd"}, auth, 404),
        "the result folder as the demo": ({**good, "demo": str(data.parent)}, auth, 404),
        "the key through a path": ({**good, "demo": f"{key}/../{key}"}, auth, 404),
        "a path as the arm": ({**good, "arm": "../../configs/arms/ur5e/arm.toml"}, auth, 400),
        "too many placements": ({**good, "placements": 10**6}, auth, 400),
        "placements as text": ({**good, "placements": "2; rm -rf /"}, auth, 400),
        "no arm": ({"demo": key}, auth, 400),
    }
    for what, (body, headers, status) in refused.items():
        got, doc = arm(body, headers)
        assert got == status and doc["error"], (what, got, doc)
    # no sleep: each refusal was answered after the server decided, and a job is queued
    # before its request is answered, so none of them can queue one from now on
    assert dash.jobs.snapshot() == [] and gate.calls == []
    status, doc = arm({**good, "dataset": "/etc/passwd", "out": "/tmp/evil.h5"}, auth)
    assert status == 200 and (doc["job"]["kind"], doc["job"]["demo"]) == ("arm", key)
    _wait(lambda: len(gate.calls) == 1, "the arm job's start")
    (job,) = gate.calls
    assert (job.dataset, job.arm, job.placements) == (data, "ur5e", 2)
    assert job.dataset.is_relative_to(dash.config.out_root)


# --------------------------------------------------------------------------- the augment queue

#: the process the queue tests run: sleeps 0.3 s, then appends "start end" (Unix s) to argv[1]
SLEEP = ("import sys, time; t0 = time.time(); time.sleep(0.3); "
         "open(sys.argv[1], 'a').write(f'{t0} {time.time()}\\n')")
#: the same, waiting (instead of the sleep) until a second process has appended to argv[2] as
#: it started, at most SOON_S: two processes run at once whenever the queue lets them, however
#: slowly a loaded machine starts the second, so the overlap is an event, not a timing guess
MEET = f"""import sys, time
t0 = time.time()
open(sys.argv[2], "a").write("started\\n")
t_end = time.monotonic() + {SOON_S}
while len(open(sys.argv[2]).read().splitlines()) < 2 and time.monotonic() < t_end:
    time.sleep(0.01)
open(sys.argv[1], "a").write(f"{{t0}} {{time.time()}}\\n")
"""


def _timed(stamps: Path, program: str = SLEEP) -> Callable[[Path], list[str]]:
    starts = stamps.with_suffix(".starts")
    return lambda session: [sys.executable, "-c", program, str(stamps), str(starts)]


def _spans(stamps: Path) -> list[tuple[float, float]]:
    return sorted(tuple(map(float, line.split())) for line in stamps.read_text().splitlines())


def _max_overlap(spans: list[tuple[float, float]]) -> int:
    events = sorted([(a, 1) for a, _ in spans] + [(b, -1) for _, b in spans])
    level = best = 0
    for _, d in events:
        level += d
        best = max(best, level)
    return best


def test_the_augment_queue_runs_one_process_at_a_time(tmp_path: Path, caplog) -> None:
    """Five sessions submitted at once run one after another, in order, each logged with its exit
    code; with ``max_running=2`` the same five overlap (so the check can fail)."""
    caplog.set_level(logging.INFO, logger="dexaug.pipeline.augment_queue")
    for max_running, expected in ((1, 1), (2, 2)):
        stamps = tmp_path / f"stamps{max_running}.txt"
        q = AugmentQueue(tmp_path / "out", max_running=max_running, max_waiting=8,
                         command=_timed(stamps, SLEEP if max_running == 1 else MEET))
        sessions = [tmp_path / f"s{k}.mcap" for k in range(5)]
        assert all(q.submit(s) for s in sessions)
        q.close()   # waits for the queue to run out
        spans = _spans(stamps)
        assert len(spans) == 5 and _max_overlap(spans) == expected, spans
    finished = [r.getMessage() for r in caplog.records if "(exit code 0" in r.getMessage()]
    assert len(finished) == 10
    started = [r.getMessage() for r in caplog.records if r.getMessage().startswith("augmenting ")]
    assert [m.split()[1] for m in started[:5]] == [str(s) for s in sessions]   # FIFO
    assert (tmp_path / "out" / "s0.augment.log").is_file()


def test_the_augment_queue_refuses_beyond_its_bound_and_terminates_on_close(tmp_path: Path,
                                                                             caplog) -> None:
    """With one running and ``max_waiting`` (2) waiting, further sessions are refused with a
    warning naming the command to run later; ``close(timeout_s=0)`` drops the waiting ones and
    terminates the running one (its exit code logged), in well under its 30 s."""
    caplog.set_level(logging.INFO, logger="dexaug.pipeline.augment_queue")
    started = tmp_path / "started"
    long = f"import pathlib, time; pathlib.Path({str(started)!r}).touch(); time.sleep(30)"
    notes: list[str] = []
    q = AugmentQueue(tmp_path / "out", ("--n", "5"), max_waiting=2, notify=notes.append,
                     command=lambda s: [sys.executable, "-c", long, s.name])
    assert q.submit(tmp_path / "a.mcap")
    _wait(started.exists, "the first process's start")
    assert q.submit(tmp_path / "b.mcap") and q.submit(tmp_path / "c.mcap")
    assert not q.submit(tmp_path / "d.mcap")
    assert any("not augmenting" in n and "d.mcap" in n and "2 sessions already wait" in n
               for n in notes), notes
    q.close(timeout_s=0.0)
    # terminated, not waited for (the event, not close's wall time): SIGTERM's exit code; a
    # close that waited would log the process's own end after its 30 s, exit code 0
    assert any("a.mcap failed (exit code -15" in n for n in notes), notes
    assert sum("not augmenting" in n and "stopping" in n for n in notes) == 2, notes
    assert not q.submit(tmp_path / "e.mcap")   # closed


def test_the_default_command_is_dexaug_augment(tmp_path: Path) -> None:
    q = AugmentQueue(tmp_path / "out", ("--n", "5"))
    try:
        assert q.command(Path("rec/s.mcap")) == [sys.executable, "-m", "dexaug", "augment",
                                                 "rec/s.mcap", "--out", str(tmp_path / "out"),
                                                 "--n", "5"]
    finally:
        q.close()


def _wrong(token: str) -> str:
    """``token`` with its last character changed (always a different token: replacing it by a
    fixed letter let the right token through when it already ended in that letter)."""
    return token[:-1] + ("y" if token.endswith("x") else "x")
