"""Offscreen images of a scene (hand + object, contacts marked) with MuJoCo's renderer.

Rendering needs an OpenGL backend: ``MUJOCO_GL=egl`` (GPU or Mesa's EGL) or ``osmesa``
(software). ``gl_available`` lets callers and tests check before they try.
"""

from __future__ import annotations

import os
from functools import cache
from typing import TYPE_CHECKING

import cv2
import numpy as np

from sim.errors import DexaugError
from sim.io import write_bytes_atomic

if TYPE_CHECKING:
    import mujoco


class RenderError(DexaugError):
    """Offscreen rendering is not possible on this machine."""


@cache
def gl_available() -> str | None:
    """The first working ``MUJOCO_GL`` backend (the current one, then egl, then osmesa) or None.

    Each backend is probed in a subprocess, since a failed GL initialisation can abort the
    process that attempts it.
    """
    import subprocess
    import sys

    probe = ("import mujoco; m = mujoco.MjModel.from_xml_string('<mujoco><worldbody>"
             "<geom size=\".1\"/></worldbody></mujoco>'); mujoco.Renderer(m, 8, 8).render()")
    candidates = [os.environ.get("MUJOCO_GL"), "egl", "osmesa"]
    for backend in dict.fromkeys(c for c in candidates if c):
        env = {**os.environ, "MUJOCO_GL": backend}
        ok = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True,
                            timeout=60).returncode == 0
        if ok:
            return backend
    return None


def select_gl_backend() -> str:
    """Set ``MUJOCO_GL`` to a working backend; call before MuJoCo is first imported (MuJoCo
    reads the variable once, at import)."""
    backend = gl_available()
    if backend is None:
        raise RenderError("no OpenGL backend for offscreen rendering (tried MUJOCO_GL=egl and "
                          "osmesa); install Debian's libegl1 or libosmesa6")
    os.environ["MUJOCO_GL"] = backend
    return backend


def render_scene(model: mujoco.MjModel, data: mujoco.MjData, *, lookat: np.ndarray,
                 distance_m: float = 0.35, azimuth_deg: float = 135.0,
                 elevation_deg: float = -25.0, width: int = 640, height: int = 480,
                 show_contacts: bool = True) -> np.ndarray:
    """RGB image (H, W, 3) uint8 of the current state from a free camera aimed at ``lookat``.
    Contact points are drawn by MuJoCo when ``show_contacts``."""
    import mujoco  # deferred: MUJOCO_GL must be chosen before MuJoCo's first import
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = lookat
    cam.distance, cam.azimuth, cam.elevation = distance_m, azimuth_deg, elevation_deg
    opt = mujoco.MjvOption()
    opt.flags[mujoco.mjtVisFlag.mjVIS_CONTACTPOINT] = show_contacts
    opt.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = False
    model.vis.scale.contactwidth = 0.08
    model.vis.scale.contactheight = 0.02
    model.vis.scale.forcewidth = 0.03
    model.vis.map.force = 0.002  # metres of arrow per newton
    with mujoco.Renderer(model, height, width) as renderer:
        renderer.update_scene(data, cam, scene_option=opt)
        return renderer.render().copy()


def save_png(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """Write an RGB image to PNG atomically."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError(f"OpenCV could not encode {path} as PNG")
    write_bytes_atomic(path, buf.tobytes())
