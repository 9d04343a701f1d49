"""Foxglove: sessions the real bridge records with the ``foxglove-sdk`` read back through the
``mcap`` reader with every ``foxglove.*`` message validated against the SDK's schema, and the
bridge's live server (``bridge --foxglove``) seen by a real WebSocket client on loopback.

Validation here is independent of the reader under test: each ``foxglove.*`` channel's schema
must be the SDK's own (name, encoding, descriptor bytes), and each message is parsed with
``google.protobuf`` from the descriptor set stored in the file, must hold no field the schema
lacks, and must re-encode to the very bytes stored. Real zenoh, MuJoCo, files, sockets; no mocks.
"""

from __future__ import annotations

import asyncio
import base64
import json
import re
import socket
import struct
import threading
from collections import Counter
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from foxglove import messages as fm
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.message import Message
from google.protobuf.unknown_fields import UnknownFieldSet
from mcap.reader import make_reader

from sim.paths import REPO_ROOT
from teleop.record import schemas
from tests.conftest import SOON_S, needs_menagerie
from tests.test_bridge import CAPTURE, _pinch_offset, _record, _Rig, frames  # noqa: F401

pytestmark = [pytest.mark.slow, needs_menagerie,
              pytest.mark.skipif(not CAPTURE.is_file(), reason=f"no hand capture {CAPTURE}")]

LAYOUT = REPO_ROOT / "configs" / "foxglove" / "dexaug_layout.json"
#: the WebSocket subprotocol of the foxglove-sdk's server (successor of foxglove.websocket.v1,
#: which this SDK's server refuses with 400)
SUBPROTOCOL = "foxglove.sdk.v1"


# ------------------------------------------------------------------------- schema validation


def _protobuf_class(name: str, descriptor_set: bytes) -> type[Message]:
    files = descriptor_pb2.FileDescriptorSet.FromString(descriptor_set)
    pool = descriptor_pool.DescriptorPool()
    for f in files.file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def _no_unknown_fields(msg: Message) -> bool:
    if len(UnknownFieldSet(msg)):
        return False
    return all(_no_unknown_fields(item) for field, value in msg.ListFields()
               if field.message_type is not None
               for item in ([value] if isinstance(value, Message) else value))


def foxglove_messages(path: Path) -> Iterator[tuple[str, Message]]:
    """Every ``foxglove.*`` message of an MCAP file, read with the ``mcap`` reader (CRCs
    checked), each validated against the SDK's schema (module docstring); AssertionError on
    the first that fails."""
    classes: dict[int, type[Message]] = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f, validate_crcs=True).iter_messages():
            if schema is None or not schema.name.startswith("foxglove."):
                continue
            if schema.id not in classes:
                sdk = getattr(fm, schema.name.removeprefix("foxglove.")).get_schema()
                assert (schema.encoding, channel.message_encoding) == ("protobuf", "protobuf"), \
                    f"{channel.topic}: {schema.encoding}/{channel.message_encoding}, not protobuf"
                assert schema.data == bytes(sdk.data), f"{channel.topic}: not the SDK's schema"
                classes[schema.id] = _protobuf_class(schema.name, schema.data)
            msg = classes[schema.id].FromString(message.data)
            assert _no_unknown_fields(msg), f"{channel.topic}: fields its schema lacks"
            assert msg.SerializeToString(deterministic=True) == message.data, channel.topic
            yield channel.topic, msg


@pytest.fixture(scope="module")
def bridge_session(frames, shadow, tmp_path_factory) -> Path:  # noqa: F811
    """A session recorded by the real bridge: the Quest capture replayed over loopback zenoh,
    the hand placed so the pinch touches the box (contacts and their markers are recorded)."""
    from teleop.record.replay import replay_capture

    rig = _Rig(frames, "fx1", deterministic=True, world_offset_m=_pinch_offset(frames, shadow),
               view_enabled=False)
    path = tmp_path_factory.mktemp("foxglove") / "bridge.mcap"
    try:
        _record(rig, path, lambda: replay_capture(frames, rig.client, "fx1", rate="max"))
    finally:
        rig.close()
    return path


