"""``bridge --foxglove``: the bridge's live state on the ``foxglove-sdk``'s WebSocket server.

Why: an operator's assistant watches the session as it happens in the Foxglove app (open
``configs/foxglove/dexaug_layout.json``): the simulated hand, the object, the contacts, the head
camera and the grasp state, on the same channels, schemas and payloads as a recording
(:mod:`teleop.record.schemas`), so one layout serves the live bridge and a recorded session.

Channels: ``/state`` and ``/contacts`` (our JSON, built by the recorder's own functions),
``/tf`` (world→palm, world→object, world→operator: the tracking space), ``/markers``
(``foxglove.SceneUpdate``: the robot hand as a stick figure of its bodies and fingertip pads,
the operator's tracked hands, the contacts with force arrows; the object's mesh locked to the
``object`` frame and the table, sent again whenever a client subscribes or the object changes)
and ``/view`` (the head camera's JPEGs as ``foxglove.CompressedImage``). Steps are published at
most ``rate_hz`` (30 Hz: what a viewer needs, a fraction of the loop's rate), and nothing is
built for a channel no client subscribes to. A failure here is logged, never raised into the
bridge loop.

Security: the SDK's server has no per-start token, Host or Origin check, so it serves loopback
only (:func:`check_host`); a non-loopback host is refused with ValueError
(from another machine, use an SSH tunnel). It advertises no capability: a client can only
watch, never publish or call anything.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Mapping, Sequence
from typing import Any

import foxglove as fx
import numpy as np
from foxglove import messages as fm
from foxglove.websocket import ChannelView, Client, ServerListener

from sim.world.scene import HAND_PREFIX, Scene
from teleop.messages import HandFrame
from teleop.net_access import is_loopback
from teleop.record import foxglove, schemas
from teleop.record.contact_record import ContactRecord, contacts_payload

__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "FRAME_OPERATOR", "LIVE_TOPICS", "FoxgloveLive",
           "check_host", "hand_figure_entity"]

logger = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
#: the operator's tracking space (MuJoCo axes), ``world_offset_m`` from the world
FRAME_OPERATOR = "operator"
#: what the server publishes (a recording's channels but the raw input and the events)
LIVE_TOPICS = (schemas.TOPIC_STATE, schemas.TOPIC_CONTACTS, schemas.TOPIC_TF,
               schemas.TOPIC_MARKERS, schemas.TOPIC_VIEW)
_ROBOT_RGBA = (0.75, 0.78, 0.85, 1.0)
_OPERATOR_RGBA = (1.0, 0.8, 0.6, 0.6)


def check_host(host: str) -> str:
    """``host`` when only this machine reaches it (``127.0.0.0/8``, ``::1``, ``localhost``);
    ValueError for any other address, wildcards included (module docstring): the rule of
    :func:`teleop.net_access.is_loopback`."""
    if not is_loopback(host):
        raise ValueError(f"--foxglove-host {host}: the Foxglove server (foxglove-sdk) cannot "
                         "require a per-start token, so it listens on loopback only; from "
                         "another machine use an SSH tunnel (ssh -L 8765:127.0.0.1:8765 …)")
    return host


def _hand_links(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scene ids of the hand's bodies, (body, parent) pairs among them, and (tip body, pad
    site) pairs: what :func:`hand_figure_entity` draws."""
    m, hand = scene.model, scene.hand
    bodies = np.flatnonzero(scene.hand_body_mask)
    inside = set(bodies.tolist())
    links = np.array([(b, m.body_parentid[b]) for b in bodies if m.body_parentid[b] in inside],
                     dtype=int).reshape(-1, 2)
    pads = np.array([(m.body(HAND_PREFIX + hand.model.body(b).name).id,
                      m.site(HAND_PREFIX + hand.model.site(s).name).id)
                     for b, s in zip(hand.tip_body_ids, hand.tip_site_ids, strict=True)],
                    dtype=int).reshape(-1, 2)
    return bodies, links, pads


