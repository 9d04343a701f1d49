"""The dashboard (``dexaug ui``): job queue, JSON API, and the page in headless Chromium.

The browser test is the user's path, checked on content: a session without a usable grasp shows
its reason; "Augment" on the dice demo runs the real pipeline (small options) with progress on
the page; the numbers the page then shows equal ``summary.json`` and the dataset, the demo
grasp's own verdict is shown beside them as the report states it, and the report it links
states the same passed count; a restarted dashboard shows the finished result
directly. "Put on arm" on a finished result runs the real arm stage as a job and the page, then
a restarted dashboard's catalog, shows the arm file's own numbers. A screenshot goes to
``tests/artifacts/``. The queue and API tests use fake jobs (no pipeline): order, progress, a
dexaug error, an unexpected error, bad requests, an arm job's live progress and failure.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import shutil
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from augment import dataset
from dexaug.dashboard.jobs import JobQueue
from sim.errors import DexaugError
from sim.paths import REPO_ROOT
from tests.browser import artifact_path, new_page
from tests.conftest import HANG_S, SOON_S, needs_menagerie, needs_ycb, wait_for
from tests.dashboard_http import post_json
from tests.fake_results import arm_file_numbers, fake_result

pytestmark = pytest.mark.slow

DICE = REPO_ROOT / "recordings" / "demo_062_dice.mcap"
RAW = REPO_ROOT / "recordings" / "synth_005_tomato_soup_can.mcap"


def fake_job(payload: Any, progress) -> dict[str, Any]:
    """A fake job target: ``("ok", n)`` reports n progress steps and returns
    a summary-like dict; ``("fail", msg)`` raises a DexaugError; ``("bug", msg)`` another
    error; the dashboard's own payload ``(demo, out, opts)`` fails as the pipeline would."""
    if len(payload) == 3:
        raise DexaugError(f"{payload[0].id}: FSG found no grasp")
    kind, arg = payload
    if kind == "fail":
        raise DexaugError(arg)
    if kind == "bug":
        raise KeyError(arg)
    for k in range(arg + 1):
        progress("fsg", k, arg)
    return {"generated": arg, "passed": arg - 1, "report": None}


def _wait_final(q: JobQueue, n: int) -> list[dict[str, Any]]:
    def final() -> list[dict[str, Any]] | None:
        jobs = q.snapshot()
        return jobs if len(jobs) == n and all(j["state"] in ("done", "failed") for j in jobs) \
            else None
    return wait_for(final, SOON_S, lambda: f"{n} finished jobs: {q.snapshot()}")


def test_result_view_of_a_summary_without_the_demo_check(tmp_path: Path) -> None:
    """A summary.json written before the demo grasp was checked lists as not validated, not
    as an error; one with the check carries its verdict and the report's wording of it."""
    from dexaug.dashboard.catalog import result_view
    from dexaug.pipeline.summary import demo_grasp_text, demo_verdict

    old = result_view({"generated": 4, "passed": 1, "report": None}, tmp_path)
    assert old["demo_grasp"] is None and old["demo_grasp_text"].startswith("not validated")
    verdict = demo_verdict("six-dir", False, "slipped", 0.021, 0.05)
    new = result_view({"generated": 4, "passed": 1, "demo_grasp": verdict}, tmp_path)
    assert new["demo_grasp"] == verdict and new["pass_rate"] == 0.25
    assert new["demo_grasp_text"] == demo_grasp_text(verdict) == (
        "failed (slipped) — six-dir; the object moved 21.0 mm and turned 2.9° in the hand")