def test_a_bridge_session_reads_back_with_every_foxglove_schema_validated(bridge_session):
    from teleop.record.session import open_session

    session = open_session(bridge_session)
    assert session.metadata["format_version"] == schemas.FORMAT_VERSION == 2
    assert not session.truncated
    got: dict[str, list[Message]] = {}
    for topic, msg in foxglove_messages(bridge_session):
        got.setdefault(topic, []).append(msg)
    assert set(got) == {"/tf", "/markers"}    # the bridge records no /view
    states = [s for _, s in session.json_messages("/state")]
    contacts = [c for _, c in session.json_messages("/contacts")]
    assert len(got["/tf"]) == len(states) > 500 and len(got["/markers"]) == len(contacts)
    # /tf holds the /state poses (Foxglove's xyzw = our wxyz rolled)
    for tf, state in zip(got["/tf"], states, strict=True):
        by_child = {t.child_frame_id: t for t in tf.transforms}
        palm = by_child["palm"]
        assert palm.parent_frame_id == "world"
        np.testing.assert_allclose([palm.translation.x, palm.translation.y, palm.translation.z],
                                   state["palm_pos_m"])
        r = palm.rotation
        np.testing.assert_allclose([r.w, r.x, r.y, r.z], state["palm_quat_wxyz"])
    # one contact sphere per recorded contact, and some steps touch the box
    spheres = [sum(len(e.spheres) for e in m.entities if e.id == "contacts") for m in got["/markers"]]
    assert spheres == [len(c["contacts"]) for c in contacts] and max(spheres) > 0


def test_the_validation_can_fail(bridge_session, tmp_path):
    """A format-1 recording (Foxglove's JSON schemas) and a message with bytes its schema lacks
    are refused: the check above is not vacuous."""
    with pytest.raises(AssertionError, match="not protobuf"):
        list(foxglove_messages(REPO_ROOT / "recordings" / "demo_004_sugar_box.mcap"))
    from mcap.writer import Writer

    bad = tmp_path / "bad.mcap"
    schema = fm.FrameTransforms.get_schema()
    with open(bad, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema(schema.name, schema.encoding, bytes(schema.data))
        cid = w.register_channel("/tf", "protobuf", sid)
        w.add_message(cid, 1, fm.FrameTransforms().encode() + bytes([0x78, 0x05]), 1)  # field 15
        w.finish()
    with pytest.raises(AssertionError, match="fields its schema lacks"):
        list(foxglove_messages(bad))


def test_a_recorder_session_with_view_and_skeletons_validates(tmp_path):
    """Every foxglove.* message the recorder can write (/view JPEGs, model and skeleton
    markers, extra transforms) passes, and the session reader gives them in Foxglove's JSON
    form, the same shape as format 1's JSON."""
    from teleop.record.session import open_session
    from tests.test_recorder import _record as record_all

    path = tmp_path / "all.mcap"
    written = record_all(path, 20, rng=np.random.default_rng(7), record_view=True)
    counts = Counter(topic for topic, _ in foxglove_messages(path))
    assert counts == {"/tf": 40, "/markers": 40, "/view": 20}
    views = [m.payload for m in open_session(path).messages("/view")]
    assert [base64.b64decode(v["data"]) for v in views] == written["jpegs"]
    assert views[0]["format"] == "jpeg" and set(views[0]["timestamp"]) == {"sec", "nsec"}


# ------------------------------------------------------------------------------- live server


class _LiveBridge:
    """``bridge_main`` with ``foxglove=("127.0.0.1", 0)`` in a thread, as ``dexaug bridge
    --foxglove`` runs it; ``live`` is its server once it listens. Its loop (``duration_s``)
    starts once ``watching`` is set (or after SOON_S): a client that subscribed first sees the
    whole run, however long the machine took to get it there."""

    def __init__(self, duration_s: float) -> None:
        from teleop.bridge.main import bridge_main
        from teleop.keys import free_tcp_port

        self.live: Any = None
        self._up = threading.Event()
        self.watching = threading.Event()
        self.thread = threading.Thread(target=bridge_main, args=("shadow_right", "box", "fxlive"),
                                       kwargs={"listen_port": free_tcp_port(),
                                               "duration_s": duration_s, "view": False,
                                               "foxglove": ("127.0.0.1", 0),
                                               "on_foxglove": self._on_live}, daemon=True)
        self.thread.start()
        assert self._up.wait(SOON_S), "the Foxglove server did not start"

    def _on_live(self, live: Any) -> None:
        self.live = live
        self._up.set()
        self.watching.wait(SOON_S)   # in the bridge's thread, before its loop starts


async def _watch(url: str, subscribed: threading.Event
                 ) -> tuple[dict[str, dict], dict[str, list[bytes]]]:
    """A Foxglove WebSocket client: the advertised channels (topic → channel) and the
    payloads received on each after subscribing to all of them (``subscribed`` set then),
    until the server closes the socket (its bridge's run ended)."""
    import aiohttp

    async with aiohttp.ClientSession() as http, \
            http.ws_connect(url, protocols=[SUBPROTOCOL]) as ws:
        channels: dict[int, dict] = {}
        while len(channels) < 5:
            msg = json.loads((await ws.receive(timeout=SOON_S)).data)
            if msg["op"] == "advertise":
                channels.update({c["id"]: c for c in msg["channels"]})
        subs = dict(enumerate(channels))
        await ws.send_str(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": sub, "channelId": cid} for sub, cid in subs.items()]}))
        subscribed.set()
        data: dict[str, list[bytes]] = {}
        while True:
            msg = await ws.receive(timeout=SOON_S)
            if msg.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSING,
                            aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.ERROR):
                break
            if msg.type == aiohttp.WSMsgType.BINARY and msg.data[0] == 1:   # message data
                sub, _t_ns = struct.unpack_from("<IQ", msg.data, 1)
                data.setdefault(channels[subs[sub]]["topic"], []).append(msg.data[13:])
        return {c["topic"]: c for c in channels.values()}, data


def _non_loopback_address() -> str | None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("192.0.2.1", 9))   # no packet is sent: only the route is looked up
            addr = s.getsockname()[0]
        except OSError:
            return None
    return None if addr.startswith("127.") else addr


