"""The bridge's ``/view`` stream: a render thread fed with copies of the loop's MuJoCo data.

Why a thread of its own: GL contexts are thread-bound and a frame costs tens of milliseconds
under software GL, so the loop only copies its ``MjData`` (:meth:`ViewStream.snapshot`, under a
lock) and wakes this thread, which renders the copy from the operator's head
(:class:`teleop.bridge.view.HeadView`), encodes JPEG and hands the bytes to the bridge's
callback (publish, count, record). MuJoCo's renderer holds the GIL while it draws, so the
thread sleeps after each frame to use at most ``view_max_duty`` of the time, whatever
``view_rate_hz`` asks. :func:`gl_backend` says whether a view can exist at all;
:func:`head_pose` where the camera is.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable

import mujoco
import numpy as np

from teleop.bridge.config import BridgeConfig
from teleop.messages import HandFrame

__all__ = ["ViewStream", "gl_backend", "head_pose"]

logger = logging.getLogger(__name__)
Array = np.ndarray

_GL: dict[str, str | None] = {}


def head_pose(frame: HandFrame | None, config: BridgeConfig) -> tuple[Array, Array]:
    """Where the view camera is (world metres, quaternion wxyz): the operator's head shifted by
    ``world_offset_m``, or before any frame a default pose behind the object looking down."""
    if frame is None:
        pos = np.array([*config.object_pos_m, 0.0]) + np.array([-0.45, 0.0, 0.45])
        return pos, np.array([math.cos(math.radians(22.5)), 0.0,
                              math.sin(math.radians(22.5)), 0.0])
    return np.asarray(frame.head_position, float) + config.world_offset_m, \
        np.asarray(frame.head_orientation_wxyz, float)


def gl_backend() -> str | None:
    """The working GL backend, probed once per process (the probe costs a subprocess)."""
    if "backend" not in _GL:
        from sim.world.render import gl_available
        _GL["backend"] = gl_available()
    return _GL["backend"]


class ViewStream:
    """Renders snapshots of a scene to JPEG in a background thread (module docstring).

    ``config`` gives the image size, JPEG quality and duty cap; ``on_jpeg(jpeg)`` runs in the
    render thread for every frame. ``active`` is True while a renderer is up.
    """

    def __init__(self, config: BridgeConfig, on_jpeg: Callable[[bytes], None]) -> None:
        self.config = config
        self._on_jpeg = on_jpeg
        self._view_lock = threading.Lock()
        self._view_data: mujoco.MjData | None = None
        self._view_head: tuple[Array, Array] | None = None
        self._view_wake = threading.Event()
        self._view_stop = threading.Event()
        self._view_thread: threading.Thread | None = None
        self.active = False

    def snapshot(self, model: mujoco.MjModel, data: mujoco.MjData,
                 head: tuple[Array, Array]) -> None:
        """Copy ``data`` and the head pose (metres, quaternion wxyz) for the next frame."""
        with self._view_lock:
            if self._view_data is None:
                self._view_data = mujoco.MjData(model)
            mujoco.mj_copyData(self._view_data, model, data)
            self._view_head = head
        self._view_wake.set()

    def start(self, model: mujoco.MjModel) -> None:
        """Start the render thread for ``model``; returns once its renderer is up (or failed)."""
        self._view_stop.clear()
        self._view_data = None
        ready = threading.Event()
        self._view_thread = threading.Thread(target=self._view_loop, args=(model, ready),
                                             name="dexaug-view", daemon=True)
        self._view_thread.start()
        ready.wait(10.0)

    def stop(self) -> None:
        """Stop the render thread (a no-op when none runs)."""
        if self._view_thread is not None:
            self._view_stop.set()
            self._view_wake.set()
            self._view_thread.join(10.0)
            self._view_thread = None
        self.active = False

    def _view_loop(self, model: mujoco.MjModel, ready: threading.Event) -> None:
        from teleop.bridge.view import HeadView
        try:
            view = HeadView(model, width=self.config.view_width, height=self.config.view_height,
                            jpeg_quality=self.config.jpeg_quality)
        except Exception as exc:
            logger.warning("view renderer unavailable (%s): the /view stream is off", exc)
            ready.set()
            return
        self.active = True
        ready.set()
        try:
            while not self._view_stop.is_set():
                if not self._view_wake.wait(0.1):
                    continue
                self._view_wake.clear()
                with self._view_lock:
                    if self._view_data is None or self._view_head is None:
                        continue
                    view.update(self._view_data, *self._view_head)
                t_render = time.perf_counter()
                jpeg = view.encode(view.renderer.render())
                t_render = time.perf_counter() - t_render
                self._on_jpeg(jpeg)
                # MuJoCo's renderer holds the GIL while it draws: with software GL (tens of
                # ms a frame) an unthrottled view would stall the control loop, so the view
                # may use at most view_max_duty of the time, whatever view_rate_hz asks
                self._view_stop.wait(t_render * (1.0 / self.config.view_max_duty - 1.0))
        finally:
            view.close()
            self.active = False
