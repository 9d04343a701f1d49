"""An image of a closed grasp (:meth:`sim.validate.validator.Validator.render`): the report's
gallery and the figures.

The camera frames the bounding boxes of the object's geoms and of the hand geoms within
:data:`FRAME_HAND_M` of it, so a small object is not lost beside a large hand and the hand near
it is not cropped (the forearm may leave the frame).
"""

from __future__ import annotations

import numpy as np

from sim.world.render import frame_points, geom_box_corners, render_scene
from sim.world.scene import Scene

__all__ = ["FRAME_HAND_M", "RENDER_BACKGROUND_RGB", "framed_image"]

#: hand geoms within this distance (m) of the object's centre are framed
FRAME_HAND_M = 0.12
#: the background of the images (light grey: prints, shows dark hands)
RENDER_BACKGROUND_RGB = (236, 238, 242)


def framed_image(scene: Scene, width: int = 640, height: int = 480, *,
                 geom_ids: list[np.ndarray] | None = None) -> np.ndarray:
    """RGB image (height, width, 3) of ``scene`` as it is (a grasp placed and closed),
    contacts marked, on a light background. ``geom_ids``: see
    :func:`sim.world.render.render_scene`."""
    m, d = scene.model, scene.data
    corners = geom_box_corners(m, d, np.flatnonzero(scene.obj_geom_mask))
    centre = corners.mean(axis=0) if len(corners) else scene.object_pose()[0]
    hand = np.flatnonzero(scene.hand_geom_mask)
    near = hand[np.linalg.norm(d.geom_xpos[hand] - centre, axis=1) < FRAME_HAND_M]
    lookat, distance = frame_points(
        np.vstack([corners, geom_box_corners(m, d, near), centre[None]]),
        fovy_deg=float(m.vis.global_.fovy), margin=1.0)
    return render_scene(m, d, lookat=lookat, distance_m=distance, width=width, height=height,
                        background_rgb=RENDER_BACKGROUND_RGB, geom_ids=geom_ids)
