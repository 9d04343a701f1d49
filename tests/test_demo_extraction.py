"""Demo extraction on sessions the real bridge recorded: one clock, the simulation's.

The bridge (real zenoh peers on loopback, real MuJoCo, deterministic mode) is fed a synthetic
operator's noise-free sugar-box grasp (``teleop.synthetic``): the approach frames, then the
object put back on its spot (``reset_object``: the approach knocks light objects over, see
``teleop/synthetic/scripted.py``), the closing frames and the closed hand held for a second.
Replayed recordings do not serve here: their operator input does not close on the object in
the bridge (the synthetic rerecord of ``recordings/synth_005_tomato_soup_can.mcap`` touches
it in 6 of 504 steps). The speed checks rewrite a file's log times with the ``mcap`` library.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from sim.paths import REPO_ROOT
from teleop import keys
from teleop.messages import encode
from teleop.record.demos import DemoError, extract_demos
from teleop.record.session import open_session
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]

OBJECT = "004_sugar_box"
SCRIPTED = REPO_ROOT / "recordings" / "demo_005_tomato_soup_can.mcap"


def _record(path: Path, *, mark: bool, on_recording_closed: Callable[[Path], None] | None = None
            ) -> Path:
    """The grasp of the module docstring through a real bridge, recorded to ``path``; with
    ``mark`` a ``mark_grasp`` control once the hand has closed; ``on_recording_closed`` is the
    bridge's hook (``--auto-augment``'s)."""
    from teleop.bridge.bridge import Bridge
    from teleop.bridge.config import load_bridge_config
    from teleop.record.replay import hands_publisher, play
    from teleop.synthetic.config import SynthConfig
    from teleop.synthetic.synthesize import synthesize

    quiet = SynthConfig(position_noise_m=0.0, orientation_noise_deg=0.0, dropout_fraction=0.0,
                        time_jitter_s=0.0, latency_jitter_s=0.0)
    ep = synthesize(OBJECT, hand="shadow_right", seed=0, config=quiet)
    approach_end, closed = ep.phases["approach"][1], ep.phases["grasp"][1]
    approach = [f for f in ep.frames if f.device_time_s < approach_end]
    close = [f for f in ep.frames if approach_end <= f.device_time_s < closed]
    dt = 1.0 / quiet.rate_hz
    last = close[-1]
    hold = [dataclasses.replace(last, seq=last.seq + k, device_time_s=last.device_time_s + k * dt,
                                receive_time_s=last.receive_time_s + k * dt)
            for k in range(1, 81)]
    cfg = load_bridge_config()   # the object where the operator reaches for it
    cfg = dataclasses.replace(cfg, deterministic=True, view_enabled=False,
                              object_pos_m=(np.asarray(ep.object_pos_m) + cfg.world_offset_m)[:2])
    port = keys.free_tcp_port()
    with Bridge("shadow_right", OBJECT, "demo", cfg, listen_port=port,
                calibration_frames=ep.frames, on_recording_closed=on_recording_closed) as bridge:
        client = keys.open_session(connect_ports=[port])
        try:
            bridge.start()
            assert bridge.control("start_recording", {"path": str(path)})["ok"]
            pub = hands_publisher(client, "demo", 5.0)
            sent = 0
            for part in (approach, close, hold):
                sent += play(pub, [(0.0, encode(f)) for f in part], "max")
                assert bridge.wait_idle(60.0, received=sent)
                if part is approach:
                    assert bridge.control("reset_object")["ok"]
                if part is close and mark:
                    assert bridge.control("mark_grasp", {"source": "test"})["ok"]
            pub.undeclare()
            assert bridge.control("stop_recording")["ok"]
        finally:
            client.close()
    return path


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _record(tmp_path_factory.mktemp("bridge") / "plain.mcap", mark=False)


@pytest.fixture(scope="module")
def marked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _record(tmp_path_factory.mktemp("bridge") / "marked.mcap", mark=True)


def _rewrite(src: Path, dst: Path, log_time: Callable[[str, int], int],
             event: Callable[[dict], dict] | None = None,
             contacts: Callable[[dict], dict] | None = None,
             state: Callable[[dict], dict] | None = None) -> Path:
    """``src`` copied to ``dst`` (mcap's own reader and writer) with each message's log and
    publish time mapped by ``log_time(topic, t_ns)`` and, when given, each ``/events`` JSON
    by ``event``, each ``/contacts`` JSON by ``contacts`` and each ``/state`` by ``state``."""
    import json

    with open(src, "rb") as f_in, open(dst, "wb") as f_out:
        reader = make_reader(f_in)
        header = reader.get_header()
        writer = Writer(f_out, compression=CompressionType.ZSTD, enable_data_crcs=True)
        writer.start(profile=header.profile, library=header.library)
        schema_ids: dict[int, int] = {}
        channel_ids: dict[int, int] = {}
        for rec in reader.iter_metadata():
            writer.add_metadata(rec.name, rec.metadata)
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            if schema.id not in schema_ids:
                schema_ids[schema.id] = writer.register_schema(schema.name, schema.encoding,
                                                               schema.data)
            if channel.id not in channel_ids:
                channel_ids[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schema_ids[schema.id],
                    channel.metadata)
            data = msg.data
            edit = {"/events": event, "/contacts": contacts, "/state": state}.get(channel.topic)
            if edit is not None:
                data = json.dumps(edit(json.loads(data))).encode()
            t = log_time(channel.topic, msg.log_time)
            writer.add_message(channel_ids[channel.id], t, data, t, msg.sequence)
        writer.finish()
    return dst


def _scaled(src: Path, dst: Path, factor: float) -> Path:
    """``src`` as if recorded ``1/factor`` times as fast: log times scaled about the first."""
    t0 = open_session(src).start_time_ns
    return _rewrite(src, dst, lambda _topic, t: t0 + round((t - t0) * factor))


def _moments(demos) -> list[tuple]:
    """What makes two extractions the same grasp: how, sim-time duration, fingers, joints."""
    return [(d.how, d.duration_s, d.fingers, d.joints.tolist()) for d in demos]


def test_a_bridge_recording_yields_a_demo(plain: Path) -> None:
    """Every step's /state and /contacts carry the same sim time and seq (and one log time),
    and the stable grasp is found."""
    demos = extract_demos(plain)
    assert len(demos) >= 1
    d = demos[0]
    assert d.how == "stable contact" and d.object == OBJECT and d.duration_s >= 0.3
    assert "thumb" in d.fingers and len(d.fingers) >= 2
    s = open_session(plain)
    states, contacts = s.json_messages("/state"), s.json_messages("/contacts")
    assert len(states) == len(contacts) > 200
    for (ts, st), (tc, co) in zip(states, contacts, strict=True):
        assert (st["t_s"], st["seq"], ts) == (co["t_s"], co["seq"], tc)


def test_no_demo_spans_a_scene_restore(plain: Path, tmp_path: Path) -> None:
    """A ``scene_restored`` in the middle of the grasp (the bridge re-placed the object and
    parked the hand) cuts the contact run there: the demo found is no longer the one spanning
    the whole hold."""
    (d,) = extract_demos(plain)[:1]
    s = open_session(plain)
    states = s.json_messages("/state")
    t0 = states[0][1]["t_s"]     # one scene throughout: the demo's time is t_s since the first
    t_demo = next(st["t_s"] for _, st in states if st["t_s"] - t0 >= d.time_s - 1e-9)

    def restore_mid_grasp(ev: dict) -> dict:
        return {**ev, "type": "scene_restored", "t_s": t_demo} if ev["type"] == "object_reset" else ev

    broken = _rewrite(plain, tmp_path / "restored.mcap", lambda _topic, t: t, restore_mid_grasp)
    try:
        after = extract_demos(broken)
    except DemoError:   # what is left on either side is too short for a demo
        after = []
    assert all(x.duration_s < d.duration_s for x in after)
    assert all(abs(x.time_s - d.time_s) > 1e-6 for x in after)


def test_contacts_pair_by_seq_not_log_time(plain: Path, tmp_path: Path) -> None:
    """Contacts logged a microsecond after their state (the old bridge took two clock readings)
    still pair with it."""
    shifted = _rewrite(plain, tmp_path / "shifted.mcap",
                       lambda topic, t: t + 1000 if topic == "/contacts" else t)
    assert _moments(extract_demos(shifted)) == _moments(extract_demos(plain))


def test_b_grasp_mark_is_honoured(marked: Path, tmp_path: Path) -> None:
    """A mark_grasp control is an event of the step it happened at (same seq and sim time as
    that step's state) and the demo is the state it names; without its seq the mark is found by
    its sim time, and the same state comes back."""
    s = open_session(marked)
    (mark,) = [e for _, e in s.events() if e["type"] == "grasp_mark"]
    (state,) = [st for _, st in s.json_messages("/state") if st["seq"] == mark["payload"]["seq"]]
    assert mark["t_s"] == state["t_s"] and mark["payload"]["source"] == "test"
    demos = extract_demos(marked)
    assert [d.how for d in demos] == ["grasp_mark"]
    np.testing.assert_array_equal(demos[0].joints, state["qpos"])

    def no_seq(ev: dict) -> dict:
        return {**ev, "payload": {k: v for k, v in ev["payload"].items() if k != "seq"}}

    late = _rewrite(marked, tmp_path / "no_seq.mcap", lambda topic, t: t + 10**9
                    if topic == "/events" else t, event=no_seq)   # log time says nothing
    assert _moments(extract_demos(late)) == _moments(demos)


def test_mark_takes_the_fullest_state_near_it(marked: Path, tmp_path: Path) -> None:
    """A mark names a grasp, not a physics step: with one finger's contacts dropped at the
    marked state (a fingertip leaving the object for one step, as a resting one does), the demo
    is the nearest state within ``mark_snap_s`` that has every finger in contact; with
    ``mark_snap_s`` 0 it is the marked state itself, without that finger."""
    from teleop.record.demos import DemoParams

    s = open_session(marked)
    (mark,) = [e for _, e in s.events() if e["type"] == "grasp_mark"]
    (demo,) = extract_demos(marked)
    assert len(demo.fingers) >= 3, demo.fingers
    gone = next(f for f in demo.fingers if f != "thumb")

    def drop(msg: dict) -> dict:
        if msg.get("seq") == mark["payload"]["seq"] and msg.get("t_s") == mark["t_s"]:
            msg = {**msg, "contacts": [c for c in msg["contacts"] if c["finger"] != gone]}
        return msg

    edited = _rewrite(marked, tmp_path / "flicker.mcap", lambda _topic, t: t, contacts=drop)
    (near,) = extract_demos(edited)
    assert near.fingers == demo.fingers and near.how == "grasp_mark"
    assert 0.0 < abs(near.time_s - demo.time_s) <= DemoParams().mark_snap_s + 0.01
    (exact,) = extract_demos(edited, DemoParams(mark_snap_s=0.0))
    assert set(exact.fingers) == set(demo.fingers) - {gone}
    (state,) = [st for _, st in s.json_messages("/state")
                if st["seq"] == mark["payload"]["seq"] and st["t_s"] == mark["t_s"]]
    np.testing.assert_array_equal(exact.joints, state["qpos"])


@pytest.mark.parametrize("factor", [0.1, 0.3, 3.0])
def test_c_recording_speed_does_not_change_the_demo(plain: Path, marked: Path, tmp_path: Path,
                                                     factor: float) -> None:
    """Durations, gaps and mark windows are simulated time: a session whose log times are
    squeezed to a tenth or a third, or stretched threefold, gives the same demos (the bridge
    recordings, and the committed scripted one, whose mark carries no seq). The old
    log-time extraction gave the scripted one a 0.0 s, 0.616 s and a 3.168 s + 2.664 s
    demo."""
    for src in (plain, marked, SCRIPTED):
        fast = _scaled(src, tmp_path / f"{src.stem}_{factor}.mcap", factor)
        assert _moments(extract_demos(fast)) == _moments(extract_demos(src)), src.name


def test_the_moment_of_a_bridged_run_has_the_thumb() -> None:
    """A gap-bridged run holds states inside its gaps; the fullest of those may lack the thumb
    (four fingers without it against thumb + two): the moment is taken among the states that
    meet the rule, never a thumbless demo of a thumb grasp."""
    from teleop.record.demo_track import Track
    from teleop.record.demos import _best_in

    touching = [frozenset({"thumb", "forefinger", "middle"}), frozenset({"thumb", "middle"}),
                frozenset({"forefinger", "middle", "ring", "little"}),
                frozenset({"thumb", "forefinger", "middle"})]
    n = len(touching)
    track = Track(np.arange(n), np.arange(n) * 4_000_000, None, list(range(n)),
                   [{}] * n, [[]] * n, touching)
    ok = np.array(["thumb" in f and len(f) >= 2 for f in touching])
    i = _best_in(track, 0, n, ok)
    assert "thumb" in touching[i] and len(touching[i]) == 3


def _first_grasp_s(path: Path) -> float:
    """Simulated time (s) of the first contacts message with the thumb and another fingertip."""
    for _, msg in open_session(path).json_messages("/contacts"):
        fingers = {c.get("finger") for c in msg["contacts"]} - {None}
        if "thumb" in fingers and len(fingers) >= 2:
            return float(msg["t_s"])
    raise AssertionError(f"{path}: no thumb grasp")


def test_a_short_contact_the_hand_lifts_is_a_grasp(plain: Path, tmp_path: Path) -> None:
    """People lift 0.12–0.64 s after the first contact: the bridged grasp cut to 0.1 s of
    contact (shorter than min_duration_s) is no demo while the hand stays put, and is one —
    "lift-confirmed contact", thumb included — when the palm rises 3 cm right after it (and
    the object with it, in the free-object mode)."""
    free = open_session(plain).metadata.get("object_mode", "free") != "demo"
    t_a = _first_grasp_s(plain)

    def short(msg: dict) -> dict:
        keep = t_a <= float(msg["t_s"]) <= t_a + 0.1
        return {**msg, "contacts": msg["contacts"] if keep else []}

    def lifted(msg: dict) -> dict:
        if float(msg["t_s"]) < t_a + 0.06:
            return msg
        up = [0.0, 0.0, 0.03]
        out = {**msg, "palm_pos_m": list(np.add(msg["palm_pos_m"], up))}
        if free:
            out["object_pos_m"] = list(np.add(msg["object_pos_m"], up))
        return out

    same = lambda _topic, t: t   # noqa: E731
    still = _rewrite(plain, tmp_path / "still.mcap", same, contacts=short)
    with pytest.raises(DemoError, match="did not lift"):
        extract_demos(still)
    (demo,) = extract_demos(_rewrite(plain, tmp_path / "lift.mcap", same, contacts=short,
                                     state=lifted))
    assert demo.how == "lift-confirmed contact"
    assert "thumb" in demo.fingers and 0.05 <= demo.duration_s <= 0.1 + 1e-9
