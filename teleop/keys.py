"""zenoh key expressions of a teleop rig, and a loopback session helper, defined in one place.

Why one module: the ingest, the bridge, replay, the headset page and the benchmarks all meet on
these keys; a key spelled differently in one of them would silently receive nothing. Layout
(``<rig>`` names one operator station, e.g. ``lab1``):

=============================  ==========  =================================================
key                            kind        payload
=============================  ==========  =================================================
``dexaug/<rig>/hands``         pub/sub     :func:`teleop.messages.encode` bytes (HandFrame)
``dexaug/<rig>/head``          pub/sub     head pose JSON (reserved for native streamers)
``dexaug/<rig>/view``          pub/sub     JPEG bytes of the head-following camera
``dexaug/<rig>/state``         pub/sub     bridge state JSON (qpos, palm/object pose, contacts)
``dexaug/<rig>/events``        pub/sub     event JSON (recording started/stopped, grasp marks)
``dexaug/<rig>/control/<cmd>`` queryable   JSON request payload → JSON reply
=============================  ==========  =================================================

Control commands: ``start_recording``, ``stop_recording``, ``choose_object``,
``reset_object``, ``set_object_mode``, ``set_object_rest``, ``next_object_rest``,
``mark_grasp``, ``status`` (see
:mod:`teleop.bridge.control`). A query is untrusted: it names a recording (``name``) or a
catalogue object, never a file path (:func:`teleop.bridge.control.remote_args`).

Tests and the CLI open peers on loopback with multicast scouting **off** (:func:`open_session`):
scouting would let concurrent test runs on one machine discover and talk to each other.
"""

from __future__ import annotations

import json
import socket
from dataclasses import dataclass

import zenoh

PREFIX = "dexaug"
CONTROL_COMMANDS: tuple[str, ...] = ("start_recording", "stop_recording", "choose_object",
                                     "reset_object", "set_object_mode", "set_object_rest",
                                     "next_object_rest", "recalibrate_scale", "mark_grasp",
                                     "status")


class KeyError_(ValueError):
    """A rig name that would break the key layout (empty, or with ``/``, ``*``, ``?``, ``#``, ``$``)."""


@dataclass(frozen=True)
class RigKeys:
    """The key expressions of one rig."""

    rig: str

    def __post_init__(self) -> None:
        if not self.rig or any(c in self.rig for c in "/*?#$ "):
            raise KeyError_(f"rig name {self.rig!r} must be non-empty, without '/', '*', '?', "
                            "'#', '$' or spaces")

    @property
    def base(self) -> str:
        return f"{PREFIX}/{self.rig}"

    @property
    def hands(self) -> str:
        return f"{self.base}/hands"

    @property
    def head(self) -> str:
        return f"{self.base}/head"

    @property
    def view(self) -> str:
        return f"{self.base}/view"

    @property
    def state(self) -> str:
        return f"{self.base}/state"

    @property
    def events(self) -> str:
        return f"{self.base}/events"

    @property
    def control(self) -> str:
        """The queryable's key expression (all commands)."""
        return f"{self.base}/control/**"

    def control_cmd(self, command: str) -> str:
        """The key to query for one control command."""
        return f"{self.base}/control/{command}"


def free_tcp_port() -> int:
    """A currently free TCP port on 127.0.0.1 (tests: distinct peers need distinct ports)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def loopback_config(listen_port: int | None = None, connect_ports: list[int] | tuple[int, ...] = (),
                    *, host: str = "127.0.0.1") -> zenoh.Config:
    """A peer config listening on ``tcp/<host>:<listen_port>`` (if given) and connecting to
    ``connect_ports``, multicast scouting off (no discovery of other processes' peers)."""
    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"peer"')
    cfg.insert_json5("scouting/multicast/enabled", "false")
    listen = [f"tcp/{host}:{listen_port}"] if listen_port is not None else []
    cfg.insert_json5("listen/endpoints", json.dumps(listen))
    cfg.insert_json5("connect/endpoints", json.dumps([f"tcp/{host}:{p}" for p in connect_ports]))
    return cfg


def open_session(listen_port: int | None = None,
                 connect_ports: list[int] | tuple[int, ...] = ()) -> zenoh.Session:
    """Open a zenoh peer on loopback (see :func:`loopback_config`)."""
    return zenoh.open(loopback_config(listen_port, connect_ports))


def query_json(session: zenoh.Session, key: str, payload: dict | None = None, *,
               timeout_s: float = 5.0) -> dict:
    """Send one control query and return the first reply's JSON; an error reply or no reply
    raises RuntimeError (a control call that silently did nothing is worse than a failure)."""
    body = json.dumps(payload or {}).encode()
    for reply in session.get(key, payload=body, timeout=timeout_s):
        if reply.ok is not None:
            return json.loads(reply.ok.payload.to_bytes())
        err = reply.err.payload.to_bytes() if reply.err is not None else b""
        raise RuntimeError(f"{key}: error reply {err!r}")
    raise RuntimeError(f"{key}: no reply within {timeout_s} s")
