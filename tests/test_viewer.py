"""The interactive 3D grasp viewer (#16): the page shows the validated grasps, and it works in
a browser.

The scene's hand poses are checked against MuJoCo itself (the validator's scene with the grasp
placed), the page against the dataset it was made from (every row listed, filters counting the
dataset's verdicts, the hand drawn where Python's forward kinematics puts it), in headless
Chromium with WebGL2 (SwiftShader); screenshots go to ``tests/artifacts/viewer*.png``.
"""

from __future__ import annotations

import base64
import collections
from pathlib import Path

import numpy as np
import pytest

from augment import dataset
from dexaug.pipeline.options import AugmentOptions
from dexaug.viewer.mesh_lod import within_budget
from dexaug.viewer.scene import ViewerLimits, grasp_body_poses, hand_meshes, viewer_scene
from sim.demo import load_demo
from sim.hand.config import hand_names
from tests.browser import artifact_path, new_page
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]

#: the authors' table-mode demo of the sugar box: its result has passes and failures
DEMO = Path(__file__).resolve().parent.parent / "recordings/demos/human/004_sugar_box.json"


@pytest.fixture(scope="module")
def result(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real augmentation's folder (report, viewer, dataset) from the pipeline."""
    from dexaug.pipeline.run import augment_demo

    out = tmp_path_factory.mktemp("viewer")
    summary = augment_demo(load_demo(DEMO), out, AugmentOptions(n=24, workers=1, gallery=1))
    return Path(summary.dataset).parent


def _table(folder: Path) -> dataset.ObjectTable:
    (table,) = dataset.load(folder / "grasps.h5").values()
    return table


def test_lighter_meshes_keep_their_budget_and_their_shape() -> None:
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=5, radius=0.05)     # 20 480 faces
    v, f = within_budget(mesh.vertices, mesh.faces, 2000)
    assert 100 < len(f) <= 2000 and f.max() < len(v)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 0.05, atol=0.004)  # still the sphere
    same_v, same_f = within_budget(mesh.vertices, mesh.faces, 30_000)
    assert np.array_equal(same_f, mesh.faces) and np.array_equal(same_v, mesh.vertices)


@pytest.mark.parametrize("hand_name", hand_names())
def test_every_hand_has_meshes_within_budget_on_every_moving_body(hand_name: str) -> None:
    from sim.hand.model import Hand

    hand = Hand.load(hand_name)
    meshes = hand_meshes(hand, 20_000)
    assert sum(len(f) for _, f, _ in meshes.values()) <= 20_000 + 12 * hand.model.ngeom
    m = hand.model
    drawn = {int(m.geom_bodyid[g]) for g in range(m.ngeom)
             if m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0} or set(m.geom_bodyid)
    assert drawn == set(meshes) and {int(b) for b in hand.tip_body_ids} <= set(meshes)
    for v, f, c in meshes.values():
        assert len(v) == len(c) and f.min() >= 0 and f.max() < len(v)


def test_hand_poses_are_where_mujoco_puts_the_validated_grasp(shadow, result: Path) -> None:
    """Every drawn body at every grasp sits where the validator's scene has it (object at home)."""
    from sim.transforms import pose_mul, quat_angle
    from sim.validate.validator import Validator
    from sim.world.objects import load_object
    from sim.world.scene import HAND_PREFIX, OBJECT_HOME

    table = _table(result)
    bodies = sorted(hand_meshes(shadow, 20_000))
    poses = grasp_body_poses(shadow, table["palm_pose"][:5], table["hand_pose"][:5], bodies)
    scene = Validator(shadow, load_object("004_sugar_box")).scene("lift-drop")
    ids = [scene.model.body(HAND_PREFIX + shadow.model.body(b).name).id for b in bodies]
    for i in range(5):
        pose = table["palm_pose"][i]
        palm = pose_mul(OBJECT_HOME, np.array([1.0, 0, 0, 0]), pose[:3], pose[3:])
        scene.reset_with_grasp(*palm, table["hand_pose"][i])
        want_p = scene.data.xpos[ids] - OBJECT_HOME
        np.testing.assert_allclose(poses[i, :, :3], want_p, atol=1e-9)
        assert np.max(quat_angle(poses[i, :, 3:], scene.data.xquat[ids])) < 1e-6


def test_the_scene_lists_every_row_with_its_verdict(shadow, result: Path) -> None:
    from sim.world.objects import load_object

    table = _table(result)
    scene = viewer_scene(table, shadow, load_object("004_sugar_box"), demo=load_demo(DEMO))
    g = scene["grasps"]
    rejected = len(table.rejected) if table.rejected is not None else 0
    assert g["n"] == len(table) + rejected == scene["grasps_in_table"]
    assert collections.Counter(g["verdict"]) == {k: v for k, v in
                                                 (("passed", len(table)), ("failed", rejected)) if v}
    assert scene["table"] is not None and scene["demo"]["id"] == load_demo(DEMO).id
    every = dataset.with_rejected(table)
    points = np.frombuffer(base64.b64decode(g["contact_points"]), "<f4").reshape(-1, 3)
    np.testing.assert_allclose(points, every["contact_points"], atol=1e-6)
    assert g["contact_offsets"] == list(every["contact_offsets"])
    small = viewer_scene(table, shadow, load_object("004_sugar_box"),
                         limits=ViewerLimits(max_grasps=3))
    assert small["grasps"]["n"] == 3 and small["grasps_in_table"] == g["n"] and small["demo"] is None
    assert small["grasps"]["contact_offsets"] == list(every["contact_offsets"][:4])


