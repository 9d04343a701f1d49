"""Drawing AutoWS workspace clouds over an offscreen MuJoCo rendering of the hand (the paper's
Fig. 2 (h)–(j)): :func:`render_workspace_png`, and the world → pixel projection of MuJoCo's free
camera it uses (:func:`free_camera_projection`, no GL needed).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from augment.autows.cloud import WorkspaceCloud
from augment.autows.params import WorkspaceError
from sim.hand.model import Hand
from sim.transforms import quat_to_mat
from sim.world.drawing import Canvas

__all__ = ["free_camera_projection", "render_workspace_png"]

_COLOURS_RGB = ((230, 60, 60), (60, 170, 240), (70, 200, 90), (240, 170, 40), (190, 90, 220),
                (40, 200, 200), (250, 110, 180), (150, 150, 150))


def free_camera_projection(model: mujoco.MjModel, data: mujoco.MjData, lookat: ArrayLike,
                           distance_m: float, azimuth_deg: float, elevation_deg: float,
                           width: int, height: int,
                           ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """World → pixel projection of the free camera that :func:`sim.world.render.render_scene` uses,
    read back from ``mjv_updateScene`` (no GL needed). Returns ``project(points (N,3)) ->
    (uv (N,2), depth (N,))``: pixel coordinates with (0, 0) at the centre of the top-left pixel
    (as :mod:`sim.world.drawing` draws), and the depth along the view direction in metres (> 0
    in front)."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = lookat
    cam.distance, cam.azimuth, cam.elevation = distance_m, azimuth_deg, elevation_deg
    scene = mujoco.MjvScene(model, maxgeom=max(1000, 4 * model.ngeom))
    mujoco.mjv_updateScene(model, data, mujoco.MjvOption(), None, cam,
                           int(mujoco.mjtCatBit.mjCAT_ALL), scene)
    # the scene holds a left/right eye pair (offset by the model's ipd); a mono rendering uses
    # their average
    gl = mujoco.mjv_averageCamera(scene.camera[0], scene.camera[1])
    fwd, up = np.array(gl.forward), np.array(gl.up)
    right = np.cross(fwd, up)
    origin = np.array(gl.pos)
    near, top, bottom = gl.frustum_near, gl.frustum_top, gl.frustum_bottom
    half_w = gl.frustum_width if gl.frustum_width > 0 else 0.5 * (top - bottom) * width / height
    left = gl.frustum_center - half_w

    def project(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rel = np.asarray(points, dtype=float) - origin
        depth = rel @ fwd
        z = np.maximum(depth, 1e-9)
        xs, ys = near * (rel @ right) / z, near * (rel @ up) / z
        u = (xs - left) / (2 * half_w) * width
        v = (top - ys) / (top - bottom) * height
        return np.stack([u, v], axis=1) - 0.5, depth

    return project


def render_workspace_png(hand: Hand, cloud: WorkspaceCloud, path: Path | str | None, *,
                         q: ArrayLike | None = None, width: int = 960, height: int = 720,
                         skeletons_per_finger: int = 12, point_radius_px: int = 2,
                         ) -> np.ndarray:
    """Draw the workspace clouds over an offscreen MuJoCo rendering of the hand (like the
    paper's Fig. 2 (h)–(j)) and write a PNG to ``path`` (skipped when ``None``).

    The hand is shown at ``q`` (default: the demo's joints for a demo cloud, else all zeros);
    the clouds are placed through its palm frame (they are relative to the palm, so the hand's
    pose does not change their shape). Points are coloured per finger; a few link skeletons per
    finger are drawn as thin polylines. Needs an OpenGL backend (``sim.world.render.gl_available``).

    Returns:
        the RGB image (H, W, 3) uint8.
    """
    from sim.world.render import render_scene, save_png

    if cloud.hand != hand.name:
        raise WorkspaceError(f"cloud of hand {cloud.hand!r} drawn over hand {hand.name!r}")
    if q is None:
        demo_q = cloud.provenance.get("demo_joints")
        q = np.zeros(hand.nq) if demo_q is None else np.asarray(demo_q, dtype=float)
    qv = hand.check_q(np.asarray(q, dtype=float), "render joint vector")
    model = hand.spec().compile()  # render_scene changes visual scales: keep hand.model intact
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    data = mujoco.MjData(model)
    data.qpos[:] = qv
    mujoco.mj_forward(model, data)
    ppos, pquat = hand.palm_pose(qv)
    rot = quat_to_mat(pquat[0])

    def to_world(p: np.ndarray) -> np.ndarray:
        return ppos[0] + np.asarray(p, dtype=float) @ rot.T

    pts = [to_world(f.positions) for f in cloud.fingers if f.n_points]
    links = [model.body(b).id for f in hand.config.fingers for b in f.links]
    everything = np.vstack([*pts, ppos, data.xpos[links]])
    lo, hi = everything.min(0), everything.max(0)
    lookat = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 0.03)
    fovy = math.radians(model.vis.global_.fovy)
    distance = 1.15 * radius / math.sin(0.5 * fovy)
    # look at the palm face (+y of frame_palm) from slightly beside and above
    eye_dir = rot @ np.array([0.35, 1.0, 0.3])
    forward = -eye_dir / np.linalg.norm(eye_dir)
    azimuth = math.degrees(math.atan2(forward[1], forward[0]))
    elevation = math.degrees(math.asin(float(np.clip(forward[2], -1.0, 1.0))))
    rgb = render_scene(model, data, lookat=lookat, distance_m=distance, azimuth_deg=azimuth,
                       elevation_deg=elevation, width=width, height=height, show_contacts=False)
    project = free_camera_projection(model, data, lookat, distance, azimuth, elevation, width,
                                     height)
    img = np.ascontiguousarray(rgb)
    rng = np.random.default_rng(0)
    with Canvas(img) as canvas:
        for i, f in enumerate(cloud.fingers):
            colour = _COLOURS_RGB[i % len(_COLOURS_RGB)]
            r, g, b = colour
            dim = (int(0.55 * r), int(0.55 * g), int(0.55 * b))
            if f.n_points and skeletons_per_finger > 0:
                pick = rng.choice(f.n_points, min(skeletons_per_finger, f.n_points), replace=False)
                for s in f.skeleton[pick]:
                    uv, _ = project(to_world(s))
                    canvas.polyline(np.round(uv), dim)
            if f.n_points:
                uv, depth = project(to_world(f.positions))
                for u, v in np.round(uv[depth > 0]):
                    canvas.disk((u, v), point_radius_px, colour)
            canvas.text((12, 26 + 24 * i), f"{f.name}: {f.n_points} pts, {f.n_faces} faces", colour,
                        size_px=19, bold=True)
    if path is not None:
        save_png(path, img)
    return img