def test_live_server_on_loopback_lists_its_channels_and_streams_them():
    from teleop.bridge.foxglove_live import LIVE_TOPICS

    bridge = _LiveBridge(duration_s=5.0)
    live = bridge.live
    assert live.url.startswith("ws://127.0.0.1:") and live.port > 0
    # Its own thread and loop: a browser test's Playwright may hold this thread's loop.
    with ThreadPoolExecutor(1) as pool:
        channels, data = pool.submit(asyncio.run, _watch(live.url, bridge.watching)).result()
    assert set(channels) == set(LIVE_TOPICS)
    for topic, ch in channels.items():
        spec = schemas.CHANNEL_BY_TOPIC[topic]
        assert (ch["schemaName"], ch["encoding"], ch["schemaEncoding"]) == (
            spec.schema_name, spec.message_encoding, spec.schema_encoding)
    assert {"/state", "/contacts", "/tf", "/markers"} <= set(data)   # /view needs GL
    state = json.loads(data["/state"][-1])
    assert state["object"] == "box" and len(state["qpos"]) > 20 and "grasp_held_s" in state["extra"]
    # the protobuf channels decode with the schema the server advertised
    tf_cls = _protobuf_class("foxglove.FrameTransforms",
                             base64.b64decode(channels["/tf"]["schema"]))
    frames_ = {t.child_frame_id for t in tf_cls.FromString(data["/tf"][-1]).transforms}
    assert frames_ == {"palm", "object", "operator"}
    markers_cls = _protobuf_class("foxglove.SceneUpdate",
                                  base64.b64decode(channels["/markers"]["schema"]))
    updates = [markers_cls.FromString(d) for d in data["/markers"]]
    ids = {e.id for u in updates for e in u.entities}
    assert {"robot_hand", "contacts", "object", "table"} <= ids
    hand = next(e for e in updates[-1].entities if e.id == "robot_hand")
    assert len(hand.spheres) > 20 and len(hand.lines[0].points) > 40
    # sent on subscribe (and again when the scene places it anew during the run: the client
    # now watches the whole run, not a 1.5 s window)
    objs = [e for u in updates for e in u.entities if e.id == "object"]
    assert objs and all(o.frame_locked and o.models[0].data[:4] == b"glTF" for o in objs)
    # loopback only: nothing answers on this machine's network address
    addr = _non_loopback_address()
    if addr is not None:
        with pytest.raises(OSError), socket.create_connection((addr, live.port), timeout=1):
            pass
    bridge.thread.join(SOON_S)   # the socket closed as the bridge's run ended: it is closing
    assert not bridge.thread.is_alive()
    with pytest.raises(OSError):   # stopped with the bridge
        socket.create_connection(("127.0.0.1", live.port), timeout=1).close()


