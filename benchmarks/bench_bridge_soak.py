"""Bridge soak: a real zenoh operator peer streaming hand tracking at 90 Hz into a real Bridge
for minutes, with dropouts, NaN frames and reconnects, recorded to MCAP and read back.

The bridge runs in its own process (as ``dexaug bridge`` would), live (``deterministic`` off,
the default: the loop steps physics on the wall clock and answers the latest frame, as on the
rig; ``--deterministic`` queues every frame instead), view off, recording to an MCAP file for
the whole run. This process is the operator: it replays the synthetic operator's ``/hands``
(``recordings/synth_005_tomato_soup_can.mcap``, looped, fresh ``seq`` and device times) at 90 Hz
of wall time, so the simulated duration ``--sim-s`` (default 600 s) is also the streaming time,
and injects, on a seeded schedule:

* dropouts: gaps of 0.2–2 s in which the frames due are not sent (``seq`` goes on: the bridge
  sees the jump, as after a lost Wi-Fi burst);
* NaN frames: bursts of lost-hand frames (every joint NaN and marked invalid: the retargeter
  must hold the last output, counted in its ``held`` counts) and single frames with a NaN in a
  joint marked valid (the bridge must refuse them as malformed);
* reconnects: the publisher's zenoh session is closed and a new one opened ``--reconnects``
  times (the frames due meanwhile are lost, like a dropout).

Latency: a frame's publish time (``perf_counter`` here) to the arrival here of the first
``/state`` naming its ``seq`` (the bridge's state carries the ``seq`` of the frame it answered),
one clock, on loopback. In live mode a frame superseded before the loop took it is never
answered; those are counted, not timed. At the end the bridge stops recording and the file is
read back to its last chunk (:func:`teleop.record.session.open_session`): it must not be
truncated, and its ``/hands`` count must equal the frames the bridge accepted.

    .venv/bin/python benchmarks/bench_bridge_soak.py [--sim-s 600] [--reconnects 4]
        [--deterministic] [--seed 0] [--out DIR]

Writes a record (:func:`benchmarks.record.write_record`, ``benchmarks/measured/bridge_soak/``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import multiprocessing as mp
import os
import struct
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.record import write_record
from sim.paths import REPO_ROOT

SOURCE = REPO_ROOT / "recordings" / "synth_005_tomato_soup_can.mcap"
RATE_HZ = 90.0
#: a frame more than this many periods behind its slot is skipped (a loaded machine must not
#: make the operator burst: the stream keeps wall time, as a headset does)
LATE_PERIODS = 3


def _bridge_proc(port: int, rig: str, rec: str, deterministic: bool, ready: Any, stop: Any,
                 out: Any) -> None:
    os.environ.setdefault("MUJOCO_GL", "egl")
    from sim.hand.config import default_hand_name
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config
    from teleop.record.session import open_session

    calib = [f for _, f in open_session(SOURCE).hands()]
    cfg = dataclasses.replace(load_bridge_config(), view_enabled=False,
                              deterministic=deterministic)
    with Bridge(default_hand_name(), None, rig, cfg, listen_port=port,
                calibration_frames=calib) as bridge:
        started = bridge.control("start_recording", {"path": rec, "overwrite": True})
        if not started["ok"]:
            out.put({"error": started["error"]})
            ready.set()
            return
        ready.set()
        t0 = time.perf_counter()
        thread = bridge.start()
        stop.wait()
        bridge.stop()
        thread.join(30)
        stopped = bridge.control("stop_recording", {"reason": "soak end"})
        st = bridge.status()
        out.put({"stop": stopped, "counts": st["counts"], "held": st["held"],
                 "sim_time_s": st["sim_time_s"], "wall_s": time.perf_counter() - t0})


def _nan_valid(frame: Any) -> bytes:
    """``frame`` encoded with a NaN in the wrist position, still marked valid (malformed)."""
    from teleop.messages import JOINT_INDEX, encode

    f = dataclasses.replace(frame, left=None)
    buf = bytearray(encode(f))
    struct.pack_into("<f", buf, 64 + len(f.source.encode()) + 12 * JOINT_INDEX["wrist"],
                     float("nan"))
    return bytes(buf)


def _schedule(n: int, reconnects: int, rng: np.random.Generator) -> tuple[np.ndarray, set[int]]:
    """Per frame slot: 0 send, 1 dropout (not sent), 2 lost hand (NaN, invalid), 3 NaN in a
    valid joint; and the slots at which the publisher reconnects."""
    kind = np.zeros(n, np.int8)
    i = int(5 * RATE_HZ)                              # 5 s of clean stream first
    while i < n:
        i += int(rng.uniform(8, 25) * RATE_HZ)        # a dropout every 8–25 s
        kind[i:i + int(rng.uniform(0.2, 2.0) * RATE_HZ)] = 1
    i = int(7 * RATE_HZ)
    while i < n:
        i += int(rng.uniform(4, 10) * RATE_HZ)        # NaN frames every 4–10 s
        if i < n and kind[i] == 0:
            burst = int(rng.integers(1, 30))
            kind[i:i + burst][kind[i:i + burst] == 0] = 2
            if i + burst < n and kind[i + burst] == 0:
                kind[i + burst] = 3
    at = {int(n * (k + 1) / (reconnects + 1)) for k in range(reconnects)}
    return kind, at


def _pct(lat: np.ndarray, q: float) -> float:
    return float(np.percentile(lat, q)) if len(lat) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim-s", type=float, default=600.0,
                    help="simulated (= streaming) seconds (default 600)")
    ap.add_argument("--reconnects", type=int, default=4)
    ap.add_argument("--deterministic", action="store_true",
                    help="the bridge queues every frame (default: live, latest frame)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None, help="where the recording goes (kept)")
    args = ap.parse_args()
    if not 1.0 <= args.sim_s <= 7200.0 or not 0 <= args.reconnects <= 100:
        raise SystemExit("--sim-s must be 1..7200 and --reconnects 0..100")

    import zenoh

    from teleop import keys
    from teleop.messages import HandState, encode
    from teleop.record.session import open_session

    frames = [f for _, f in open_session(SOURCE).hands() if f.right is not None]
    out_dir = args.out or Path(tempfile.mkdtemp(prefix="bridge_soak_"))
    out_dir.mkdir(parents=True, exist_ok=True)
    rec = out_dir / "soak.mcap"
    port, rig = keys.free_tcp_port(), "soak"
    ctx = mp.get_context("spawn")
    ready, stop, result = ctx.Event(), ctx.Event(), ctx.Queue()
    proc = ctx.Process(target=_bridge_proc, args=(port, rig, str(rec), args.deterministic,
                                                  ready, stop, result))
    proc.start()
    if not ready.wait(300):
        proc.terminate()
        raise SystemExit("the bridge did not start within 300 s")

    k = keys.RigKeys(rig)
    monitor = keys.open_session(connect_ports=[port])   # the state subscriber: never closed
    lock = threading.Lock()
    got: dict[int, float] = {}

    def on_state(sample: Any) -> None:
        t = time.perf_counter()
        seq = json.loads(sample.payload.to_bytes()).get("seq")
        with lock:
            if seq is not None and seq not in got:
                got[seq] = t

    state_sub = monitor.declare_subscriber(k.state, on_state)

    def connect() -> tuple[Any, Any]:
        s = keys.open_session(connect_ports=[port])
        p = s.declare_publisher(k.hands, congestion_control=zenoh.CongestionControl.DROP)
        t_end = time.monotonic() + 60
        while not p.matching_status.matching:
            if time.monotonic() > t_end:
                raise SystemExit("the publisher never matched the bridge")
            time.sleep(0.005)
        return s, p

    n = int(args.sim_s * RATE_HZ)
    kind, reconnect_at = _schedule(n, args.reconnects, np.random.default_rng(args.seed))
    period = 1.0 / RATE_HZ
    sent: dict[int, float] = {}
    tally = dict.fromkeys(("sent", "dropout", "lost_hand", "nan_valid", "late_skipped",
                           "reconnect_lost"), 0)
    reconnect_s: list[float] = []
    reconnected_at = -1.0   # when the last reconnect finished (perf_counter)
    session, pub = connect()
    t0 = time.perf_counter()
    for i in range(n):
        target = t0 + i * period
        if i in reconnect_at:
            tr = time.perf_counter()
            pub.undeclare()
            session.close()
            session, pub = connect()
            reconnected_at = time.perf_counter()
            reconnect_s.append(reconnected_at - tr)
        if time.perf_counter() > target + LATE_PERIODS * period:   # its slot has passed
            tally["dropout" if kind[i] == 1 else "reconnect_lost" if target < reconnected_at
                  else "late_skipped"] += 1
            continue
        while (now := time.perf_counter()) < target:
            time.sleep(min(0.002, target - now))
        if kind[i] == 1:
            tally["dropout"] += 1
            continue
        f = dataclasses.replace(frames[i % len(frames)], seq=i, device_time_s=i * period)
        if kind[i] == 2:
            payload = encode(dataclasses.replace(f, right=HandState.untracked(), left=None))
            tally["lost_hand"] += 1
        elif kind[i] == 3:
            payload = _nan_valid(f)
            tally["nan_valid"] += 1
        else:
            payload = encode(f)
        sent[i] = time.perf_counter()
        pub.put(payload)
        tally["sent"] += 1
    stream_s = time.perf_counter() - t0
    # the last answers: wait until the bridge's state names the last frame sent (or 10 s)
    last = max(sent)
    t_end = time.monotonic() + 10
    while time.monotonic() < t_end:
        with lock:
            if max(got, default=-1) >= last:
                break
        time.sleep(0.01)
    pub.undeclare()
    session.close()
    stop.set()
    bridge = result.get(timeout=120)
    proc.join(60)
    state_sub.undeclare()
    monitor.close()
    if "error" in bridge:
        raise SystemExit(f"the bridge could not record: {bridge['error']}")

    # ---------------------------------------------------------------- the recording, read back
    t_read = time.perf_counter()
    s = open_session(rec)
    read_counts: dict[str, int] = {}
    last_log_ns = 0
    for m in s.messages(decode=True):   # every message, to the last chunk, decoded and checked
        read_counts[m.topic] = read_counts.get(m.topic, 0) + 1
        last_log_ns = max(last_log_ns, m.log_time_ns)
    read_s = time.perf_counter() - t_read
    counts = bridge["counts"]

    with lock:
        answered = {q: got[q] - sent[q] for q in sent if q in got}
    lat = np.array(list(answered.values())) * 1e3
    warm = np.array([v * 1e3 for q, v in answered.items() if q >= RATE_HZ])   # after 1 s
    rows = []
    window = int(60 * RATE_HZ)
    for w0 in range(0, n, window):
        ws = [q for q in sent if w0 <= q < w0 + window]
        wl = np.array([answered[q] for q in ws if q in answered]) * 1e3
        rows.append({"t0_s": w0 / RATE_HZ, "sent": len(ws), "answered": len(wl),
                     "p50_ms": _pct(wl, 50), "p99_ms": _pct(wl, 99),
                     "max_ms": float(wl.max()) if len(wl) else float("nan")})
    summary = {
        "sim_s_requested": args.sim_s, "stream_wall_s": round(stream_s, 1),
        "bridge_sim_time_s": bridge["sim_time_s"], "frames_scheduled": n, **tally,
        "reconnects": len(reconnect_s),
        "reconnect_ms_max": 1e3 * max(reconnect_s) if reconnect_s else None,
        "bridge_received": counts.get("received", 0), "bridge_accepted": counts.get("accepted", 0),
        "bridge_malformed": counts.get("malformed", 0),
        "bridge_processed": counts.get("processed", 0),
        "bridge_superseded": counts.get("superseded", 0),
        "bridge_held": counts.get("held", 0), "held_reasons": bridge["held"],
        "physics_lag_steps": counts.get("physics_lag_steps", 0),
        "lost_in_transport": tally["sent"] - counts.get("received", 0),
        "answered": len(lat), "answered_pct": 100.0 * len(lat) / max(1, tally["sent"]),
        "latency_p50_ms": _pct(warm, 50), "latency_p99_ms": _pct(warm, 99),
        "latency_max_ms": float(warm.max()) if len(warm) else float("nan"),
        "recording_bytes": rec.stat().st_size, "recording_truncated": s.truncated,
        "recording_counts": read_counts,
        "recording_hands_match_accepted": read_counts.get("/hands", 0) == counts.get("accepted"),
        "recording_span_s": (last_log_ns - (s.start_time_ns or last_log_ns)) / 1e9,
        "read_back_s": round(read_s, 2), "recording": str(rec),
    }
    config = {"sim_s": args.sim_s, "rate_hz": RATE_HZ, "reconnects": args.reconnects,
              "deterministic": args.deterministic, "seed": args.seed, "view": False,
              "source": str(SOURCE.relative_to(REPO_ROOT)), "late_periods": LATE_PERIODS}
    path = write_record("bridge_soak", rows, summary=summary, config=config)
    print(json.dumps(summary, indent=1, default=str))
    print(f"record: {path}")
    if s.truncated or not summary["recording_hands_match_accepted"]:
        raise SystemExit("the recording is truncated or its /hands count is off")


if __name__ == "__main__":
    main()
