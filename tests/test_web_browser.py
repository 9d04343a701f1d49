"""The headset page in headless Chromium with IWER emulating a Quest 3, replaying the real Quest 3
capture, against a real Bridge (MuJoCo, /view when GL works) and the real web ingest (HTTPS
with its self-signed certificate, WebSocket, zenoh on loopback with scouting off).

What is checked is content, not that a page loaded: every hand frame the page sent reached zenoh
``/hands``; its joints equal the capture's (converted by the project's own converters, and the
derived reference-space file) to 1 mm; the bridge processed them; the page decoded view JPEGs
from the bridge and showed state; bad input (no hand tracking, no immersive VR, a second
headset, a lost WebSocket) gives a visible message on the page and a log line, never a crash.
A screenshot of the emulated headset view goes to ``tests/artifacts/``.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time

import numpy as np
import pytest

from sim.paths import SHARED_ASSETS
from teleop import keys
from teleop.messages import decode
from tests.browser import artifact_path, iwer_build_dir, iwer_missing, new_page
from tests.conftest import SOON_S, wait_for

CAPTURE_DIR = SHARED_ASSETS / "handdata" / "quest3_webxr"
CAPTURE = CAPTURE_DIR / "cap.min.js"
DERIVED = CAPTURE_DIR / "derived" / "quest3_hands_world.npz"
FIRST, LAST = 950, 1711  # the capture's hand-tracking segment is rows 955–1711
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not CAPTURE.is_file(), reason=f"no hand capture {CAPTURE}"),
              pytest.mark.timeout(180)]


def _ingest(rig: str, **kw):
    from teleop.input.web_ingest import WebIngest, WebIngestConfig
    why = iwer_missing()
    if why:
        pytest.skip(why)
    zport = keys.free_tcp_port()
    cfg = WebIngestConfig(host="127.0.0.1", port=kw.pop("port", 0), **kw,
                          dev_static={"iwer": iwer_build_dir(), "capture": CAPTURE_DIR})
    ingest = WebIngest(rig, cfg, listen_port=zport)
    ingest.start()
    return ingest, zport


class _HandsTap:
    """A zenoh subscriber on ``/hands`` keeping (arrival wall time, decoded frame)."""

    def __init__(self, zport: int, rig: str) -> None:
        self.session = keys.open_session(connect_ports=[zport])
        self.frames: list[tuple[float, object]] = []
        self._lock = threading.Lock()
        self.sub = self.session.declare_subscriber(keys.RigKeys(rig).hands, self._on)

    def _on(self, sample) -> None:
        t = time.time()
        f = decode(sample.payload.to_bytes())
        with self._lock:
            self.frames.append((t, f))

    def close(self) -> None:
        self.sub.undeclare()
        self.session.close()


def _js(page, expr: str):
    return page.evaluate(f"() => {expr}")


def _wait(page, expr: str, timeout_s: float, what: str) -> None:
    try:
        page.wait_for_function(f"() => {expr}", timeout=timeout_s * 1000)
    except Exception as exc:
        msg = _js(page, "document.getElementById('message').textContent")
        raise AssertionError(f"{what} (page says {msg!r}): {exc}") from None


@pytest.fixture(scope="module")
def capture_frames():
    from teleop.input.iwer import iwer_hand_frames, load_iwer_capture
    return {f.seq: f for f in iwer_hand_frames(load_iwer_capture(CAPTURE))}


def test_quest3_replay_reaches_the_bridge_and_the_view_comes_back(chromium, capture_frames,
                                                                   shadow, caplog):
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config
    caplog.set_level(logging.INFO, logger="teleop.input.web_ingest")
    t_start = time.perf_counter()
    rig = "webq3"
    ingest, zport = _ingest(rig)
    cfg = dataclasses.replace(load_bridge_config(), view_rate_hz=20.0)
    bridge = Bridge("shadow_right", None, rig, cfg, connect_ports=(zport,),
                    calibration_frames=list(capture_frames.values()))
    bridge.start()
    tap = _HandsTap(zport, rig)
    console: list[str] = []
    page = new_page(chromium, console=console)
    try:
        page.goto(ingest.page_url(emulate="quest3", capture="/dev/capture/cap.min.js",
                                  **{"from": str(FIRST), "to": str(LAST)}))
        _wait(page, "window.dexaug.stats.connects >= 1 && !document.getElementById('enter')"
              ".disabled", 30, "page never connected / offered VR")
        page.click("#enter")
        _wait(page, "window.dexaug.emulation.replay.done", 60, "the replay did not finish")
        shot = artifact_path("web_quest3_replay.png")  # the emulated headset's view: the panel
        page.screenshot(path=str(shot))
        print(f"\nscreenshot: {shot}")
        page.evaluate("() => window.dexaug.session.end()")
        _wait(page, "!window.dexaug.stats.sessionActive", 10, "the session did not end")
        n_sent = _js(page, "window.dexaug.stats.framesSent")
        wait_for(lambda: len(tap.frames) >= n_sent, SOON_S,
                 lambda: f"{n_sent} frames at the zenoh tap (got {len(tap.frames)})")
        img_w = 0
        if bridge.view_active:
            _wait(page, "window.dexaug.stats.viewsReceived >= 10", 10, "too few view frames")
            # read the width in the same poll that finds it decoded: every new frame replaces
            # the <img> source, and until it decodes the width reads 0
            img_w = page.wait_for_function(
                "() => document.getElementById('view').naturalWidth || false",
                timeout=10_000).json_value()
        stats = _js(page, "window.dexaug.stats")
        grip = page.inner_text("#grip")
        log = _js(page, "window.dexaug.emulation.replay.log")
        bstatus = bridge.status()
        istats = ingest.stats()
    finally:
        page.context.close()
        tap.close()
        bridge.close()
        ingest.close()
    wall_s = time.perf_counter() - t_start

    # --- every frame the page sent arrived on zenoh, in order, at the emulated session's rate
    received = [f for _, f in tap.frames]
    missing = sorted(set(range(1, max(f.seq for f in received) + 1)) - {f.seq for f in received})
    assert len(received) == n_sent == stats["framesSent"], (len(received), n_sent, istats,
                                                            missing[:20], bstatus["counts"])
    seqs = [f.seq for f in received]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    with_hands = [f for f in received if f.left is not None or f.right is not None]
    assert len(log) >= (LAST - FIRST) * 0.95
    t = np.array([tr for tr, f in tap.frames if f.seq in dict(log)])
    fps = (len(t) - 1) / (t[-1] - t[0])
    assert fps > 30.0, f"only {fps:.1f} frames/s from the emulated session"
    assert all(f.source == "webxr" for f in received)

    # --- joint poses equal the capture's after the frame conversion (1 mm; rounding 1e-3)
    by_seq = {f.seq: f for f in received}
    derived = np.load(DERIVED)
    from teleop.input.frames import xr_to_mujoco_positions
    from teleop.input.webxr import WEBXR_JOINTS
    assert list(derived["joint_names"]) == list(WEBXR_JOINTS)
    errs, quat_dots, errs_derived, n_hands = [], [], [], 0
    def expected(row: int, side: str):
        """What IWER's ActionPlayer shows at a recorded row (stepFrames, alpha 0): an input is
        active when the *next* row has it, posed by this row's data if it has the input, else
        by the next row's."""
        nxt, cur = capture_frames.get(row + 1), capture_frames.get(row)
        if nxt is None or nxt.hand(side) is None:
            return None, None
        src = cur if cur is not None and cur.hand(side) is not None else nxt
        return src.hand(side), src

    for seq, row in log:
        got = by_seq.get(seq)
        if got is None or row + 1 > LAST:
            continue
        for side in ("left", "right"):
            g, (w, src) = got.hand(side), expected(row, side)
            assert (g is None) == (w is None), (seq, row, side)
            if g is None:
                continue
            k = int(np.searchsorted(derived["t_s"], src.device_time_s - 1e-6))
            n_hands += 1
            np.testing.assert_array_equal(g.valid, w.valid)
            v = w.valid
            errs.append(np.abs(g.positions[v] - w.positions[v]).max())
            quat_dots.append(np.abs(np.sum(g.orientations_wxyz[v] * w.orientations_wxyz[v],
                                           axis=1)).min())
            np.testing.assert_allclose(g.radii[v], w.radii[v], atol=1e-6)
            ref = xr_to_mujoco_positions(derived[f"{side}_joint_pos"][k])
            errs_derived.append(np.abs(g.positions[1:] - ref).max())
    assert n_hands > 1.5 * (LAST - FIRST) * 0.9, n_hands
    errs, errs_derived = np.array(errs), np.array(errs_derived)
    print(f"joint position error vs capture: median {np.median(errs) * 1e3:.3f} mm, max "
          f"{errs.max() * 1e3:.3f} mm; vs derived npz max {errs_derived.max() * 1e3:.3f} mm; "
          f"min |q·q'| {min(quat_dots):.6f}; {fps:.1f} frames/s; {len(with_hands)} frames "
          f"with hands; test wall {wall_s:.1f} s")
    assert errs.max() < 1.0e-3
    assert errs_derived.max() < 1.0e-3
    assert min(quat_dots) > 0.9995

    # --- the bridge processed them; the page got state, status and view frames
    assert bstatus["counts"]["accepted"] == len(received)
    assert bstatus["counts"].get("malformed", 0) == 0
    assert stats["state"] is not None and stats["status"]["bridge"] is True
    assert {"grasp_stable", "grasp_held_s", "assist"} <= set(stats["state"])   # the grasp cue
    assert grip.startswith("grip:"), grip
    if not bstatus["view"]:
        pytest.skip("no OpenGL: hands checked, the /view half of the test could not run")
    assert stats["viewsReceived"] >= 10, stats["viewsReceived"]
    assert img_w == cfg.view_width
    assert stats["lastViewSize"] == [cfg.view_width, cfg.view_height]
    assert not [c for c in console if c.startswith("pageerror")], console
    assert any("headset connected" in r.message for r in caplog.records)