def hand_figure_entity(scene: Scene, t_ns: int, links: tuple[np.ndarray, np.ndarray, np.ndarray]
                       | None = None) -> fm.SceneEntity:
    """The simulated robot hand, world frame: a sphere at each body origin and at each
    fingertip pad, lines from each body to its parent and from each tip body to its pad."""
    bodies, pairs, pads = links if links is not None else _hand_links(scene)
    xpos, spos = scene.data.xpos, scene.data.site_xpos
    rgba = foxglove.color(*_ROBOT_RGBA)
    spheres = [foxglove.sphere(p, 0.012, rgba) for p in xpos[bodies]]
    spheres += [foxglove.sphere(p, 0.01, foxglove.color(0.9, 0.3, 0.3)) for p in spos[pads[:, 1]]]
    segments = np.concatenate([np.stack([xpos[pairs[:, 0]], xpos[pairs[:, 1]]], axis=1),
                               np.stack([xpos[pads[:, 0]], spos[pads[:, 1]]], axis=1)])
    return foxglove.scene_entity("robot_hand", t_ns, spheres=spheres,
                                 lines=[foxglove.line_list(segments, rgba, thickness_m=0.006)])


class _Listener(ServerListener):
    """The server's callbacks (the SDK calls every method of its protocol; the defaults do
    nothing): a new viewer of ``/markers`` needs the static entities, so they are resent."""

    def __init__(self, static_due: threading.Event) -> None:
        self._static_due = static_due

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        if channel.topic == schemas.TOPIC_MARKERS:
            self._static_due.set()