def test_job_queue_order_progress_and_failures() -> None:
    q = JobQueue(fake_job)
    try:
        a = q.submit("a", "job a", ("ok", 5))
        assert q.submit("a", "job a again", ("ok", 9)) is a   # a double click queues nothing
        q.submit("b", "job b", ("fail", "object 999_nothing is not installed"))
        q.submit("c", "job c", ("bug", "palm"))
        q.submit("d", "job d", ("ok", 2))
        jobs = _wait_final(q, 4)
    finally:
        q.close()
    by = {j["key"]: j for j in jobs}
    assert by["a"]["state"] == "done" and by["a"]["result"]["passed"] == 4
    assert (by["a"]["stage"], by["a"]["done"], by["a"]["total"]) == ("fsg", 5, 5)
    assert by["b"]["state"] == "failed" and by["b"]["error"] == "object 999_nothing is not installed"
    assert by["c"]["state"] == "failed" and by["c"]["error"] == "KeyError: 'palm'"
    assert by["d"]["state"] == "done"      # the queue outlives a failed job
    order = sorted(jobs, key=lambda j: j["id"])
    for before, after in itertools.pairwise(order):   # one at a time, in order
        assert after["started_at"] >= before["finished_at"]


def _sessions_dir(tmp_path: Path, *extra: Path) -> Path:
    d = tmp_path / "sessions"
    d.mkdir()
    for src in (DICE, RAW, *extra):
        shutil.copy(src, d / src.name)
    return d


def _get(url: str) -> tuple[int, Any]:
    try:
        with urllib.request.urlopen(url, timeout=SOON_S) as r:
            body = r.read()
            ctype = r.headers.get("Content-Type", "")
            return r.status, json.loads(body) if "json" in ctype else (ctype, body)
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def _last_job_in(url: str, state: str) -> list[dict[str, Any]]:
    """The dashboard's ``api/jobs`` once its last job is in ``state`` (waits SOON_S at most)."""
    def jobs() -> list[dict[str, Any]] | None:
        listed = _get(url + "api/jobs")[1]["jobs"]
        return listed if listed and listed[-1]["state"] == state else None
    return wait_for(jobs, SOON_S, f"the last job {state}", every_s=0.1)