def test_a_browser_without_hand_tracking_says_so(chromium, caplog):
    caplog.set_level(logging.INFO, logger="teleop.input.web_ingest")
    ingest, _ = _ingest("webnohands")
    page = new_page(chromium)
    try:
        page.goto(ingest.page_url(emulate="quest3-nohands"))
        _wait(page, "window.dexaug.stats.connects >= 1 && !document.getElementById('enter')"
              ".disabled", 30, "page never connected")
        page.click("#enter")
        _wait(page, "document.getElementById('message').textContent.includes('Hand tracking "
              "is not available')", 15, "no hand-tracking message")
        _wait(page, "window.dexaug.stats.xrFrames > 10", 15, "the session did not run")
    finally:
        page.context.close()
        ingest.close()
    assert any("Hand tracking is not available" in r.message for r in caplog.records)


def test_no_immersive_vr_and_a_second_headset_are_refused_visibly(chromium, caplog):
    caplog.set_level(logging.INFO, logger="teleop.input.web_ingest")
    ingest, _ = _ingest("webtwo")
    first, second = new_page(chromium), new_page(chromium)
    try:
        # plain headless Chromium has navigator.xr but no headset: a clear message, no crash
        first.goto(ingest.url)
        _wait(first, "document.getElementById('message').textContent.includes('cannot start "
              "an immersive VR session')", 20, "no message about immersive VR")
        _wait(first, "window.dexaug.stats.connects >= 1", 20, "first page not connected")
        second.goto(ingest.url)
        _wait(second, "document.getElementById('message').textContent.includes('Refused')",
              20, "the second headset was not refused visibly")
        assert "another headset" in _js(second, "window.dexaug.stats.refused")
        assert _js(first, "window.dexaug.stats.connects") == 1
        assert ingest.stats()["connected"]
    finally:
        first.context.close()
        second.context.close()
        ingest.close()
    messages = [r.message for r in caplog.records]
    assert any("refused a second headset" in m for m in messages)
    assert any("immersive-vr unsupported" in m for m in messages)


def test_a_lost_websocket_shows_reconnecting_and_recovers(chromium, caplog):
    caplog.set_level(logging.INFO, logger="teleop.input.web_ingest")
    ingest, _ = _ingest("weblost")
    port = ingest.port
    page = new_page(chromium)
    try:
        page.goto(ingest.page_url(emulate="quest3"))
        _wait(page, "window.dexaug.stats.connects >= 1", 20, "page not connected")
        ingest.close()  # the bridge side goes away
        _wait(page, "document.getElementById('message').textContent.includes('Disconnected, "
              "reconnecting')", 15, "no reconnecting message")
        ingest, _ = _ingest("weblost", port=port)  # and comes back on the same port
        _wait(page, "window.dexaug.stats.connects >= 2", 20, "the page did not reconnect")
        assert "Connected" in _js(page, "document.getElementById('message').textContent")
    finally:
        page.context.close()
        ingest.close()
    assert sum("headset connected" in r.message for r in caplog.records) == 2