class FoxgloveLive:
    """The WebSocket server and its channels (module docstring); :meth:`close` stops it.

    ``port`` 0 picks a free port (:attr:`port` says which); ``fingers`` orders the contact
    colours as in recordings; ``world_offset_m`` places the operator's tracking space (the
    bridge's config). Raises ValueError for a non-loopback ``host``.
    """

    def __init__(self, *, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT,
                 name: str = "dexaug bridge", fingers: Sequence[str] = (),
                 world_offset_m: Any = (0.0, 0.0, 0.0), rate_hz: float = 30.0) -> None:
        self.host = check_host(host)
        self.fingers = tuple(fingers)
        self.world_offset_m = np.asarray(world_offset_m, dtype=float).reshape(3)
        self._period_s = 1.0 / float(rate_hz)
        self._next_s = 0.0
        self._context = fx.Context()   # its own: the recorder's file never sees these
        self._channels = {t: foxglove.sdk_channel(schemas.CHANNEL_BY_TOPIC[t], self._context)
                          for t in LIVE_TOPICS}
        self._static_due = threading.Event()   # the object and table, to (re)send
        self._static_due.set()
        self._scene: Scene | None = None
        self._links: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._meshes: dict[str, bytes] = {}
        self._failures = 0
        self.server = fx.start_server(name=name, host=host, port=port, context=self._context,
                                      server_listener=_Listener(self._static_due))
        self.port = self.server.port

    @property
    def url(self) -> str:
        """The WebSocket URL a Foxglove client opens."""
        return f"ws://{self.host}:{self.port}"

    def app_url(self) -> str | None:
        """The Foxglove app's URL that opens this server as its data source."""
        return self.server.app_url()

    # --- publishing (the bridge loop's thread, the view thread) -------------------------------

    def _wanted(self, topic: str) -> bool:
        return self._channels[topic].has_sinks()

    def _log(self, topic: str, data: bytes, t_ns: int) -> None:
        self._channels[topic].log(data, log_time=t_ns)

    def publish_step(self, scene: Scene, contacts: Sequence[ContactRecord], *, t_s: float,
                     seq: int | None, tracked: bool, object_name: str | None,
                     extra: Mapping[str, Any], operator: HandFrame | None,
                     now_s: float | None = None) -> bool:
        """One bridge step, when ``rate_hz`` allows (``now_s``: perf_counter seconds); True if
        published. Never raises: a failure is logged (the first ones and every 100th)."""
        now_s = time.perf_counter() if now_s is None else now_s
        if now_s < self._next_s:
            return False
        self._next_s = now_s + self._period_s
        try:
            self._publish(scene, contacts, t_s, seq, tracked, object_name, extra, operator)
        except Exception as exc:   # a viewer must never stop the bridge
            self._failures += 1
            if self._failures <= 3 or self._failures % 100 == 0:
                logger.warning("Foxglove live publishing failed (#%d): %s", self._failures, exc)
            return False
        return True

    def _publish(self, scene: Scene, contacts: Sequence[ContactRecord], t_s: float,
                 seq: int | None, tracked: bool, object_name: str | None,
                 extra: Mapping[str, Any], operator: HandFrame | None) -> None:
        t_ns = time.time_ns()
        if scene is not self._scene:   # a new object means a new scene
            self._scene, self._links = scene, _hand_links(scene)
            self._static_due.set()
        palm_p, palm_q = scene.palm_world_pose()
        obj_p, obj_q = scene.object_pose()
        if self._wanted(schemas.TOPIC_STATE):
            self._log(schemas.TOPIC_STATE, schemas.dumps(schemas.state_payload(
                scene.data.qpos[scene.hand_qadr], palm_p, palm_q, obj_p, obj_q, t_s=t_s, seq=seq,
                tracked=tracked, object_name=object_name, extra=extra)), t_ns)
        if self._wanted(schemas.TOPIC_CONTACTS):
            self._log(schemas.TOPIC_CONTACTS, schemas.dumps(contacts_payload(
                contacts, t_s=t_s, seq=seq, object_name=object_name)), t_ns)
        if self._wanted(schemas.TOPIC_TF):
            tf = foxglove.FrameTransform
            self._log(schemas.TOPIC_TF, foxglove.frame_transforms([
                tf(schemas.FRAME_WORLD, schemas.FRAME_PALM, palm_p, palm_q),
                tf(schemas.FRAME_WORLD, schemas.FRAME_OBJECT, obj_p, obj_q),
                tf(schemas.FRAME_WORLD, FRAME_OPERATOR, self.world_offset_m, (1, 0, 0, 0))],
                t_ns).encode(), t_ns)
        if self._wanted(schemas.TOPIC_MARKERS):
            self._log(schemas.TOPIC_MARKERS,
                      self._markers(scene, contacts, operator, t_ns).encode(), t_ns)

    def _markers(self, scene: Scene, contacts: Sequence[ContactRecord],
                 operator: HandFrame | None, t_ns: int) -> fm.SceneUpdate:
        entities = [hand_figure_entity(scene, t_ns, self._links),
                    foxglove.contact_entity(contacts, t_ns, fingers=self.fingers)]
        deletions = []
        for side in ("left", "right"):
            hand = getattr(operator, side) if operator is not None else None
            if hand is not None:
                entities.append(foxglove.hand_skeleton_entity(
                    hand, t_ns, entity_id=f"operator_{side}", frame_id=FRAME_OPERATOR,
                    rgba=foxglove.color(*_OPERATOR_RGBA)))
            else:
                deletions.append(fm.SceneEntityDeletion(
                    timestamp=foxglove.timestamp(t_ns), id=f"operator_{side}",
                    type=fm.SceneEntityDeletionType.MatchingId))
        if self._static_due.is_set():
            self._static_due.clear()
            entities += self._static_entities(scene, t_ns)
        return foxglove.scene_update(entities, deletions)

    def _static_entities(self, scene: Scene, t_ns: int) -> list[fm.SceneEntity]:
        """The object's visual mesh (GLB, locked to the ``object`` frame) and the table."""
        out = []
        if scene.obj is not None:
            name = scene.obj.name
            if name not in self._meshes:
                glb = scene.obj.surface_mesh().export(file_type="glb")
                if not isinstance(glb, bytes):   # trimesh types export() for every format
                    raise TypeError(f"trimesh exported a {type(glb).__name__}, not glb bytes")
                self._meshes[name] = glb
            out.append(foxglove.scene_entity(
                "object", t_ns, frame_id=schemas.FRAME_OBJECT, frame_locked=True,
                models=[foxglove.model("", (0, 0, 0), (1, 0, 0, 0), data=self._meshes[name],
                                       media_type="model/gltf-binary",
                                       rgba=foxglove.color(0.85, 0.55, 0.25, 1.0))]))
        if scene.table_geom >= 0:
            g = scene.table_geom
            out.append(foxglove.scene_entity("table", t_ns, cubes=[foxglove.cube(
                scene.model.geom_pos[g], (1, 0, 0, 0), 2 * scene.model.geom_size[g],
                foxglove.color(0.55, 0.45, 0.35, 0.5))]))
        return out

    def publish_view(self, jpeg: bytes) -> None:
        """A head-camera frame (the view thread); never raises."""
        try:
            if self._wanted(schemas.TOPIC_VIEW):
                t_ns = time.time_ns()
                self._log(schemas.TOPIC_VIEW, foxglove.compressed_image(jpeg, t_ns).encode(), t_ns)
        except Exception as exc:
            logger.warning("Foxglove live /view failed: %s", exc)

    def close(self) -> None:
        """Stop the server (clients are disconnected)."""
        self.server.stop()
