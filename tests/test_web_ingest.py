"""The web ingest without a browser: the page's binary frame format, the self-signed certificate,
and the WebSocket protocol spoken by a real aiohttp client against the real server and zenoh."""

from __future__ import annotations

import asyncio
import json
import ssl
import threading

import numpy as np
import pytest
from aiohttp import ClientSession, WSMsgType

from teleop import keys
from teleop.input.tls import ensure_certificate
from teleop.input.web_ingest import WebIngest, WebIngestConfig
from teleop.input.web_protocol import WS_HEADER_SIZE, pack_ws_frame, parse_ws_frame
from teleop.input.webxr import hand_frame_from_webxr
from teleop.messages import MessageError, decode
from tests.conftest import HANG_S, SOON_S, wait_for, wait_for_match, wait_for_queryable


def _hand(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    j = np.zeros((25, 8))
    j[:, :3] = rng.normal(0, 0.05, (25, 3)) + np.array([0.1, 1.2, -0.3])
    q = rng.normal(size=(25, 4))
    j[:, 3:7] = q / np.linalg.norm(q, axis=1, keepdims=True)
    j[:, 7] = 0.01
    return j.astype(np.float32).astype(float)


HEAD = np.array([0.0, 1.6, 0.0, 0.0, 0.0, 0.0, 1.0], np.float32).astype(float)  # wire precision


def test_frame_format_round_trip_and_errors():
    left, right = _hand(1), _hand(2)
    right[7, :] = np.nan  # a joint the runtime did not report
    data = pack_ws_frame(42, 1.5e12, HEAD, {"left": left, "right": right})
    assert len(data) == WS_HEADER_SIZE + 2 * 800
    f = parse_ws_frame(data, 123.0)
    ref = hand_frame_from_webxr(42, 1.5e9, HEAD[:3], HEAD[3:],
                                {s: (h[:, :3], h[:, 3:7], h[:, 7]) for s, h in
                                 (("left", left), ("right", right))}, receive_time_s=123.0)
    assert f == ref and f.seq == 42 and f.device_time_s == 1.5e9
    assert not f.right.valid[8] and f.right.tracked
    assert parse_ws_frame(pack_ws_frame(1, 0.0, HEAD, {}), 0.0).hands == ()
    with pytest.raises(MessageError, match="header needs 48"):
        parse_ws_frame(data[:20], 0.0)
    with pytest.raises(MessageError, match="magic"):
        parse_ws_frame(b"XXXX" + data[4:], 0.0)
    with pytest.raises(MessageError, match="expected 1648 for 2 hand"):
        parse_ws_frame(data[:-4], 0.0)


def test_certificate_is_made_once_and_covers_the_hosts(tmp_path):
    from cryptography import x509
    cert, key = ensure_certificate(tmp_path, hosts=["127.0.0.1", "192.0.2.7"])
    c = x509.load_pem_x509_certificate(cert.read_bytes())
    san = c.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert "localhost" in san.get_values_for_type(x509.DNSName)
    assert {str(a) for a in san.get_values_for_type(x509.IPAddress)} == {"127.0.0.1", "192.0.2.7"}
    mtime = cert.stat().st_mtime_ns
    assert ensure_certificate(tmp_path, hosts=["192.0.2.7"]) == (cert, key)
    assert cert.stat().st_mtime_ns == mtime  # reused: the headset's acceptance stays valid
    ensure_certificate(tmp_path, hosts=["192.0.2.8"])  # a new address: a new certificate
    assert cert.stat().st_mtime_ns != mtime
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    ctx.load_cert_chain(cert, key)


def test_websocket_protocol_frames_control_refusal(tmp_path, caplog):
    rig = "wsproto"
    zport = keys.free_tcp_port()
    ingest = WebIngest(rig, WebIngestConfig(host="127.0.0.1", port=0, cert_dir=tmp_path,
                                            status_period_s=0.2), listen_port=zport)
    ingest.start()
    peer = keys.open_session(connect_ports=[zport])
    got: list = []
    sub = peer.declare_subscriber(keys.RigKeys(rig).hands,
                                  lambda s: got.append(decode(s.payload.to_bytes())))
    calls = []

    def on_query(q):  # a stand-in bridge control endpoint on real zenoh
        calls.append(str(q.key_expr))
        q.reply(q.key_expr, json.dumps({"ok": True, "recording": None}).encode())

    qbl = peer.declare_queryable(keys.RigKeys(rig).control, on_query)
    view = peer.declare_publisher(keys.RigKeys(rig).view)
    # every route up before anything is sent (the events themselves, not a guess of their time)
    wait_for_match(ingest._pub, SOON_S, "the ingest's /hands reaching the peer")
    wait_for_match(view, SOON_S, "the peer's /view reaching the ingest")
    wait_for_queryable(ingest.session, keys.RigKeys(rig).control_cmd("mark_grasp"), SOON_S,
                       "the stand-in control queryable reaching the ingest")
    url = f"wss://127.0.0.1:{ingest.port}/ws"

    async def session() -> dict:
        out: dict = {}
        async with ClientSession() as http:
            ws = await http.ws_connect(url, ssl=False)
            await ws.send_str(json.dumps({"type": "hello", "client_id": "a"}))
            out["welcome"] = json.loads((await ws.receive()).data)
            for k in range(20):
                await ws.send_bytes(pack_ws_frame(k, 1e12 + k, HEAD, {"right": _hand(k)}))
            await ws.send_bytes(b"nonsense")
            await ws.send_str(json.dumps({"type": "control", "command": "mark_grasp", "id": 7}))
            await ws.send_str(json.dumps({"type": "control", "command": "rm_rf", "id": 8}))
            two = await http.ws_connect(url, ssl=False)
            await two.send_str(json.dumps({"type": "hello", "client_id": "b"}))
            out["second"] = json.loads((await two.receive()).data)
            out["second_close"] = (await two.receive()).type
            view.put(b"\xff\xd8fakejpeg")
            replies, views = [], []
            while len(replies) < 2 or not views:
                msg = await ws.receive(timeout=SOON_S)
                if msg.type == WSMsgType.BINARY:
                    views.append(msg.data)
                elif json.loads(msg.data)["type"] == "control_reply":
                    replies.append(json.loads(msg.data))
            out["replies"], out["views"] = replies, views
            await ws.close()
        return out

    try:
        # own thread and loop: a Playwright sync fixture may hold this thread's event loop
        box: dict = {}
        th = threading.Thread(target=lambda: box.update(out=asyncio.run(session())))
        th.start()
        th.join(HANG_S)
        assert not th.is_alive(), "the WebSocket client hung"
        out = box["out"]
        wait_for(lambda: len(got) >= 20, SOON_S, lambda: f"20 frames on /hands; got {len(got)}")
        stats = ingest.stats()
    finally:
        sub.undeclare()
        qbl.undeclare()
        view.undeclare()
        peer.close()
        ingest.close()
    assert out["welcome"]["type"] == "welcome" and out["welcome"]["rig"] == rig
    assert [f.seq for f in got] == list(range(20)) and got[0].right is not None
    assert stats["counts"]["frames"] == 20 and stats["counts"]["bad_frames"] == 1
    assert out["second"]["type"] == "refused" and "another headset" in out["second"]["reason"]
    assert out["second_close"] in (WSMsgType.CLOSE, WSMsgType.CLOSED)
    by_id = {r["id"]: r for r in out["replies"]}
    assert by_id[7]["result"]["ok"] and not by_id[8]["result"]["ok"]
    assert f"dexaug/{rig}/control/mark_grasp" in calls
    assert out["views"] == [b"\xff\xd8fakejpeg"]
    assert any("refused a second headset" in r.message for r in caplog.records)
