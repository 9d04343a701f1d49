"""Ingest for native hand-tracking streamer apps that send text lines over UDP or TCP.

Why: some operators already run a Quest app that streams hand landmarks (e.g. "Hand Tracking
Streamer", HTS, github.com/wengmister/hand-tracking-streamer). Its lines are converted here into
the same :class:`teleop.messages.HandFrame` as the WebXR page's and published on
``dexaug/<rig>/hands``; the bridge cannot tell the source.

Format (HTS ``CONNECTIONS.md``), UTF-8, one packet per hand and update::

    Right wrist:, x, y, z, qx, qy, qz, qw
    Right landmarks:, x0, y0, z0, ..., x20, y20, z20

over UDP one datagram per packet (default port 9000), over TCP newline-terminated lines
(default port 8000, usually through ``adb reverse tcp:8000 tcp:8000``). The wrist pose is in
Unity's world (left-handed: +X right, +Y up, +Z forward; metres; quaternion xyzw); the 21
landmarks are positions in the wrist's frame (``GetJointPosesFromWrist``), in OpenXR joint order
without PALM and the four finger metacarpals: wrist, thumb metacarpal/proximal/distal/tip, then
proximal, intermediate, distal, tip of index, middle, ring, little.

Conversion: Unity → WebXR reference space by mirroring z (p → (x, y, −z), q → (−qx, −qy, qz,
qw)), landmarks to world through the wrist pose, then :func:`teleop.input.webxr.from_webxr_joints` (XR
→ MuJoCo once, as for the page). What the app does not send is marked, not invented: the finger
metacarpals (and so PALM) are invalid joints; joint orientations are not streamed, so every
streamed joint carries the wrist's orientation (the retargeter uses only the wrist orientation
and fingertip positions); radii are ``joint_radius_m``. Without metacarpals the retargeter's
operator-scale calibration has no bone chain and keeps its configured hand length. The app sends
each hand separately; a frame carries both hands, the other side's latest packet included while
younger than ``stale_after_s``.
"""

from __future__ import annotations

import logging
import socket
import socketserver
import threading
import time
from collections import Counter
from dataclasses import dataclass

import numpy as np
import zenoh

from sim import transforms
from teleop import keys as zkeys
from teleop.input.webxr import NUM_WEBXR_JOINTS, WEBXR_JOINTS, from_webxr_joints
from teleop.messages import HandFrame, HandState, MessageError, encode
from teleop.net_access import is_loopback

logger = logging.getLogger(__name__)
Array = np.ndarray

#: WebXR joint index of each of the 21 streamed landmarks (HTS order).
HTS_TO_WEBXR: tuple[int, ...] = tuple(WEBXR_JOINTS.index(n) for n in (
    "wrist", "thumb-metacarpal", "thumb-phalanx-proximal", "thumb-phalanx-distal", "thumb-tip",
    *(f"{f}-finger-{j}" for f in ("index", "middle", "ring", "pinky")
      for j in ("phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip"))))
NUM_LANDMARKS = len(HTS_TO_WEBXR)  # 21
_UNITY_TO_XR = np.array([1.0, 1.0, -1.0])
_LOG_EVERY = 100


@dataclass(frozen=True)
class HtsPacket:
    """One hand's update as the app sent it (Unity convention): wrist position (3,) m, wrist
    quaternion (4,) xyzw, landmarks (21, 3) m in the wrist frame."""

    side: str
    wrist_pos: Array
    wrist_quat_xyzw: Array
    landmarks: Array


def _floats(line: str, label: str, n: int, where: str) -> Array:
    body = line[len(label):].lstrip(":").strip().lstrip(",")
    try:
        vals = np.array([float(v) for v in body.split(",") if v.strip()], float)
    except ValueError as exc:
        raise MessageError(f"{where}: {label!r}: not a number ({exc})") from None
    if vals.size != n:
        raise MessageError(f"{where}: {label!r} has {vals.size} values, expected {n}")
    if not np.isfinite(vals).all():
        raise MessageError(f"{where}: {label!r} has non-finite values")
    return vals


