"""The headset view: a camera that follows the operator's head, rendered to JPEG.

Why a separate module (and a persistent renderer): :func:`sim.world.render.render_scene` opens a GL
context per image, fine for reports but tens of milliseconds too slow for a 30 Hz stream. Here
one :class:`mujoco.Renderer` lives as long as the view, in the one thread that renders (GL
contexts are thread-bound). The backend comes from :func:`sim.world.render.gl_available`; without GL
the bridge simply does not stream a view.

Camera: MuJoCo free camera placed at the head (metres, world), looking along the head's forward
axis (local +X after :mod:`teleop.input.frames`' conversion, XR's −Z); roll is dropped (a free camera
has none). Contact points are drawn as in :func:`sim.world.render.render_scene`.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from sim.world.drawing import encode_jpeg

Array = np.ndarray


def head_camera(head_pos_m: Array, head_quat_wxyz: Array, *, lookat_distance_m: float = 0.5
                ) -> tuple[Array, float, float, float]:
    """Free-camera parameters (lookat, distance_m, azimuth_deg, elevation_deg) that put the
    camera at the head looking along its forward axis."""
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(head_quat_wxyz, float))
    fwd = mat.reshape(3, 3)[:, 0]
    norm = float(np.linalg.norm(fwd))
    fwd = fwd / norm if norm > 1e-9 else np.array([1.0, 0.0, 0.0])
    az = math.degrees(math.atan2(fwd[1], fwd[0]))
    el = math.degrees(math.asin(max(-1.0, min(1.0, float(fwd[2])))))
    lookat = np.asarray(head_pos_m, float) + lookat_distance_m * fwd
    return lookat, lookat_distance_m, az, el


class HeadView:
    """Renders ``data`` from the head pose to JPEG bytes; create and use in one thread."""

    def __init__(self, model: mujoco.MjModel, *, width: int = 320, height: int = 240,
                 jpeg_quality: int = 80, show_contacts: bool = True) -> None:
        self.model = model
        self.renderer = mujoco.Renderer(model, height, width)
        # shadows cost ~8x the frame time under software GL (156 ms vs 19 ms at 320x240 on
        # llvmpipe) and add little to a teleop view; reflections likewise
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self.cam = mujoco.MjvCamera()
        self.cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.opt = mujoco.MjvOption()
        self.opt.flags[mujoco.mjtVisFlag.mjVIS_CONTACTPOINT] = show_contacts
        self.opt.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = False
        model.vis.scale.contactwidth = 0.08
        model.vis.scale.contactheight = 0.02
        self.jpeg_quality = int(jpeg_quality)

    def update(self, data: mujoco.MjData, head_pos_m: Array, head_quat_wxyz: Array) -> None:
        """Copy the state into the renderer's scene from the head's viewpoint (the only step
        that reads ``data``: callers sharing ``data`` hold their lock just for this)."""
        lookat, dist, az, el = head_camera(head_pos_m, head_quat_wxyz)
        self.cam.lookat[:] = lookat
        self.cam.distance, self.cam.azimuth, self.cam.elevation = dist, az, el
        self.renderer.update_scene(data, self.cam, scene_option=self.opt)

    def render_rgb(self, data: mujoco.MjData, head_pos_m: Array, head_quat_wxyz: Array) -> Array:
        """RGB (H, W, 3) uint8 from the head."""
        self.update(data, head_pos_m, head_quat_wxyz)
        return self.renderer.render()

    def encode(self, rgb: Array) -> bytes:
        """JPEG bytes of an RGB image."""
        return encode_jpeg(rgb, self.jpeg_quality)

    def render_jpeg(self, data: mujoco.MjData, head_pos_m: Array, head_quat_wxyz: Array
                    ) -> bytes:
        """JPEG bytes of :meth:`render_rgb`."""
        return self.encode(self.render_rgb(data, head_pos_m, head_quat_wxyz))

    def close(self) -> None:
        self.renderer.close()
