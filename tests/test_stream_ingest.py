"""Native streamer-app ingest (HTS text lines) over real UDP and TCP sockets into zenoh, fed with
the real Quest 3 capture written in the app's format (Unity convention, wrist-relative landmarks,
the app's 4/3 decimals), and checked against the capture converted by the project's converter."""

from __future__ import annotations

import socket
import threading

import numpy as np
import pytest

from sim import transforms
from sim.paths import SHARED_ASSETS
from teleop import keys
from teleop.input.stream_ingest import HTS_TO_WEBXR, HtsParser, StreamIngest
from teleop.input.webxr import from_webxr_joints
from teleop.messages import JOINT_INDEX, MessageError, decode
from tests.conftest import SOON_S, wait_for, wait_for_match

DERIVED = SHARED_ASSETS / "handdata" / "quest3_webxr" / "derived" / "quest3_hands_world.npz"
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not DERIVED.is_file(), reason=f"no derived capture {DERIVED}")]


def _hts_packet(side: str, pos_xr: np.ndarray, quat_xyzw: np.ndarray) -> str:
    """One hand of the capture (25 WebXR joints, XR reference space) as the HTS app writes it:
    wrist pose in Unity's world (z mirrored), landmarks in the wrist frame, F4/F3 decimals."""
    p_w, q_w = pos_xr[0] * [1, 1, -1], quat_xyzw[0]
    q_u = np.array([-q_w[0], -q_w[1], q_w[2], q_w[3]])
    q_u_wxyz = transforms.quat_xyzw_to_wxyz(q_u / np.linalg.norm(q_u))
    world_u = pos_xr[list(HTS_TO_WEBXR)] * [1, 1, -1]
    local = transforms.rotate(transforms.quat_conj(q_u_wxyz), world_u - p_w)
    name = side.capitalize()
    wrist = ", ".join(f"{v:.4f}" for v in p_w) + ", " + ", ".join(f"{v:.3f}" for v in q_u)
    lms = ", ".join(f"{v:.4f}" for v in local.reshape(-1))
    return f"{name} wrist:, {wrist}\n{name} landmarks:, {lms}"


@pytest.fixture(scope="module")
def packets():
    d = np.load(DERIVED)
    out = []
    for k in range(0, len(d["t_s"]), 7):
        for side in ("left", "right"):
            if d[f"{side}_valid"][k]:
                out.append((k, side, _hts_packet(side, d[f"{side}_joint_pos"][k].astype(float),
                                                 d[f"{side}_joint_quat_xyzw"][k].astype(float))))
    return d, out


def _expected(d, k: int, side: str) -> np.ndarray:
    h = from_webxr_joints(d[f"{side}_joint_pos"][k], d[f"{side}_joint_quat_xyzw"][k],
                          d[f"{side}_joint_radius"][k])
    return h.positions


def test_parser_errors_name_the_line():
    p = HtsParser()
    with pytest.raises(MessageError, match="unknown line"):
        p.feed("Middle wrist:, 1, 2, 3")
    with pytest.raises(MessageError, match="has 3 values, expected 7"):
        p.feed("Right wrist:, 1, 2, 3")
    with pytest.raises(MessageError, match="without a preceding right wrist"):
        p.feed("Right landmarks:, " + ", ".join(["0"] * 63))
    with pytest.raises(MessageError, match="not a number"):
        p.feed("Left wrist:, 1, 2, x, 0, 0, 0, 1")


@pytest.mark.parametrize("proto", ["udp", "tcp"])
def test_streamer_lines_arrive_as_hand_frames(packets, proto):
    d, pk = packets
    zport = keys.free_tcp_port()
    ingest = StreamIngest(f"hts{proto}", udp_port=0 if proto == "udp" else None,
                          tcp_port=0 if proto == "tcp" else None, host="127.0.0.1",
                          listen_port=zport)
    client = keys.open_session(connect_ports=[zport])
    got, lock = [], threading.Lock()

    def on(sample):
        with lock:
            got.append(decode(sample.payload.to_bytes()))

    sub = client.declare_subscriber(keys.RigKeys(f"hts{proto}").hands, on)
    try:
        wait_for_match(ingest._pub, SOON_S, "the ingest's /hands reaching the client")
        if proto == "udp":
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                for k, (_, _, text) in enumerate(pk, 1):
                    s.sendto(text.encode(), ("127.0.0.1", ingest.udp_port))
                    # paced on the ingest's count, so a starved reader never overflows the
                    # socket's buffer (datagrams over it are dropped)
                    wait_for(lambda k=k: ingest.counts["datagrams"] >= k, SOON_S,
                             f"datagram {k} read", every_s=0.0005)
                s.sendto(b"Right wrist:, garbage", ("127.0.0.1", ingest.udp_port))
        else:
            with socket.create_connection(("127.0.0.1", ingest.tcp_port)) as s:
                for _, _, text in pk:
                    s.sendall(text.encode() + b"\n")
                s.sendall(b"Right wrist:, garbage\n")
        # the garbage line, sent last, read too: the frames may reach the client before it
        wait_for(lambda: len(got) >= len(pk) and ingest.counts["bad_lines"] >= 1, SOON_S,
                 lambda: f"{len(pk)} frames; got {len(got)}, counts {dict(ingest.counts)}")
    finally:
        sub.undeclare()
        client.close()
        counts = dict(ingest.counts)
        ingest.close()
    assert len(got) == len(pk) and counts["bad_lines"] == 1, (len(got), len(pk), counts)
    errs = []
    for frame, (k, side, _) in zip(got, pk, strict=True):
        hand = frame.hand(side)
        assert hand is not None and hand.tracked and frame.source == "hts"
        want = _expected(d, k, side)
        streamed = [0, *[i + 1 for i in HTS_TO_WEBXR]]  # OpenXR indices (PALM = 0)
        assert not hand.valid[JOINT_INDEX["palm"]] and not hand.valid[JOINT_INDEX["index_metacarpal"]]
        assert hand.valid[streamed[1:]].all()
        errs.append(np.abs(hand.positions[streamed[1:]] - want[streamed[1:]]).max())
        # the wrist orientation survives the Unity round trip (3 decimals)
        q_ref = from_webxr_joints(d[f"{side}_joint_pos"][k], d[f"{side}_joint_quat_xyzw"][k],
                                  d[f"{side}_joint_radius"][k]).orientations_wxyz[1]
        assert abs(float(np.dot(hand.orientations_wxyz[1], q_ref))) > 0.9999
    # 1e-4 m printing + 1e-3 quaternion printing over ~0.2 m of hand
    assert max(errs) < 1.0e-3, max(errs)