class HtsParser:
    """Line-by-line parser: a ``<Side> wrist:`` line then its ``<Side> landmarks:`` line make a
    packet. Stateful because TCP delivers lines, not packets."""

    def __init__(self) -> None:
        self._wrist: dict[str, Array] = {}

    def feed(self, line: str, where: str = "stream") -> HtsPacket | None:
        """A complete packet, or None (first half, or an empty line); MessageError on a line
        that is not the format (naming the label and value count)."""
        line = line.strip()
        if not line:
            return None
        head = line.split(":", 1)[0].strip()
        words = head.split()
        if len(words) != 2 or words[0].lower() not in ("left", "right") or \
                words[1].lower() not in ("wrist", "landmarks"):
            raise MessageError(f"{where}: unknown line {line[:40]!r} (expected 'Left|Right "
                               "wrist:' or 'Left|Right landmarks:')")
        side, kind = words[0].lower(), words[1].lower()
        label = head
        if kind == "wrist":
            self._wrist[side] = _floats(line, label, 7, where)
            return None
        wrist = self._wrist.pop(side, None)
        if wrist is None:
            raise MessageError(f"{where}: {side} landmarks without a preceding {side} wrist line")
        lm = _floats(line, label, 3 * NUM_LANDMARKS, where).reshape(NUM_LANDMARKS, 3)
        return HtsPacket(side, wrist[:3], wrist[3:], lm)


def packet_to_hand(packet: HtsPacket, *, joint_radius_m: float = 0.008) -> HandState:
    """One packet → a 26-joint :class:`HandState` in the MuJoCo world (see the module docstring
    for what is marked invalid and what is nominal)."""
    q_u = packet.wrist_quat_xyzw
    n = float(np.linalg.norm(q_u))
    if not n > 1e-6:
        raise MessageError(f"{packet.side} wrist: zero quaternion")
    # Unity (left-handed, z forward) → XR (right-handed, −z forward): mirror z
    p_w = packet.wrist_pos * _UNITY_TO_XR
    q_w = np.array([-q_u[0], -q_u[1], q_u[2], q_u[3]]) / n
    lm_xr = packet.landmarks * _UNITY_TO_XR
    q_wxyz = transforms.quat_xyzw_to_wxyz(q_w)
    world = p_w + transforms.rotate(q_wxyz, lm_xr)
    pos = np.full((NUM_WEBXR_JOINTS, 3), np.nan)
    quat = np.full((NUM_WEBXR_JOINTS, 4), np.nan)
    rad = np.full(NUM_WEBXR_JOINTS, np.nan)
    idx = list(HTS_TO_WEBXR)
    pos[idx] = world
    pos[0] = p_w  # the wrist is the pose itself (landmark 0 is the wrist frame's origin)
    quat[idx] = q_w
    rad[idx] = joint_radius_m
    return from_webxr_joints(pos, quat, rad)


class _TcpServer(socketserver.ThreadingTCPServer):
    allow_reuse_address = True  # a restarted ingest gets its port back at once
    daemon_threads = True


