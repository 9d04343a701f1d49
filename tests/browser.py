"""Headless Chromium for browser tests (the headset page now, the dashboard later).

Why Debian's Chromium and not Playwright's own: ``playwright install`` downloads a browser,
which this project's machines cannot; ``make browser`` installs Debian's ``chromium`` and the
npm packages the pages need (IWER) instead, and tests skip with the reason when they are
missing. The flags keep Chromium off the network (no background services, no QUIC, no sync).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
CHROMIUM = Path(os.environ.get("DEXAUG_CHROMIUM", "/usr/bin/chromium"))
#: Where ``make browser`` installs npm packages (ignored by git, with the venv).
NODE_PREFIX = Path(os.environ.get("DEXAUG_NODE_PREFIX", REPO / ".venv" / "node"))
IWER_VERSION = "2.5.0"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync"]
ARTIFACTS = REPO / "tests" / "artifacts"


def chromium_missing() -> str | None:
    """Why a browser test cannot run here, or None."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is not installed (pip install -e '.[dev]')"
    if not (CHROMIUM.is_file() and os.access(CHROMIUM, os.X_OK)):
        return f"no Chromium at {CHROMIUM} (make browser installs Debian's chromium as root)"
    return None


def iwer_build_dir() -> Path | None:
    """The folder holding IWER's ``iwer.module.js`` (pinned :data:`IWER_VERSION`), or None."""
    d = NODE_PREFIX / "node_modules" / "iwer"
    try:
        version = json.loads((d / "package.json").read_text())["version"]
    except (OSError, ValueError, KeyError):
        return None
    build = d / "build"
    return build if version == IWER_VERSION and (build / "iwer.module.js").is_file() else None


def iwer_missing() -> str | None:
    if iwer_build_dir() is not None:
        return None
    npm = "npm" if shutil.which("npm") else "npm (not on PATH)"
    return (f"no iwer@{IWER_VERSION} under {NODE_PREFIX} (make browser runs "
            f"`{npm} install --prefix {NODE_PREFIX} iwer@{IWER_VERSION}`)")


@pytest.fixture(scope="session")
def chromium() -> Iterator[object]:
    """A Playwright Browser on Debian's Chromium (skips with the reason when unavailable)."""
    why = chromium_missing()
    if why:
        pytest.skip(why)
    from playwright.sync_api import sync_playwright
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield browser
        finally:
            browser.close()


def new_page(browser: object, *, https: bool = True, console: list[str] | None = None,
             viewport: tuple[int, int] = (1024, 768)) -> object:
    """A page in a fresh context (own storage; self-signed certificates accepted when
    ``https``); browser console lines and page errors are appended to ``console``."""
    ctx = browser.new_context(ignore_https_errors=https,  # type: ignore[attr-defined]
                              viewport={"width": viewport[0], "height": viewport[1]})
    page = ctx.new_page()
    if console is not None:
        page.on("console", lambda m: console.append(f"{m.type}: {m.text}"))
        page.on("pageerror", lambda e: console.append(f"pageerror: {e}"))
    return page


def artifact_path(name: str) -> Path:
    """``tests/artifacts/<name>`` (created; ignored by git) for screenshots and logs."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return ARTIFACTS / name


def chromium_version() -> str:
    """Chromium's version line (for reports)."""
    try:
        return subprocess.run([str(CHROMIUM), "--version"], capture_output=True, text=True,
                              timeout=20).stdout.strip()
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"unknown ({exc})"
