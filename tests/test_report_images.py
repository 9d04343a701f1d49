"""The report's static images (#16): grasp renders framed on the object and the hand near it,
on a light background, nothing cut at the edges; the palm cloud with its demo marker and the
demo's table line."""

from __future__ import annotations

import numpy as np
import pytest

from dexaug.pipeline.report import palm_cloud_image
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.validate.grasp_image import RENDER_BACKGROUND_RGB
from sim.validate.validator import Validator
from sim.world.objects import load_object
from sim.world.render import frame_points, gl_available
from tests.conftest import needs_menagerie, needs_ycb

needs_gl = pytest.mark.skipif(gl_available() is None, reason="no offscreen OpenGL (EGL/OSMesa)")


def test_frame_points_sees_every_point_from_any_side() -> None:
    pts = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0], [0.0, 0.1, 0.05]])
    lookat, distance = frame_points(pts, fovy_deg=45.0, margin=1.0)
    assert lookat == pytest.approx([0.1, 0.05, 0.025])
    radius = np.linalg.norm(pts - lookat, axis=1).max()
    # every point lies within the view cone's half-angle from the camera at that distance
    assert np.degrees(np.arcsin(radius / distance)) == pytest.approx(22.5)


@needs_gl
@needs_menagerie
@needs_ycb
@pytest.mark.parametrize("obj", ["005_tomato_soup_can", "004_sugar_box", "024_bowl"])
def test_grasp_render_frames_object_and_hand_on_a_light_background(shadow: Hand, obj: str) -> None:
    grasp = next(r.grasp for r in load_reference_grasps(shadow) if r.object == obj)
    validator = Validator(shadow, load_object(obj))
    ids: list[np.ndarray] = []
    img = validator.render(grasp, width=480, height=360, geom_ids=ids)
    assert img.shape == (360, 480, 3)
    background = ids[0] == -1
    assert (img[background] == RENDER_BACKGROUND_RGB).all() and background.any()
    scene = validator.scene("lift-drop")
    on_object = np.isin(ids[0], np.flatnonzero(scene.obj_geom_mask))
    on_hand = np.isin(ids[0], np.flatnonzero(scene.hand_geom_mask))
    border = np.zeros_like(on_object)
    border[[0, -1], :] = border[:, [0, -1]] = True
    assert not (on_object & border).any(), "the object is cut at the image's edge"
    assert on_object.mean() > 0.05 and on_hand.mean() > 0.02, (on_object.mean(), on_hand.mean())
    assert (on_object | on_hand).mean() > 0.12   # framed, not lost in the picture


def test_palm_cloud_marks_the_demo_and_the_table() -> None:
    rng = np.random.default_rng(0)
    obj = rng.uniform(-0.03, 0.03, (400, 3)) + np.array([0, 0, 0.05])
    palms = rng.uniform(-0.1, 0.1, (20, 3)) + np.array([0, 0, 0.1])
    plain = palm_cloud_image(obj, palms)
    marked = palm_cloud_image(obj, palms, demo_palm=np.array([0.05, 0.0, 0.12]),
                              table=(np.zeros(3), np.array([0.0, 0.0, 1.0])))
    green = np.all(marked == (0, 150, 60), axis=-1)
    blue = np.all(marked == (60, 90, 220), axis=-1)
    assert green.sum() > 20 and not np.all(plain == (0, 150, 60), axis=-1).any()
    # the horizontal table shows in the side view (right panel) only, as a line across it
    half = marked.shape[1] // 2
    assert blue[:, half:].any(axis=0).mean() > 0.9 and not blue[:, :half].any()
