"""Attacks on the headset page, the streamer ingest and the bridge's control queryable, each
performed against the real servers on loopback (aiohttp server and client, real zenoh peers, a
real Bridge with MuJoCo), asserting they are refused; plus a positive check per feature with
the token. See :mod:`teleop.input.access` and :mod:`teleop.bridge.control` for the rules.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import logging
import os
import socket
import stat
import sys
import threading
import time
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any

import aiohttp
import pytest
from aiohttp import ClientSession, WSMsgType

from teleop import keys
from teleop.input.access import access_policy
from teleop.input.stream_ingest import StreamIngest
from teleop.input.tls import ensure_certificate, local_addresses
from teleop.input.web_ingest import WebIngest, WebIngestConfig
from tests.conftest import HANG_S, SOON_S, needs_menagerie, wait_for, wait_for_queryable

pytestmark = pytest.mark.slow

TOKEN = "test-token-0123456789"


def _in_thread(make: Callable[[], Coroutine[Any, Any, Any]], timeout_s: float = HANG_S) -> Any:
    """Run a client coroutine on its own loop in its own thread (a Playwright sync fixture may
    hold this thread's loop); its exception is re-raised here."""
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["out"] = asyncio.run(make())
        except BaseException as exc:  # re-raised in the test's thread
            box["exc"] = exc
    th = threading.Thread(target=run)
    th.start()
    th.join(timeout_s)   # a hang guard: every wait inside is on an event
    assert not th.is_alive(), f"the client coroutine still runs after {timeout_s:g} s"
    if "exc" in box:
        raise box["exc"]
    return box["out"]


class _Page:
    """A WebIngest on 127.0.0.1 (plain HTTP, free port) and a stand-in bridge queryable on real
    zenoh that records every forwarded control request (key, payload)."""

    def __init__(self, rig: str, token: str | None = None) -> None:
        zport = keys.free_tcp_port()
        self.ingest = WebIngest(rig, WebIngestConfig(host="127.0.0.1", port=0, tls=False,
                                                     token=token, status_period_s=30.0),
                                listen_port=zport)
        self.ingest.start()
        self.peer = keys.open_session(connect_ports=[zport])
        self.calls: list[tuple[str, dict]] = []

        def on_query(q) -> None:
            body = q.payload.to_bytes() if q.payload is not None else b"{}"
            self.calls.append((str(q.key_expr).rsplit("/", 1)[-1], json.loads(body or b"{}")))
            q.reply(q.key_expr, json.dumps({"ok": True, "path": "stand-in"}).encode())
        self.qbl = self.peer.declare_queryable(keys.RigKeys(rig).control, on_query)
        wait_for_queryable(self.ingest.session, keys.RigKeys(rig).control_cmd("mark_grasp"),
                           SOON_S, "the stand-in control queryable reaching the ingest")
        self.base = f"http://127.0.0.1:{self.ingest.port}"

    def close(self) -> None:
        self.qbl.undeclare()
        self.peer.close()
        self.ingest.close()


@pytest.fixture
def page_factory():
    pages: list[_Page] = []

    def make(rig: str, token: str | None = None) -> _Page:
        pages.append(_Page(rig, token))
        return pages[-1]
    yield make
    for p in pages:
        p.close()


async def _receive_type(ws: aiohttp.ClientWebSocketResponse, kind: str,
                        timeout_s: float = SOON_S) -> dict:
    """The next text message of type ``kind`` (others, e.g. ``status``, skipped)."""
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        msg = await ws.receive(timeout=timeout_s)
        if msg.type in (WSMsgType.CLOSE, WSMsgType.CLOSED, WSMsgType.CLOSING):
            raise AssertionError(f"socket closed ({ws.close_code}) before a {kind!r} message")
        if msg.type == WSMsgType.TEXT and json.loads(msg.data).get("type") == kind:
            return json.loads(msg.data)
    raise AssertionError(f"no {kind!r} message within {timeout_s} s")


async def _hello(http: ClientSession, url: str, client_id: str, **kw) -> tuple[Any, dict]:
    ws = await http.ws_connect(url, **kw)
    await ws.send_str(json.dumps({"type": "hello", "client_id": client_id}))
    msg = await ws.receive(timeout=SOON_S)
    return ws, json.loads(msg.data)


async def _handshake_status(url: str, **kw) -> int:
    """The HTTP status a WebSocket handshake is refused with (101 would mean accepted)."""
    async with ClientSession() as http:
        try:
            ws = await http.ws_connect(url, **kw)
        except aiohttp.WSServerHandshakeError as exc:
            return exc.status
        await ws.close()
        return 101


async def _get(url: str, **kw) -> tuple[int, str]:
    async with ClientSession() as http, http.get(url, **kw) as r:
        return r.status, await r.text()


# ------------------------------------------------------------------------------- listening


def _unreachable_off_loopback(port: int) -> None:
    """Nothing answers on ``port`` at this machine's LAN address (when it has one)."""
    for addr in [a for a in local_addresses() if not a.startswith("127.")][:1]:
        with socket.socket() as s, pytest.raises(OSError):
            s.settimeout(1.0)
            s.connect((addr, port))


def test_servers_listen_on_loopback_by_default():
    peer = keys.open_session()
    try:
        with StreamIngest("sec-stream", udp_port=0, tcp_port=0, session=peer) as ingest:
            assert [s.server_address[0] for s in ingest._servers] == ["127.0.0.1", "127.0.0.1"]
            _unreachable_off_loopback(ingest.tcp_port)
        with WebIngest("sec-bind", WebIngestConfig(port=0, tls=False), session=peer) as web:
            web.start()
            assert web.config.host == "127.0.0.1" and not web.access.required
            assert _in_thread(lambda: _get(f"http://127.0.0.1:{web.port}/"))[0] == 200
            _unreachable_off_loopback(web.port)
    finally:
        peer.close()
    # off loopback the token is required, and each start makes a fresh one
    lan_policy, again = access_policy("0.0.0.0"), access_policy("0.0.0.0")
    assert lan_policy.required and lan_policy.token != again.token and len(lan_policy.token) >= 24
    assert not access_policy("127.0.0.1").required and access_policy("127.0.0.1", TOKEN).required


def test_the_page_url_carries_the_token(page_factory):
    page = page_factory("sec-url")
    assert page.ingest.url == f"http://localhost:{page.ingest.port}/?token={page.ingest.access.token}"
    status, html = _in_thread(lambda: _get(page.ingest.url))
    assert status == 200 and "app.js" in html


# ------------------------------------------------------------------------- Host and Origin


def test_a_wrong_host_header_is_refused(page_factory):
    page = page_factory("sec-host")
    evil = {"Host": f"attacker.example:{page.ingest.port}"}
    status, text = _in_thread(lambda: _get(page.base + "/", headers=evil))
    assert status == 421 and "does not name this machine" in text
    assert _in_thread(lambda: _handshake_status(page.base + "/ws", headers=evil)) == 421
    assert _in_thread(lambda: _get(page.base + "/static/app.js", headers=evil))[0] == 421
    # positive: this machine's own names pass
    assert _in_thread(lambda: _get(page.base + "/"))[0] == 200


def test_a_foreign_origin_websocket_is_refused(page_factory):
    page = page_factory("sec-origin", token=TOKEN)
    url = f"{page.base}/ws?token={TOKEN}"
    for origin in ("https://attacker.example", f"http://attacker.example:{page.ingest.port}",
                   "null"):
        assert _in_thread(lambda o=origin: _handshake_status(url, headers={"Origin": o})) == 403

    async def own_origin() -> dict:   # positive: the page's own origin with the token
        async with ClientSession() as http:
            ws, welcome = await _hello(http, url, "own", headers={"Origin": page.base})
            await ws.close()
            return welcome
    assert _in_thread(own_origin)["type"] == "welcome"


# --------------------------------------------------------------------------------- token


def test_no_or_a_wrong_token_is_refused_when_required(page_factory):
    page = page_factory("sec-token", token=TOKEN)
    for query in ("", "?token=", "?token=wrong-token-000000"):
        assert _in_thread(lambda q=query: _get(f"{page.base}/{q}"))[0] == 401
        assert _in_thread(lambda q=query: _handshake_status(f"{page.base}/ws{q}")) == 401
    assert _in_thread(lambda: _get(f"{page.base}/?token={TOKEN}"))[0] == 200

    async def controls() -> list[dict]:
        async with ClientSession() as http:
            ws, welcome = await _hello(http, f"{page.base}/ws?token={TOKEN}", "op")
            assert welcome["type"] == "welcome"
            out = []
            for k, tok in enumerate((None, "wrong-token-000000", TOKEN)):
                msg = {"type": "control", "command": "mark_grasp", "id": k}
                if tok is not None:
                    msg["token"] = tok
                await ws.send_str(json.dumps(msg))
                out.append(await _receive_type(ws, "control_reply"))
            await ws.close()
            return out
    replies = _in_thread(controls)
    assert [r["result"]["ok"] for r in replies] == [False, False, True]
    assert "token" in replies[0]["result"]["error"]
    assert [c for c in page.calls if c[0] == "mark_grasp"] == [("mark_grasp", {})]


def test_the_page_never_forwards_a_path_or_overwrite(page_factory):
    page = page_factory("sec-args", token=TOKEN)

    async def controls() -> list[dict]:
        async with ClientSession() as http:
            ws, _ = await _hello(http, f"{page.base}/ws?token={TOKEN}", "op")
            out = []
            for k, args in enumerate(({"path": "/tmp/evil.mcap"}, {"overwrite": True},
                                      {"name": "take1", "path": "/tmp/x"}, {"name": 5},
                                      {"name": "take1"})):
                await ws.send_str(json.dumps({"type": "control", "command": "start_recording",
                                              "id": k, "args": args, "token": TOKEN}))
                out.append(await _receive_type(ws, "control_reply"))
            await ws.close()
            return out
    replies = _in_thread(controls)
    assert [r["result"]["ok"] for r in replies] == [False, False, False, False, True]
    assert "not accepted from the page" in replies[0]["result"]["error"]
    assert [c for c in page.calls if c[0] == "start_recording"] == [
        ("start_recording", {"name": "take1"})]


# ------------------------------------------------------------------------------- takeover


def test_a_token_holder_takes_the_rig_over_from_a_squatter(page_factory, caplog):
    page = page_factory("sec-takeover")   # loopback: a tokenless client is admitted
    token = page.ingest.access.token

    async def scenario() -> dict:
        async with ClientSession() as http:
            squat, w1 = await _hello(http, f"{page.base}/ws", "squatter")
            head, w2 = await _hello(http, f"{page.base}/ws?token={token}", "headset")
            replaced = await squat.receive(timeout=SOON_S)
            closed = await squat.receive(timeout=SOON_S)
            # a second tokenless client cannot take it back
            again, w3 = await _hello(http, f"{page.base}/ws", "squatter2")
            await head.send_str(json.dumps({"type": "control", "command": "mark_grasp",
                                            "id": 1, "token": token}))
            reply = await _receive_type(head, "control_reply")
            await head.close()
            await again.close()
            return {"w": [w1["type"], w2["type"], w3["type"]],
                    "replaced": json.loads(replaced.data),
                    # the code the server's close frame carried; the client's own close_code
                    # reads 1006 when the server drops the socket before the client's close
                    # reply is written (an aiohttp race, seen once in CI)
                    "closed": (closed.type, closed.data), "reply": reply}
    caplog.set_level(logging.INFO)
    out = _in_thread(scenario)
    assert out["w"] == ["welcome", "welcome", "refused"]
    assert out["replaced"]["type"] == "replaced" and "took rig" in out["replaced"]["reason"]
    assert out["closed"] == (WSMsgType.CLOSE, 4001) and out["reply"]["result"]["ok"]
    assert page.ingest.stats()["counts"]["taken_over"] == 1
    assert any("took the rig over" in r.getMessage() for r in caplog.records)


# ------------------------------------------------------------------------- log injection


def test_a_notice_cannot_inject_log_lines_or_counters(page_factory, caplog):
    page = page_factory("sec-notice")
    forged = "hello\n2026-01-01 INFO teleop.bridge: recording deleted\r\x1b[2J" + "x" * 5000

    async def notices() -> None:
        async with ClientSession() as http:
            ws, _ = await _hello(http, f"{page.base}/ws", "op")
            for k in range(50):
                await ws.send_str(json.dumps({"type": "notice", "what": f"w{k}\nFAKE",
                                              "message": forged}))
            await ws.send_str(json.dumps({"type": "notice", "what": "no_webxr", "message": "x"}))
            await ws.send_str(json.dumps({"type": "stats"}))
            # the server reads a socket's messages in order: the stats message sent last
            # counted means every notice before it was handled (logged, counted)
            await asyncio.to_thread(
                wait_for, lambda: page.ingest.stats()["counts"].get("page_stats"), SOON_S,
                "the page's stats message handled")
            await ws.close()
    caplog.set_level(logging.WARNING, logger="teleop.input.web_ingest")
    _in_thread(notices)
    lines = [r.getMessage() for r in caplog.records if r.name == "teleop.input.web_ingest"
             and "hello" in r.getMessage()]
    assert len(lines) == 50
    assert all("\n" not in m and "\r" not in m and "\x1b" not in m and len(m) < 400 for m in lines)
    counts = page.ingest.stats()["counts"]
    assert {k for k in counts if k.startswith("notice_")} == {"notice_other", "notice_no_webxr"}
    assert counts["notice_other"] == 50


# ------------------------------------------------------------------------------ TLS key


def test_the_key_file_is_created_0600_and_a_loose_reused_key_is_fixed(tmp_path, caplog):
    old = os.umask(0)   # the most permissive umask: the key must still never be readable
    try:
        cert, key = ensure_certificate(tmp_path / "c", hosts=["127.0.0.1"])
    finally:
        os.umask(old)
    assert stat.S_IMODE(key.stat().st_mode) == 0o600
    key.chmod(0o644)
    assert ensure_certificate(tmp_path / "c", hosts=["127.0.0.1"]) == (cert, key)  # reused
    assert stat.S_IMODE(key.stat().st_mode) == 0o600
    assert any("readable by other users" in r.getMessage() for r in caplog.records)
    # a key file left 0644 before a new certificate is written is tightened before the write
    key.chmod(0o644)
    ensure_certificate(tmp_path / "c", hosts=["127.0.0.1", "192.0.2.9"])
    assert stat.S_IMODE(key.stat().st_mode) == 0o600


# ------------------------------------------------------------------- bridge control (zenoh)


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """A real bridge (recordings in a fresh folder, the /view on when OpenGL is there) and a
    zenoh client peer; its ``query`` sends control queries as any local process could."""
    if needs_menagerie.args[0]:
        pytest.skip(needs_menagerie.kwargs["reason"])
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config
    root = tmp_path_factory.mktemp("sec")
    cfg = dataclasses.replace(load_bridge_config(), recordings_dir=root / "recordings",
                              deterministic=True)
    port = keys.free_tcp_port()
    bridge = Bridge("shadow_right", None, "secrig", cfg, listen_port=port)
    client = keys.open_session(connect_ports=[port])
    bridge.start()
    k = keys.RigKeys("secrig")
    wait_for_queryable(client, k.control_cmd("status"), SOON_S,
                       "the bridge's control queryable reaching the client")

    class Rig:
        pass
    r = Rig()
    r.bridge, r.client, r.root, r.port = bridge, client, root, port
    r.recordings = cfg.recordings_dir
    r.query = lambda cmd, payload=None: keys.query_json(client, k.control_cmd(cmd), payload,
                                                        timeout_s=SOON_S)
    yield r
    client.close()
    bridge.close()


def _tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_zenoh_start_recording_refuses_path_and_overwrite(rig):
    victim = rig.root / "victim.mcap"
    victim.write_bytes(b"precious")
    before = _tree(rig.root)
    for payload in ({"path": str(victim), "overwrite": True}, {"path": str(victim)},
                    {"path": str(rig.root / "new" / "nested" / "x.mcap")},
                    {"name": "ok", "overwrite": True}, {"name": ["not", "a", "string"]}):
        reply = rig.query("start_recording", payload)
        assert not reply["ok"], payload
        assert "not accepted from a remote caller" in reply["error"] or "string" in reply["error"]
        assert "\n" not in reply["error"]
    assert _tree(rig.root) == before and not (rig.root / "new").exists()
    assert rig.query("status")["recording"] is None


def test_zenoh_recording_names_stay_inside_the_recordings_folder(rig):
    made = []
    for name in ("../../escape", "../../escape", "/etc/cron.d/evil.mcap", "..", "a\\..\\b c"):
        reply = rig.query("start_recording", {"name": name})
        if name == "..":
            assert not reply["ok"] and "no usable file name" in reply["error"]
            continue
        assert reply["ok"], reply
        path = Path(reply["path"])
        assert path.parent.resolve() == rig.recordings.resolve() and path.suffix == ".mcap"
        made.append(path.name)
        assert rig.query("stop_recording")["ok"]
    assert made == ["escape.mcap", "escape_2.mcap", "evil.mcap", "b_c.mcap"]
    assert sorted(p.name for p in rig.recordings.iterdir()) == sorted(made)
    assert not (rig.root.parent / "escape.mcap").exists()


def test_zenoh_choose_object_takes_catalogue_ids_only(rig):
    opened: list[str] = []
    watching = threading.Event()
    targets = ("/etc/passwd", str(rig.root / "planted.xml"))
    (rig.root / "planted.xml").write_text("<mujoco/>")

    def audit(event: str, args: tuple) -> None:
        if watching.is_set() and event == "open" and str(args[0]) in targets:
            opened.append(str(args[0]))
    sys.addaudithook(audit)   # cannot be removed: it only records while `watching` is set
    watching.set()
    try:
        replies = {o: rig.query("choose_object", {"object": o})
                   for o in (*targets, "../../etc/passwd", "no_such_object", "")}
    finally:
        watching.clear()
    assert not any(r["ok"] for r in replies.values()), replies
    assert "installed catalogue" in replies["/etc/passwd"]["error"]
    assert "not an installed object" in replies["no_such_object"]["error"]
    assert opened == [] and rig.bridge.object_name == "box"
    # positive: a catalogue id is chosen, then the previous one again
    assert rig.query("choose_object", {"object": "cylinder"}) == {"ok": True, "object": "cylinder"}
    assert rig.query("choose_object", {"object": "box"})["ok"]
    assert rig.query("status")["object"] == "box"


def test_a_failed_choose_object_keeps_the_scene_and_the_view(rig):
    bad = rig.root / "broken.xml"
    bad.write_text("<mujoco><worldbody><body><geom type='nonsense'/></body></worldbody></mujoco>")
    bridge = rig.bridge
    scene, name, view = bridge.scene, bridge.object_name, bridge.view_active
    views0 = bridge.status()["counts"].get("views", 0)
    reply = bridge.control("choose_object", {"object": str(bad)})   # trusted: a file may be named
    assert not reply["ok"] and "\n" not in reply["error"] and "broken.xml" in reply["error"]
    assert bridge.scene is scene and bridge.object_name == name
    assert bridge.view_active == view and bridge.status()["loop_running"]
    st = rig.query("status")
    assert st["ok"] and st["object"] == name and st["view"] == view
    if view:   # the /view keeps streaming the old scene
        wait_for(lambda: bridge.status()["counts"].get("views", 0) > views0, SOON_S,
                 "a /view frame after the failed choose_object")


def test_the_page_drives_the_bridge_with_the_token_and_names_only(rig):
    """End to end: token-required page → real bridge; a name lands in the recordings folder,
    a path is refused at the page and would be at the bridge."""
    pwn = rig.root / "pwn.mcap"
    zport = keys.free_tcp_port()
    ingest = WebIngest("secrig", WebIngestConfig(host="127.0.0.1", port=0, tls=False, token=TOKEN,
                                                 status_period_s=30.0),
                       listen_port=zport, connect_ports=(rig.port,))
    ingest.start()
    base = f"http://127.0.0.1:{ingest.port}"

    async def drive() -> list[dict]:
        async with ClientSession() as http:
            ws, welcome = await _hello(http, f"{base}/ws?token={TOKEN}", "headset")
            assert welcome["type"] == "welcome"
            out = []
            for k, (cmd, args) in enumerate((("start_recording", {"path": str(pwn)}),
                                            ("start_recording", {"name": "../page_take"}),
                                            ("mark_grasp", {}), ("stop_recording", {}))):
                await ws.send_str(json.dumps({"type": "control", "command": cmd, "id": k,
                                              "args": args, "token": TOKEN}))
                out.append((await _receive_type(ws, "control_reply"))["result"])
            await ws.close()
            return out
    try:
        wait_for_queryable(ingest.session, keys.RigKeys("secrig").control_cmd("status"), SOON_S,
                           "the bridge's control queryable reaching the ingest")
        replies = _in_thread(drive)
    finally:
        ingest.close()
    assert [r["ok"] for r in replies] == [False, True, True, True], replies
    assert Path(replies[1]["path"]) == rig.recordings / "page_take.mcap"
    assert (rig.recordings / "page_take.mcap").stat().st_size > 0
    assert not pwn.exists()


def test_the_cli_flags_default_to_loopback_and_a_random_token():
    import argparse

    from teleop.input.access import add_listen_args
    p = argparse.ArgumentParser()
    add_listen_args(p, prefix="web-")
    args = p.parse_args([])
    assert (args.web_host, args.web_token) == ("127.0.0.1", None)
    args = p.parse_args(["--web-host", "0.0.0.0", "--web-token", TOKEN])
    policy = access_policy(args.web_host, args.web_token)
    assert policy.required and policy.token == TOKEN
    from teleop.input.background_server import WebIngestError
    with pytest.raises(WebIngestError, match="token: expected at least 8"):
        access_policy("0.0.0.0", "short")


def test_zenoh_recalibrate_scale_takes_a_bounded_duration_only(rig):
    """``recalibrate_scale`` (#18: redo the operator's scale calibration) from a remote caller:
    a duration in (0, 10] s or none; anything else refused in one line, nothing started."""
    rig.bridge.retargeter.calibration = None
    for payload in ({"duration_s": 0}, {"duration_s": 99}, {"duration_s": "1"},
                    {"duration_s": True}, {"path": "/tmp/x"}):
        reply = rig.query("recalibrate_scale", payload)
        assert not reply["ok"] and "\n" not in reply["error"], payload
        assert rig.bridge.retargeter.calibration is None
    reply = rig.query("recalibrate_scale", {"duration_s": 0.5})
    assert reply["ok"] and reply["duration_s"] == 0.5
    assert rig.bridge.retargeter.calibration is not None