def test_a_host_off_loopback_is_refused_in_one_line_before_loading(capsys, monkeypatch):
    from dexaug.cli import main
    from teleop.bridge.foxglove_live import FoxgloveLive, check_host

    for host in ("127.0.0.1", "127.0.0.2", "::1", "[::1]", "localhost"):
        assert check_host(host) == host
    for host in ("0.0.0.0", "::", "", "192.168.1.20", "example.com"):
        with pytest.raises(ValueError, match="loopback only"):
            check_host(host)
    # before loading: neither a zenoh session nor the bridge is made (either would end the
    # command with status 1, an unforeseen error, instead of 2)
    def never(what: str) -> Any:
        def called(*args: Any, **kwargs: Any) -> None:
            raise AssertionError(f"{what} before the refusal")
        return called
    monkeypatch.setattr("zenoh.open", never("zenoh.open"))
    monkeypatch.setattr("teleop.bridge.main.bridge_main", never("bridge_main"))
    monkeypatch.setattr("teleop.bridge.bridge.Bridge.__init__", never("Bridge()"))
    assert main(["bridge", "--foxglove", "--foxglove-host", "0.0.0.0"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "per-start token" in err and "0.0.0.0" in err
    with pytest.raises(ValueError, match="loopback only"):
        FoxgloveLive(host="192.168.1.20", port=0)


def test_cli_defaults_are_the_servers(capsys):
    from dexaug.cli import main
    from dexaug.commands import teleop as teleop_cmd
    from teleop.bridge.foxglove_live import DEFAULT_HOST, DEFAULT_PORT

    assert (teleop_cmd.FOXGLOVE_HOST, teleop_cmd.FOXGLOVE_PORT) == (DEFAULT_HOST, DEFAULT_PORT)
    with pytest.raises(SystemExit):
        main(["bridge", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"default {DEFAULT_HOST}" in text and f"default {DEFAULT_PORT}" in text


# ------------------------------------------------------------------------------------ layout


def _resolve(payload: Any, path: str) -> Any:
    """A Foxglove message path's value (``field.sub[2]``, ``field[:]``) in a decoded payload."""
    for name, index in re.findall(r"\.?(\w+)(?:\[([^\]]+)\])?", path):
        payload = payload[name]
        if index and index != ":":
            payload = payload[int(index)]
    return payload


def test_layout_has_its_panels_and_reads_what_the_bridge_records(bridge_session):
    from teleop.record.session import open_session

    layout = json.loads(LAYOUT.read_text())
    panels = layout["configById"]
    kinds = Counter(key.split("!")[0] for key in panels)
    assert kinds["3D"] == 1 and kinds["Image"] == 1 and kinds["Plot"] >= 2
    # every panel is placed in the layout tree
    assert set(re.findall(r'"(\w+![\w-]+)"', json.dumps(layout["layout"]))) == set(panels)
    (image,) = [c for k, c in panels.items() if k.startswith("Image!")]
    assert schemas.CHANNEL_BY_TOPIC[image["imageMode"]["imageTopic"]].schema_name == \
        "foxglove.CompressedImage"
    (scene,) = [c for k, c in panels.items() if k.startswith("3D!")]
    assert scene["followTf"] == schemas.FRAME_WORLD and set(scene["topics"]) <= schemas.FOXGLOVE_TOPICS
    # every plotted path resolves to a number in a /state the bridge recorded
    session = open_session(bridge_session)
    last = {t: session.json_messages(t)[-1][1] for t in ("/state", "/contacts")}
    paths = [p["value"] for k, c in panels.items() if k.startswith("Plot!") for p in c["paths"]]
    assert len(paths) >= 4
    for path in paths:
        topic, _, field = path.partition(".")
        value = _resolve(last[topic], field)
        values = value if isinstance(value, list) else [value]
        assert values and all(isinstance(v, int | float) for v in values), (path, value)
    raw = [c["topicPath"] for k, c in panels.items() if k.startswith("RawMessages!")]
    assert set(raw) <= set(schemas.CHANNEL_BY_TOPIC)