def _open(chromium, path: Path, console: list[str], size=(1200, 760)):  # type: ignore[no-untyped-def]
    page = new_page(chromium, https=False, console=console, viewport=size)
    page.goto(path.as_uri())
    page.wait_for_function("window.dexaugViewer && window.dexaugViewer.frames() > 0",
                           timeout=30_000)
    return page


def _canvas_pixels(page) -> np.ndarray:  # type: ignore[no-untyped-def]
    import io

    from PIL import Image

    png = page.locator("#view").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def test_the_viewer_page_draws_filters_and_poses_the_grasps(chromium, shadow,
                                                            result: Path) -> None:
    console: list[str] = []
    table = _table(result)
    page = _open(chromium, result / "viewer.html", console)
    api = "window.dexaugViewer"
    rejected = len(table.rejected) if table.rejected is not None else 0
    assert page.evaluate(f"{api}.ready") and page.evaluate(f"{api}.total") == len(table) + rejected
    assert page.locator("#grasp-list option").count() == len(table) + rejected
    page.screenshot(path=str(artifact_path("viewer.png")))
    shown = _canvas_pixels(page)
    background = np.array([245, 246, 249])
    drawn = np.abs(shown.astype(int) - background).sum(axis=2) > 30
    assert drawn.mean() > 0.05, "the canvas is (nearly) empty"
    tan = (np.abs(shown.astype(int) - [205, 160, 110]).sum(axis=2) < 120) & drawn
    assert tan.mean() > 0.01, "the object is not drawn"

    # the filters count what the dataset holds
    page.select_option("#f-verdict", "failed")
    assert page.evaluate(f"{api}.visible().length") == rejected
    page.select_option("#f-verdict", "passed")
    assert page.evaluate(f"{api}.visible().length") == len(table)
    page.select_option("#f-verdict", "")
    fingers = collections.Counter(
        "+".join(f for f, on in zip(table.finger_names, row, strict=True) if on)
        for row in table["fingers_used"])
    key, count = fingers.most_common(1)[0]
    page.select_option("#f-fingers", key)
    assert page.evaluate(f"{api}.visible().length") >= count
    page.select_option("#f-fingers", "")

    # grasp 3 selected: each body is drawn at the pose Python's forward kinematics gives
    page.locator("#grasp-list").select_option("3")
    assert page.evaluate(f"{api}.selected()") == 3
    bodies = sorted(hand_meshes(shadow, 20_000))
    want = grasp_body_poses(shadow, table["palm_pose"][3:4], table["hand_pose"][3:4], bodies)[0]
    for b in range(len(bodies)):
        m = np.array(page.evaluate(f"{api}.bodyMatrix(3, {b})")).reshape(4, 4).T   # column-major
        np.testing.assert_allclose(m[:3, 3], want[b, :3], atol=1e-6)
    page.keyboard.press("ArrowRight")
    assert page.evaluate(f"{api}.selected()") == 4

    # hiding the hand changes the picture
    with_hand = _canvas_pixels(page)
    page.uncheck("#show-hand")
    page.wait_for_timeout(200)
    assert np.abs(_canvas_pixels(page).astype(int) - with_hand).sum(axis=2).astype(bool).mean() > 0.01
    assert not [c for c in console if c.startswith(("pageerror", "error"))], console


def test_the_report_embeds_the_viewer(chromium, result: Path) -> None:
    console: list[str] = []
    page = new_page(chromium, https=False, console=console, viewport=(1200, 1400))
    page.goto((result / "report.html").as_uri())
    frame = page.frame_locator("iframe.viewer")
    frame.locator("#grasp-list option").first.wait_for(timeout=30_000)
    page.screenshot(path=str(artifact_path("viewer_in_report.png")))
    assert page.locator("a[href='viewer.html']").count() == 1
    assert page.locator("img[src='palm_cloud.png']").count() == 1   # the print view is kept
    assert not [c for c in console if c.startswith("pageerror")], console


def test_a_table_with_no_grasps_is_a_scene_with_none(shadow) -> None:
    """FSG finding no grasp is a result: the page shows the object alone (the empty table
    crashed the report with "cannot reshape array of size 0")."""
    from sim.world.objects import load_object

    table = dataset.from_fsg([], tuple(shadow.joint_names), tuple(shadow.finger_names), [],
                             attrs={"hand": shadow.name})
    scene = viewer_scene(table, shadow, load_object("004_sugar_box"))
    assert scene["grasps"]["n"] == 0 and scene["grasps_in_table"] == 0
    assert scene["grasps"]["verdict"] == [] and scene["object"]["mesh"]
