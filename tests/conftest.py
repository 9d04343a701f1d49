"""Shared fixtures: assets resolve from ../shared/assets (or the env variables), and tests that
need them skip cleanly where they are absent."""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from sim.paths import SHARED_ASSETS, ensure_menagerie_root, ycb_root
from tests.browser import chromium  # noqa: F401  (one session-wide browser for every module)


def _menagerie_available() -> bool:
    root = ensure_menagerie_root()
    return root is not None and (root / "shadow_hand").is_dir()


T = TypeVar("T")
_REPO = Path(__file__).resolve().parents[1]

#: how long a test waits for an event a quiet machine sees within about a second (a reply, a
#: zenoh route, a frame, a child's start): generous for a 2-core machine at load 4, and no cost
#: when the event comes, since every wait ends on the event itself
SOON_S = 60.0
#: how long a whole child command (a CLI run, a recorder or bridge in its own process) may take
#: before a test calls it hung: only a hang guard, for runs a quiet machine ends in seconds
HANG_S = 300.0


def run_dexaug(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``python -m dexaug ARGS`` as a user runs it (its own process, no stdin, rendering on EGL
    unless the caller chose), finished; bounded by :data:`HANG_S` only to catch a hang."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    return subprocess.run([sys.executable, "-m", "dexaug", *args], cwd=cwd or _REPO, env=env,
                          text=True, capture_output=True, timeout=HANG_S, stdin=subprocess.DEVNULL)


def sigint_as_a_terminal_gives_it() -> None:
    """``preexec_fn`` of a child a test stops with SIGINT (Ctrl-C): SIGINT at its default, as a
    terminal's foreground command has it. A suite started as a background job of a
    non-interactive shell inherits SIGINT ignored (POSIX), Python then keeps ignoring it, and
    the child would never see the Ctrl-C the test sends."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def wait_for(check: Callable[[], T], limit_s: float, what: str | Callable[[], str], *,
             every_s: float = 0.02, unless: Callable[[], str | None] | None = None) -> T:
    """Poll ``check()`` until it returns something truthy, and return that.

    Waits on the event, not on a guess of how long it takes: ``limit_s`` only bounds a wait
    for an event that never comes, so make it generous (many times the quiet-machine time).
    Raises AssertionError naming ``what`` (a text, or a callable giving one at the failure,
    e.g. with the counts seen) after ``limit_s`` seconds, or at once when ``unless()`` returns
    a reason to stop waiting (e.g. "the process exited with status 1")."""
    t_end = time.monotonic() + limit_s
    while True:
        got = check()
        if got:
            return got
        why = unless() if unless is not None else None
        if why or time.monotonic() > t_end:
            text = what() if callable(what) else what
            raise AssertionError(f"waited for {text}: {why}" if why
                                 else f"waited {limit_s:g} s for {text} in vain")
        time.sleep(every_s)


def wait_for_match(entity: object, limit_s: float, what: str) -> None:
    """Wait until a zenoh publisher (or querier) matches a subscriber (a queryable): the
    route between two peers exists, so what is put (or asked) next is not sent into the void."""
    wait_for(lambda: entity.matching_status.matching, limit_s,  # type: ignore[attr-defined]
             what, every_s=0.005)


def wait_for_queryable(session: object, key: str, limit_s: float, what: str) -> None:
    """Wait until ``session`` knows a queryable answering ``key`` (its querier matches), with
    no query sent: nothing is asked of the queryable, so its calls stay the test's own."""
    querier = session.declare_querier(key)  # type: ignore[attr-defined]
    try:
        wait_for_match(querier, limit_s, what)
    finally:
        querier.undeclare()


needs_menagerie = pytest.mark.skipif(not _menagerie_available(),
                                     reason=f"no Menagerie models (MENAGERIE_ROOT or {SHARED_ASSETS})")
needs_ycb = pytest.mark.skipif(ycb_root(required=False) is None,
                               reason=f"no YCB objects (DEXAUG_YCB_ROOT or {SHARED_ASSETS}/ycb)")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test that uses the headless browser (the ``chromium`` fixture, directly or
    through another fixture) ``browser``, so ``make test-fast`` can leave it out without each
    module having to remember the marker."""
    for item in items:
        if "chromium" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.browser)


@pytest.fixture(scope="session")
def shadow():
    from sim.hand.model import Hand

    if not _menagerie_available():
        pytest.skip("no Menagerie models")
    return Hand.load("shadow_right")


def without_grip_boost(config):
    """``config`` (a ValidateConfig) with the squeeze's grip boost off (``max_grip_safety`` =
    ``grip_safety``): for tests of how the grip is sized before the boost scales it."""
    return dataclasses.replace(config, common=dataclasses.replace(
        config.common, max_grip_safety=config.common.grip_safety))


def without_settled_modes(config):
    """``config`` (a ValidateConfig) with the ``dgb`` pregrasp's free modes left at the
    grasp's split (``[dgb] settle_free_modes`` off): for tests of the benchmark's squeeze
    mechanisms measured before the settling, and of the settling itself."""
    return dataclasses.replace(config, dgb=dataclasses.replace(config.dgb,
                                                               settle_free_modes=False))


def without_rehearsal(config):
    """``config`` (a ValidateConfig) with the ``dgb`` closing not rehearsed (``[dgb]
    rehearse_closing`` off): for tests of the targets' own mechanisms measured before the
    rehearsal chose among them (sim.validate.rehearsal)."""
    return dataclasses.replace(config, dgb=dataclasses.replace(config.dgb, rehearse_closing=False))


def without_drift_correction(config):
    """``config`` (a ValidateConfig) with the rehearsed ``dgb`` squeeze not corrected for its
    closing's drift (``[dgb] rehearsal_drift_corrections = 0``): for tests of mechanisms
    measured before the correction moved the squeeze (sim.validate.rehearsal)."""
    return dataclasses.replace(config, dgb=dataclasses.replace(config.dgb,
                                                               rehearsal_drift_corrections=0))
