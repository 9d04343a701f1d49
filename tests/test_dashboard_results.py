"""The dashboard's settings (n, table mode, protocol) and its list of every result folder (#16).

Real server, real files: the settings a POST sets are the ones a queued job runs with, bad
values are refused naming the field, a refused request changes nothing; the results list finds
a result nested below the output folder (``make demo``'s, another ``--out``), links its viewer
only when the file is there, lists a broken summary with its reason and never shows a
file-system path. In headless Chromium the form sends what is typed and the table shows the
results.
"""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest

from dexaug.dashboard.server import Dashboard, DashboardConfig
from dexaug.pipeline.options import AugmentOptions
from tests.browser import artifact_path, new_page
from tests.conftest import SOON_S
from tests.dashboard_http import post_json
from tests.test_dashboard import _get, _last_job_in, _sessions_dir

pytestmark = pytest.mark.slow


def _summary(folder: Path, demo: str, generated: int, passed: int) -> None:
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps(
        {"demo_id": demo, "object": "062_dice", "hand": "shadow_right", "generated": generated,
         "passed": passed}))
    (folder / "report.html").write_text("<html></html>")


def _results_root(root: Path) -> Path:
    _summary(root / "demo" / "keyframes@062", "keyframes@062", 10, 7)   # make demo's layout
    (root / "demo" / "keyframes@062" / "viewer.html").write_text("<html></html>")
    _summary(root / "a" / "b" / "c" / "deep", "deep", 4, 0)
    _summary(root / "a" / "b" / "c" / "d" / "e" / "too_deep", "too deep", 1, 1)
    _summary(root / ".thumbnails" / "hidden", "hidden", 1, 1)
    (root / "broken").mkdir()
    (root / "broken" / "summary.json").write_text("{not json")
    (root / "dangling").mkdir()   # a summary that is a broken link: its error names no path
    (root / "dangling" / "summary.json").symlink_to(root / "gone" / "summary.json")
    return root


def _dashboard(tmp_path: Path, **opts: object) -> Dashboard:
    cfg = DashboardConfig(_sessions_dir(tmp_path), _results_root(tmp_path / "out"),
                          AugmentOptions(n=5, workers=1, gallery=0, **opts), port=0)  # type: ignore[arg-type]
    return Dashboard(cfg, target=lambda payload, progress: {"generated": payload[2].n,
                                                            "passed": 0, "report": None})


def test_settings_round_trip_and_bad_values_are_refused(tmp_path: Path) -> None:
    with _dashboard(tmp_path) as dash:
        url = dash.start()
        st = _get(url + "api/sessions")[1]["options"]["settings"]
        assert st == {"n": 5, "n_max": 5000, "validate": "lift-drop",
                      "protocols": ["lift-drop", "six-dir", "dgb", "none"], "table": "demo",
                      "tables": ["demo", "on", "off"]}
        status, doc = post_json(url + "api/settings",
                            json.dumps({"n": 37, "table": "on", "validate": "dgb"}).encode())
        assert status == 200 and doc["options"]["settings"]["n"] == 37
        assert dash.config.options.n == 37 and dash.config.options.table is True
        assert dash.config.options.validate == "dgb" and dash.catalog.opts.n == 37
        for body, field in (({"n": 0}, "'n'"), ({"n": "7"}, "'n'"), ({"n": True}, "'n'"),
                            ({"n": 5001}, "'n'"), ({"table": True}, "'table'"),
                            ({"table": []}, "'table'"), ({"table": {}}, "'table'"),
                            ({"validate": ["dgb"]}, "'validate'"),
                            ({"validate": "shake"}, "'validate'"), ({"gallery": 3}, "gallery"),
                            ([1], "JSON object")):
            status, doc = post_json(url + "api/settings", json.dumps(body).encode())
            assert status == 400 and field in doc["error"] and "\n" not in doc["error"], body
        assert post_json(url + "api/settings", b"{oops")[0] == 400
        assert dash.config.options.n == 37   # nothing changed by the refusals
        status, doc = post_json(url + "api/settings", json.dumps({"validate": "none"}).encode())
        assert status == 200 and dash.config.options.validate is None
        # a job queued now runs with the settings of now
        (dice,) = [d for s in _get(url + "api/sessions")[1]["sessions"] for d in s["demos"]]
        job = post_json(url + "api/augment", json.dumps({"demo": dice["key"]}).encode())[1]["job"]
        jobs = _last_job_in(url, "done")
        assert job["key"] == dice["key"] and jobs[-1]["result"]["generated"] == 37


def test_settings_need_the_pages_header(tmp_path: Path) -> None:
    with _dashboard(tmp_path) as dash:
        url = dash.start()
        req = urllib.request.Request(url + "api/settings", json.dumps({"n": 9}).encode(),
                                     {"Content-Type": "application/json"})
        try:
            urllib.request.urlopen(req, timeout=SOON_S)
            raise AssertionError("a POST without X-Dexaug was accepted")
        except urllib.error.HTTPError as exc:
            assert exc.code == 403
        assert dash.config.options.n == 5


def test_every_result_folder_is_listed_without_paths(tmp_path: Path) -> None:
    with _dashboard(tmp_path) as dash:
        url = dash.start()
        status, doc = _get(url + "api/results")
        assert status == 200
        by = {r["folder"]: r for r in doc["results"]}
        assert set(by) == {"demo/keyframes@062", "a/b/c/deep", "broken", "dangling"}
        made = by["demo/keyframes@062"]
        assert (made["generated"], made["passed"], made["pass_rate"]) == (10, 7, 0.7)
        assert made["viewer"] == "/results/demo/keyframes%40062/viewer.html"
        assert made["report"] == "/results/demo/keyframes%40062/report.html"
        assert by["a/b/c/deep"]["viewer"] is None and by["a/b/c/deep"]["pass_rate"] == 0.0
        assert "unreadable" in by["broken"]["error"] and "\n" not in by["broken"]["error"]
        assert "FileNotFoundError" in by["dangling"]["error"]
        assert str(tmp_path) not in json.dumps(doc)
        assert _get(url + made["viewer"].lstrip("/"))[0] == 200   # the link is served


def test_the_page_sends_its_settings_and_lists_the_results(chromium, tmp_path: Path) -> None:
    console: list[str] = []
    with _dashboard(tmp_path) as dash:
        page = new_page(chromium, https=False, console=console, viewport=(1200, 900))
        page.set_default_timeout(SOON_S * 1000)   # its waits end on the page's events
        page.goto(dash.start())
        page.wait_for_selector("body[data-loaded='1']", timeout=SOON_S * 1000)
        assert page.input_value("#set-n") == "5" and page.input_value("#set-table") == "demo"
        page.fill("#set-n", "120")
        page.select_option("#set-table", "off")
        page.select_option("#set-validate", "six-dir")
        page.click("#set-apply")
        page.wait_for_function("document.getElementById('options').textContent.includes('n 120')")
        assert (dash.config.options.n, dash.config.options.table,
                dash.config.options.validate) == (120, False, "six-dir")
        page.fill("#set-n", "0")
        page.click("#set-apply")
        page.wait_for_selector("#message.error")
        assert "'n'" in page.text_content("#message") and dash.config.options.n == 120
        rows = page.locator("#results tbody tr")
        assert rows.count() == 4   # incl. the broken and the dangling summary
        row = page.locator("#results tr[data-folder='demo/keyframes@062']")
        assert "70.0 %" in row.text_content() and row.locator("a", has_text="3D view").count() == 1
        page.screenshot(path=str(artifact_path("dashboard_settings_results.png")), full_page=True)
    assert not [c for c in console if c.startswith("pageerror")], console
