"""End-to-end bridge latency on loopback: a ``/hands`` sample published → the ``/state`` sample
that answers it (matched on ``seq``) received, with the view stream on at 30 Hz when GL works.

The bridge runs in its own process (as ``dexaug bridge`` would), the operator side (publisher at
90 Hz, replaying the real Quest 3 capture in a loop with fresh sequence numbers, and the state
subscriber) in this one; both are zenoh peers on 127.0.0.1 with multicast scouting off.
Target: median ≤ 5 ms. The figures go to a record as well (:func:`benchmarks.record.write_record`,
``benchmarks/measured/bridge/``).

    .venv/bin/python benchmarks/bench_bridge.py [--seconds 10] [--rate-hz 90] [--no-view]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
from sim.paths import SHARED_ASSETS

CAPTURE = SHARED_ASSETS / "handdata" / "quest3_webxr" / "cap.min.js"


def _bridge_proc(port: int, rig: str, view: bool, seconds: float, ready: mp.Event) -> None:
    os.environ.setdefault("MUJOCO_GL", "egl")
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config
    from teleop.input.iwer import iwer_hand_frames, load_iwer_capture
    frames = iwer_hand_frames(load_iwer_capture(CAPTURE))
    cfg = dataclasses.replace(load_bridge_config(), view_enabled=view, view_rate_hz=30.0)
    from sim.hand.config import default_hand_name
    with Bridge(default_hand_name(), None, rig, cfg, listen_port=port,
                calibration_frames=frames) as bridge:
        print(f"bridge: view {'on' if bridge.view_active else 'off'}", flush=True)
        ready.set()
        bridge.run(duration_s=seconds)
        print("bridge status:", json.dumps(bridge.status()["counts"]), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rate-hz", type=float, default=90.0)
    ap.add_argument("--no-view", action="store_true")
    args = ap.parse_args()

    from teleop import keys
    from teleop.input.iwer import iwer_hand_frames, load_iwer_capture
    from teleop.messages import encode

    frames = [f for f in iwer_hand_frames(load_iwer_capture(CAPTURE)) if f.right is not None]
    port, rig = keys.free_tcp_port(), "bench"
    ctx = mp.get_context("spawn")
    ready = ctx.Event()
    proc = ctx.Process(target=_bridge_proc,
                       args=(port, rig, not args.no_view, args.seconds + 8.0, ready))
    proc.start()
    if not ready.wait(60):
        raise SystemExit("bridge did not start")
    k = keys.RigKeys(rig)
    session = keys.open_session(connect_ports=[port])
    sent: dict[int, float] = {}
    got: dict[int, float] = {}
    views = [0]
    lock = threading.Lock()

    def on_state(sample) -> None:
        t = time.perf_counter()
        seq = json.loads(sample.payload.to_bytes())["seq"]
        with lock:
            if seq is not None and seq not in got:
                got[seq] = t

    def on_view(sample) -> None:
        views[0] += 1

    session.declare_subscriber(k.state, on_state)
    session.declare_subscriber(k.view, on_view)
    pub = session.declare_publisher(k.hands)
    while not pub.matching_status.matching:
        time.sleep(0.01)
    time.sleep(0.5)
    period = 1.0 / args.rate_hz
    n = int(args.seconds * args.rate_hz)
    t0 = time.perf_counter()
    for i in range(n):
        f = frames[i % len(frames)]
        f = dataclasses.replace(f, seq=i, device_time_s=i * period)
        payload = encode(f)
        target = t0 + i * period
        while (now := time.perf_counter()) < target:
            time.sleep(min(0.001, target - now))
        sent[i] = time.perf_counter()
        pub.put(payload)
    time.sleep(0.5)
    session.close()
    proc.join(20)
    if proc.is_alive():
        proc.terminate()
    lat = np.array([got[s] - sent[s] for s in sent if s in got]) * 1e3
    warm = lat[int(args.rate_hz):] if len(lat) > args.rate_hz else lat  # skip the first second
    print(f"frames sent {n}, answered {len(lat)} ({len(lat) / n:.1%}), view frames {views[0]} "
          f"({views[0] / args.seconds:.1f} Hz)")
    print(f"latency /hands → /state: median {np.median(warm):.2f} ms, "
          f"p99 {np.percentile(warm, 99):.2f} ms, max {warm.max():.2f} ms (target median ≤ 5 ms)")
    row = {"sent": n, "answered": len(lat), "view_frames": views[0],
           "view_hz": views[0] / args.seconds, "median_ms": float(np.median(warm)),
           "p99_ms": float(np.percentile(warm, 99)), "max_ms": float(warm.max()),
           "warm_up_skipped": len(lat) - len(warm)}
    path = write_record("bridge", [row], summary=row,
                        config={**vars(args), "capture": str(CAPTURE), "view": not args.no_view})
    print(f"record: {path}")


if __name__ == "__main__":
    main()
