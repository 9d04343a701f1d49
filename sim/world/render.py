"""Offscreen images of a scene (hand + object, contacts marked) with MuJoCo's renderer.

Rendering needs an OpenGL backend: ``MUJOCO_GL=egl`` (GPU or Mesa's EGL) or ``osmesa``
(software). ``gl_available`` lets callers and tests check before they try.
"""

from __future__ import annotations

import math
import os
from functools import cache
from typing import TYPE_CHECKING

import numpy as np

from sim.errors import DexaugError
from sim.io import write_bytes_atomic
from sim.world.drawing import encode_png

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
                 show_contacts: bool = True,
                 background_rgb: tuple[int, int, int] | None = None,
                 geom_ids: list[np.ndarray] | None = None) -> np.ndarray:
    """RGB image (H, W, 3) uint8 of the current state from a free camera aimed at ``lookat``.
    Contact points are drawn by MuJoCo when ``show_contacts``. ``background_rgb`` fills the
    pixels no geom covers (a scene without a skybox renders them black, which hides dark
    hands in print); it costs a second, segmentation pass, whose per-pixel geom ids (H, W;
    −1 where nothing is drawn, −2 on what is not a geom) are appended to ``geom_ids`` when a
    list is given."""
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
        rgb = renderer.render().copy()
        if background_rgb is not None or geom_ids is not None:
            renderer.enable_segmentation_rendering()
            seg = renderer.render()
            # −1: nothing (background); −2: something that is not a geom (a skin, a decoration)
            ids = np.where(seg[..., 0] < 0, -1,
                           np.where(seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), seg[..., 0], -2))
            if background_rgb is not None:
                rgb[seg[..., 0] < 0] = background_rgb
            if geom_ids is not None:
                geom_ids.append(ids)
        return rgb


def frame_points(points_m: np.ndarray, fovy_deg: float = 45.0,
                 margin: float = 1.15) -> tuple[np.ndarray, float]:
    """Where a camera looks and how far back it stands (m) so that every one of ``points_m``
    (N, 3, world) is in view from any direction: the centre of their bounding box, and the
    radius of the sphere around it that holds them over sin(fovy / 2), times ``margin``."""
    pts = np.asarray(points_m, float).reshape(-1, 3)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    radius = float(np.linalg.norm(pts - centre, axis=1).max(initial=0.0)) or 0.05
    return centre, margin * radius / math.sin(math.radians(fovy_deg) / 2)


def geom_box_corners(model: mujoco.MjModel, data: mujoco.MjData, geoms: np.ndarray) -> np.ndarray:
    """World corners (8·G, 3) of the bounding boxes of ``geoms`` (ids) in their current pose."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    out = []
    for g in np.asarray(geoms, int):
        centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        local = centre + signs * half
        out.append(data.geom_xpos[g] + local @ data.geom_xmat[g].reshape(3, 3).T)
    return np.vstack(out) if out else np.zeros((0, 3))


def save_png(path: str | os.PathLike[str], rgb: np.ndarray) -> None:
    """Write an RGB image to PNG atomically."""
    write_bytes_atomic(path, encode_png(rgb))