@needs_menagerie
@needs_ycb
def test_api_lists_errors_and_survives_a_failed_job(tmp_path: Path) -> None:
    from dexaug.dashboard.server import Dashboard, DashboardConfig
    from dexaug.pipeline.options import AugmentOptions

    sessions = _sessions_dir(tmp_path)
    (sessions / "junk.mcap").write_bytes(b"not an mcap file" * 4)
    cut = DICE.read_bytes()
    (sessions / "cut.mcap").write_bytes(cut[: len(cut) // 2])
    cfg = DashboardConfig(sessions, tmp_path / "out", AugmentOptions(n=5, workers=1, gallery=0),
                          port=0)
    with Dashboard(cfg, target=fake_job) as dash:
        url = dash.start()
        status, doc = _get(url + "api/sessions")
        assert status == 200 and doc["error"] is None and doc["options"]["n"] == 5
        by = {s["name"]: s for s in doc["sessions"]}
        assert set(by) == {"cut.mcap", "demo_062_dice.mcap", "junk.mcap", RAW.name}
        assert "raw input only" in by[RAW.name]["error"] and not by[RAW.name]["demos"]
        assert "junk.mcap" in by["junk.mcap"]["error"] and "not an MCAP" in by["junk.mcap"]["error"]
        cut_s = by["cut.mcap"]
        assert cut_s["error"] or "truncated" in cut_s["warning"]   # listed, never hidden
        (dice,) = by["demo_062_dice.mcap"]["demos"]
        assert dice["object"] == "062_dice" and "thumb" in dice["fingers"] and not dice["result"]
        status, (ctype, img) = _get(url + dice["thumbnail"].lstrip("/"))
        assert status == 200 and (img.startswith(b"\x89PNG") or b"no preview" in img), ctype
        assert post_json(url + "api/augment", b"{}")[0] == 400
        assert post_json(url + "api/augment", json.dumps({"demo": "nope"}).encode())[0] == 404
        # a job that fails as the pipeline would: the message reaches the API, the server
        # goes on answering
        status, doc = post_json(url + "api/augment", json.dumps({"demo": dice["key"]}).encode())
        assert status == 200 and doc["job"]["state"] in ("queued", "running")
        jobs = _last_job_in(url, "failed")
        assert jobs[-1]["error"] == f"{dice['id']}: FSG found no grasp"
        assert _get(url + "api/sessions")[0] == 200


@needs_menagerie
@needs_ycb
@pytest.mark.timeout(240)
def test_augment_a_demo_from_the_page(chromium, tmp_path: Path) -> None:
    from dexaug.dashboard.server import Dashboard, DashboardConfig
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.summary import demo_grasp_text

    t0 = time.perf_counter()
    out = tmp_path / "out"
    # 60 grasps: validation lasts a few of the page's 0.5 s polls, so its progress is seen
    opts = AugmentOptions(n=60, workers=2, gallery=1, time_budget_s=100.0)
    cfg = DashboardConfig(_sessions_dir(tmp_path), out, opts, port=0)
    console: list[str] = []
    with Dashboard(cfg) as dash:
        url = dash.start()
        page = new_page(chromium, https=False, console=console, viewport=(1200, 900))
        page.set_default_timeout(SOON_S * 1000)   # its actions wait on the page's events
        page.goto(url)
        page.wait_for_function("() => document.body.dataset.loaded === '1'", timeout=SOON_S * 1000)
        bad = page.locator(f".session[data-session='{RAW.name}'] .session-error")
        assert "raw input only" in bad.inner_text()
        assert page.locator(f".session[data-session='{RAW.name}'] .demo").count() == 0
        row = page.locator(".session[data-session='demo_062_dice.mcap'] .demo")
        assert row.count() == 1
        assert "062_dice" in row.inner_text() and "thumb" in row.inner_text()
        key = row.get_attribute("data-key")
        # record every progress line the page shows: the progress is live, not a final flash
        page.evaluate("""() => { window.seen = new Set();
            new MutationObserver(() => document.querySelectorAll('.progress-text')
              .forEach(e => window.seen.add(e.textContent)))
            .observe(document.body, {childList: true, subtree: true, characterData: true}); }""")
        row.locator("button.augment").click()
        try:
            row.locator("a.report-link").wait_for(timeout=150_000)
        except Exception as exc:
            raise AssertionError(f"no report link; the row says {row.inner_text()!r}; "
                                 f"jobs {dash.jobs.snapshot()}") from exc
        seen = page.evaluate("() => [...window.seen]")
        assert any(s.startswith("FSG sampling") for s in seen), seen
        assert any(s.startswith("validation: ") for s in seen), seen
        shown = {c: row.locator(f".{c}").inner_text() for c in ("n-generated", "n-passed",
                                                                 "pass-rate", "demo-grasp")}
        shot = artifact_path("dashboard_augment.png")
        page.screenshot(path=str(shot), full_page=True)
        print(f"\nscreenshot: {shot}")

        summary = json.loads((out / key / "summary.json").read_text())
        table = dataset.load(summary["dataset"])["062_dice"]
        assert int(shown["n-passed"]) == summary["passed"] == len(table) > 0
        assert table["passed"].all()
        assert int(shown["n-generated"]) == summary["generated"] == len(table) + len(table.rejected)
        assert shown["pass-rate"] == f"{100 * summary['passed'] / summary['generated']:.1f} %"
        assert summary["demo_grasp"]["protocol"] == "lift-drop"
        assert shown["demo-grasp"] == demo_grasp_text(summary["demo_grasp"])
        assert shown["demo-grasp"].startswith(("passed —", "failed ("))

        href = row.locator("a.report-link").get_attribute("href")
        report = new_page(chromium, https=False)
        report.set_default_timeout(SOON_S * 1000)
        report.goto(url.rstrip("/") + href)
        assert report.locator("#m-grasps-passed-validation").inner_text() == str(len(table))
        assert report.locator("#m-demonstration-grasp").inner_text() == shown["demo-grasp"]
        assert report.locator("img[alt='palm cloud']").evaluate("e => e.naturalWidth") > 0
        report.close()
        assert not [c for c in console if c.startswith(("error", "pageerror"))], console
        # leave the page before its server stops: a poll in flight would fail (connection
        # refused), which is the restart, not a page error
        page.goto("about:blank")
        console.clear()

    with Dashboard(cfg) as again:   # a restarted dashboard shows the finished demo directly
        page.goto(again.start())
        page.wait_for_function("() => document.body.dataset.loaded === '1'", timeout=SOON_S * 1000)
        assert "earlier" in row.locator(".done-note").inner_text()
        assert row.locator(".n-passed").inner_text() == shown["n-passed"]
        assert row.locator(".demo-grasp").inner_text() == shown["demo-grasp"]
        assert row.locator("a.report-link").get_attribute("href") == href
        assert not again.jobs.snapshot()
        assert not [c for c in console if c.startswith(("error", "pageerror"))], console
        page.goto("about:blank")

    # other options (as `make demo`'s run is to the dashboard's): shown as an earlier result,
    # with the button that augments it again under the dashboard's
    other = dataclasses.replace(cfg, options=dataclasses.replace(opts, n=30))
    with Dashboard(other) as third:
        page.goto(third.start())
        page.wait_for_function("() => document.body.dataset.loaded === '1'", timeout=SOON_S * 1000)
        note = row.locator(".done-note").inner_text()
        assert "other options" in note and f"{opts.n} grasps" in note, note
        assert row.locator(".n-passed").inner_text() == shown["n-passed"]
        assert row.locator("button.augment").count() == 1
        page.goto("about:blank")
    print(f"dashboard test wall time {time.perf_counter() - t0:.1f} s")


LOADED = "() => document.body.dataset.loaded === '1'"


def _dice_row(page: Any) -> Any:
    return page.locator(".session[data-session='demo_062_dice.mcap'] .demo")


@needs_menagerie
@needs_ycb
@pytest.mark.timeout(240)
def test_put_a_result_on_an_arm_from_the_page(chromium, tmp_path: Path) -> None:
    """The dice demo augmented (6 grasps), then "Put on arm" with ur5e and 2 placements chosen on
    the page: the job runs the real arm stage, its progress counts the file's pairs, the page
    shows the file's own numbers and links it, and a restarted dashboard lists them."""
    from dexaug.dashboard.server import Dashboard, DashboardConfig
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_demo
    from teleop.record.demos import extract_demos

    t0 = time.perf_counter()
    out = tmp_path / "out"
    opts = AugmentOptions(n=6, workers=1, gallery=0)
    sessions = _sessions_dir(tmp_path)
    (demo,) = extract_demos(sessions / DICE.name)   # as the dashboard lists it: not "earlier"
    summary = augment_demo(demo, out, opts)
    assert summary.passed > 0
    cfg = DashboardConfig(sessions, out, opts, port=0)
    console: list[str] = []
    with Dashboard(cfg) as dash:
        url = dash.start()
        page = new_page(chromium, https=False, console=console, viewport=(1200, 900))
        page.set_default_timeout(SOON_S * 1000)   # its actions wait on the page's events
        page.goto(url)
        page.wait_for_function(LOADED, timeout=SOON_S * 1000)
        row = _dice_row(page)
        assert row.locator(".arm-result").count() == 0
        assert "other options" not in row.locator(".done-note").inner_text()
        assert row.locator("select.arm-name option").all_inner_texts() == ["kuka_iiwa_14", "ur5e"]
        row.locator("select.arm-name").select_option("ur5e")
        row.locator("input.arm-placements").fill("2")
        row.locator("button.arm-run").click()
        shown = row.locator(".arm-result[data-arm='ur5e']")
        try:
            shown.wait_for(timeout=120_000)
        except Exception as exc:
            raise AssertionError(f"no arm result; the row says {row.inner_text()!r}; "
                                 f"jobs {dash.jobs.snapshot()}") from exc
        path = out / row.get_attribute("data-key") / "arm_ur5e.h5"
        pairs, passed, failures = arm_file_numbers(path)
        assert pairs == 2 * summary.passed                     # the page's 2 placements
        (job,) = dash.jobs.snapshot()
        assert (job["kind"], job["state"], job["stage"], job["done"], job["total"]) == (
            "arm", "done", "arm ur5e: 062_dice", pairs, pairs)
        page_numbers = _arm_numbers(shown)
        assert page_numbers == (pairs, passed, _failure_text(failures),
                                f"{100 * passed / pairs:.1f} %")
        href = shown.locator("a.arm-file").get_attribute("href")
        with urllib.request.urlopen(url.rstrip("/") + href, timeout=SOON_S) as r:
            assert r.read() == path.read_bytes()
        shot = artifact_path("dashboard_arm.png")
        page.screenshot(path=str(shot), full_page=True)
        assert not [c for c in console if c.startswith(("error", "pageerror"))], console
        page.goto("about:blank")

    with Dashboard(cfg) as again:   # the catalog lists the arm file from disk
        page.goto(again.start())
        page.wait_for_function(LOADED, timeout=SOON_S * 1000)
        assert _arm_numbers(row.locator(".arm-result[data-arm='ur5e']")) == page_numbers
        (listed,) = _get(again.url + "api/sessions")[1]["sessions"][0]["demos"][0]["result"]["arms"]
        assert (listed["arm"], listed["placements"], listed["pairs"], listed["passed"],
                listed["failures"], listed["stale"]) == ("ur5e", 2, pairs, passed, failures, False)
        page.goto("about:blank")
    print(f"arm dashboard test wall time {time.perf_counter() - t0:.1f} s")


def _failure_text(failures: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(failures.items())) or "none"


def _arm_numbers(shown: Any) -> tuple[int, int, str, str]:
    """(pairs, passed, failures, pass share) as an arm result line of the page states them."""
    return (int(shown.locator(".arm-pairs").inner_text()),
            int(shown.locator(".arm-passed").inner_text()),
            shown.locator(".arm-failures").inner_text(), shown.locator(".arm-share").inner_text())


@needs_menagerie
@needs_ycb
def test_an_arm_jobs_progress_and_failure_show_on_the_page(chromium, tmp_path: Path) -> None:
    """A gated arm job: the page shows its stage and counts while it runs, then its error with
    the control to try again; the job got the catalog's dataset and the page's placements."""
    from dexaug.dashboard.server import Dashboard, DashboardConfig
    from dexaug.pipeline.options import AugmentOptions
    from teleop.record.demos import extract_demos

    calls: list[Any] = []
    release = threading.Event()

    def gated_arm(payload: Any, progress) -> dict[str, Any]:
        calls.append(payload)
        progress("arm ur5e: 062_dice", 2, 5)
        release.wait(HANG_S)   # the test releases it
        raise DexaugError("ur5e: the arm's model is not installed")

    cfg = DashboardConfig(_sessions_dir(tmp_path), tmp_path / "out",
                          AugmentOptions(n=5, workers=1, gallery=0), port=0)
    data = fake_result(Path(cfg.out_root).resolve(), extract_demos(DICE)[0])
    console: list[str] = []
    with Dashboard(cfg, target=fake_job, arm_target=gated_arm) as dash:
        page = new_page(chromium, https=False, console=console)
        page.set_default_timeout(SOON_S * 1000)
        page.goto(dash.start())
        page.wait_for_function(LOADED, timeout=SOON_S * 1000)
        row = _dice_row(page)
        row.locator("input.arm-placements").fill("3")
        row.locator("button.arm-run").click()
        progress = row.locator(".arm-progress-text")
        progress.filter(has_text="arm ur5e: 062_dice: 2 / 5").wait_for(timeout=SOON_S * 1000)
        assert row.locator("button.arm-run").count() == 0     # no second click while it runs
        release.set()
        error = row.locator(".arm-error")
        error.wait_for(timeout=SOON_S * 1000)
        assert error.inner_text() == ("Putting on the arm failed: ur5e: the arm's model is "
                                      "not installed")
        assert row.locator("button.arm-run").count() == 1
        (job,) = calls
        assert (job.dataset, job.arm, job.placements) == (data, "kuka_iiwa_14", 3)
        assert not [c for c in console if c.startswith(("error", "pageerror"))], console
        page.goto("about:blank")
