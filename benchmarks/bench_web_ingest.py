"""Live web ingest, measured with the emulated headset: headless Chromium + IWER (Quest 3)
replaying the real Quest 3 capture through the headset page → WebSocket (HTTPS) → web ingest
→ zenoh ``/hands``, with a bridge (view on when GL works) running as ``dexaug bridge`` would.

Reports the frames per second that reached zenoh from the emulated session and the ingest's
added latency, WebSocket message arrival → zenoh subscriber (same machine and clock: the ingest
stamps ``receive_time_s`` with ``time.time()`` on arrival), median and p99; and the in-process
part (arrival → ``put`` returned).

    .venv/bin/python benchmarks/bench_web_ingest.py [--no-bridge] [--no-view]

Needs Debian's Chromium and iwer (``make browser``). The figures go to a record as well
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/web_ingest/``).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.record import write_record
from sim.paths import SHARED_ASSETS
from tests.browser import CHROMIUM, CHROMIUM_ARGS, chromium_missing, iwer_build_dir, iwer_missing

CAPTURE_DIR = SHARED_ASSETS / "handdata" / "quest3_webxr"


def _bridge_proc(zport: int, rig: str, view: bool, seconds: float, ready: mp.Event) -> None:
    import dataclasses
    import os
    os.environ.setdefault("MUJOCO_GL", "egl")
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config
    cfg = dataclasses.replace(load_bridge_config(), view_enabled=view)
    from sim.hand.config import default_hand_name
    with Bridge(default_hand_name(), None, rig, cfg, connect_ports=(zport,)) as bridge:
        print(f"bridge: view {'on' if bridge.view_active else 'off'}", flush=True)
        ready.set()
        bridge.run(duration_s=seconds)
        print("bridge counts:", json.dumps(bridge.status()["counts"]), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-bridge", action="store_true", help="ingest only, no bridge process")
    ap.add_argument("--no-view", action="store_true", help="bridge without the /view stream")
    ap.add_argument("--from-frame", type=int, default=950)
    ap.add_argument("--to-frame", type=int, default=1711)
    args = ap.parse_args()
    why = chromium_missing() or iwer_missing()
    if why:
        sys.exit(f"cannot run: {why}")
    from playwright.sync_api import sync_playwright

    from teleop import keys
    from teleop.input.web_ingest import WebIngest, WebIngestConfig
    from teleop.messages import decode

    rig, zport = "benchweb", keys.free_tcp_port()
    ingest = WebIngest(rig, WebIngestConfig(host="127.0.0.1", port=0, dev_static={
        "iwer": iwer_build_dir(), "capture": CAPTURE_DIR}), listen_port=zport)
    ingest.start()
    proc = None
    if not args.no_bridge:
        ctx = mp.get_context("spawn")
        ready = ctx.Event()
        proc = ctx.Process(target=_bridge_proc, args=(zport, rig, not args.no_view, 60.0, ready))
        proc.start()
        ready.wait(60)
    tap = keys.open_session(connect_ports=[zport])
    arrivals: list[tuple[float, float, int]] = []
    lock = threading.Lock()

    def on(sample) -> None:
        t = time.time()
        f = decode(sample.payload.to_bytes())
        with lock:
            arrivals.append((t, f.receive_time_s, f.seq))

    sub = tap.declare_subscriber(keys.RigKeys(rig).hands, on)
    time.sleep(0.5)
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        page = browser.new_context(ignore_https_errors=True).new_page()
        page.goto(ingest.page_url(emulate="quest3", capture="/dev/capture/cap.min.js",
                                  **{"from": str(args.from_frame), "to": str(args.to_frame)}))
        page.wait_for_function("() => window.dexaug.stats.connects >= 1 && "
                               "!document.getElementById('enter').disabled", timeout=30_000)
        page.click("#enter")
        page.wait_for_function("() => window.dexaug.emulation.replay.done", timeout=120_000)
        page.evaluate("() => window.dexaug.session.end()")
        sent = page.evaluate("() => window.dexaug.stats.framesSent")
        views = page.evaluate("() => window.dexaug.stats.viewsReceived")
        browser.close()
    time.sleep(0.5)
    sub.undeclare()
    tap.close()
    istats = ingest.stats()
    ingest.close()
    if proc is not None:
        proc.join(70)
    a = np.array(arrivals)
    t_rx = a[:, 0]
    fps = (len(a) - 1) / (t_rx[-1] - t_rx[0])
    lat_ms = (a[:, 0] - a[:, 1]) * 1e3
    print(f"frames: page sent {sent}, zenoh received {len(a)}; views shown on the page {views}")
    print(f"rate from the emulated session: {fps:.1f} frames/s")
    print(f"WebSocket arrival → zenoh subscriber: median {np.median(lat_ms):.2f} ms, "
          f"p99 {np.percentile(lat_ms, 99):.2f} ms, max {lat_ms.max():.2f} ms")
    row = {"page_sent": sent, "zenoh_received": len(a), "views_shown": views, "frames_per_s": fps,
           "median_ms": float(np.median(lat_ms)), "p99_ms": float(np.percentile(lat_ms, 99)),
           "max_ms": float(lat_ms.max())}
    if "ingest_latency_ms" in istats:
        il = istats["ingest_latency_ms"]
        print(f"  of which in the ingest (parse, convert, encode, put): median "
              f"{il['median']:.2f} ms, p99 {il['p99']:.2f} ms")
        row.update(ingest_median_ms=il["median"], ingest_p99_ms=il["p99"])
    path = write_record("web_ingest", [row], summary=row,
                        config={**vars(args), "capture_dir": str(CAPTURE_DIR)})
    print(f"record: {path}")


if __name__ == "__main__":
    main()