class StreamIngest:
    """UDP and/or TCP listeners → :class:`HandFrame` on ``dexaug/<rig>/hands``.

    ``udp_port``/``tcp_port``: where to listen (None: not that protocol; 0: a free port, read
    back from :attr:`udp_port`/:attr:`tcp_port`). ``host``: the listen address, loopback by
    default (``adb reverse`` brings a USB headset there); the streamer apps cannot send a token,
    so another address (``0.0.0.0`` for Wi-Fi) lets anyone on that network inject hand frames,
    and a warning says so. ``session``: a zenoh session to use, else a loopback peer on
    ``listen_port``/``connect_ports`` (closed in :meth:`close`).
    """

    def __init__(self, rig: str = "local", *, udp_port: int | None = 9000,
                 tcp_port: int | None = None, host: str = "127.0.0.1",
                 session: zenoh.Session | None = None, listen_port: int | None = None,
                 connect_ports: tuple[int, ...] = (), stale_after_s: float = 0.1,
                 joint_radius_m: float = 0.008) -> None:
        self.keys = zkeys.RigKeys(rig)
        self.stale_after_s, self.joint_radius_m = stale_after_s, joint_radius_m
        self.counts: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._latest: dict[str, tuple[HandState, float]] = {}
        self._seq = 0
        self._own_session = session is None
        self.session = session or zkeys.open_session(listen_port, list(connect_ports))
        self._pub = self.session.declare_publisher(
            self.keys.hands, congestion_control=zenoh.CongestionControl.BLOCK,
            reliability=zenoh.Reliability.RELIABLE, express=True)
        self._servers: list[socketserver.BaseServer] = []
        self._threads: list[threading.Thread] = []
        self.udp_port = self.tcp_port = None
        ingest = self

        class Udp(socketserver.BaseRequestHandler):
            def handle(self) -> None:
                data, _sock = self.request
                parser = HtsParser()  # a datagram is a whole packet
                for line in data.decode("utf-8", "replace").splitlines():
                    ingest._line(parser, line, f"udp {self.client_address[0]}")
                with ingest._lock:
                    ingest.counts["datagrams"] += 1

        class Tcp(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                peer = f"tcp {self.client_address[0]}:{self.client_address[1]}"
                logger.info("streamer app connected (%s)", peer)
                self.connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                parser = HtsParser()
                for raw in self.rfile:
                    ingest._line(parser, raw.decode("utf-8", "replace"), peer)
                logger.info("streamer app disconnected (%s)", peer)

        if udp_port is not None:
            srv = socketserver.UDPServer((host, udp_port), Udp)  # one thread: in order
            self.udp_port = srv.server_address[1]
            self._servers.append(srv)
        if tcp_port is not None:
            tsrv = _TcpServer((host, tcp_port), Tcp)
            self.tcp_port = tsrv.server_address[1]
            self._servers.append(tsrv)
        if not self._servers:
            raise ValueError("StreamIngest needs a udp_port or a tcp_port")
        for server in self._servers:
            t = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.2},
                                 name="dexaug-stream", daemon=True)
            t.start()
            self._threads.append(t)
        logger.info("streamer ingest for rig %s on %s: udp %s, tcp %s", rig, host, self.udp_port,
                    self.tcp_port)
        if not is_loopback(host):
            logger.warning("streamer ingest listens on %s: anyone who reaches this machine there "
                           "can send hand frames to rig %s (the apps have no token)", host, rig)

    def _line(self, parser: HtsParser, line: str, where: str) -> None:
        t_rx = time.time()
        try:
            packet = parser.feed(line, where)
            if packet is None:
                return
            hand = packet_to_hand(packet, joint_radius_m=self.joint_radius_m)
        except MessageError as exc:
            with self._lock:
                self.counts["bad_lines"] += 1
                n = self.counts["bad_lines"]
            if n <= 3 or n % _LOG_EVERY == 0:
                logger.warning("skipped bad streamer line #%d: %s", n, exc)
            return
        with self._lock:
            self._latest[packet.side] = (hand, t_rx)
            sides = {s: h for s, (h, t) in self._latest.items()
                     if s == packet.side or t_rx - t <= self.stale_after_s}
            self._seq += 1
            seq = self._seq
        # the app sends no head pose: identity at the origin (the view keeps its default)
        frame = HandFrame(seq=seq, device_time_s=t_rx, receive_time_s=t_rx,
                          head_position=np.zeros(3), head_orientation_wxyz=np.array([1.0, 0, 0, 0]),
                          left=sides.get("left"), right=sides.get("right"), source="hts")
        self._pub.put(encode(frame))
        with self._lock:
            self.counts["frames"] += 1

    def close(self) -> None:
        for srv in self._servers:
            srv.shutdown()
            srv.server_close()
        for t in self._threads:
            t.join(5.0)
        self._pub.undeclare()
        if self._own_session:
            self.session.close()

    def __enter__(self) -> StreamIngest:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
