"""Augmentation keeps the demonstration's context: its table and its fingers.

The paper authors' own teleoperated demonstrations (``recordings/demos/human/``, imported from
``fsg_keyframes``: sugar box, bowl, dice) were recorded with the object resting on a table.
Augmented with the defaults but ``--n 64`` (the default FSG budget), each gives at least 48 grasps
(the 3/4 that the defaults' ``--n 200`` must give, ≥ 150), and every one keeps its palm box and
contacts above that table and uses only the demo's fingers; turning table mode off lets grasps
reach below it (so the check can fail). Each grasp is checked on its own, so 64 a demo test the
same rule as 200 for less FSG time."""

from __future__ import annotations

import numpy as np
import pytest

from augment import dataset
from augment.fsg.candidates import palm_box_vertices
from dexaug.pipeline.options import AugmentOptions
from dexaug.pipeline.run import augment_demo, demo_table
from sim.demo import load_demo
from sim.hand.model import Hand
from sim.paths import REPO_ROOT
from sim.transforms import quat_to_mat
from tests.conftest import needs_menagerie, needs_ycb

HUMAN = REPO_ROOT / "recordings" / "demos" / "human"
DEMO = HUMAN / "062_dice.json"
pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]
#: grasps asked of each demo, and the 3/4 of them it must give
N, MIN_KEPT = 64, 48


def _lowest_elevation_m(hand: Hand, table, palm_pose: np.ndarray, points: np.ndarray) -> float:
    cfg = hand.config.palm
    verts = palm_box_vertices(np.asarray(cfg.box_center), np.asarray(cfg.box_half_extents))
    v_obj = palm_pose[:3] + verts @ quat_to_mat(palm_pose[3:]).T
    return float(min(table.elevation_m(v_obj).min(), table.elevation_m(points).min(initial=np.inf)))


@pytest.fixture(scope="module", params=["004_sugar_box", "024_bowl", "062_dice"])
def kept(request, tmp_path_factory):
    demo = load_demo(HUMAN / f"{request.param}.json")
    out = tmp_path_factory.mktemp("ctx")
    summary = augment_demo(demo, out, AugmentOptions(n=N, gallery=0, validate=None), force=True)
    return demo, dataset.load(summary.dataset)[demo.object]


def test_a_table_demo_augments_above_its_table_with_its_fingers(kept) -> None:
    demo, table = kept
    assert demo.table is not None and len(table) >= MIN_KEPT
    hand = Hand.load(demo.hand)
    plane = demo_table(demo, None)
    clearance = 0.0
    for i in range(len(table)):
        pts, _, _ = table.contacts(i)
        assert _lowest_elevation_m(hand, plane, table["palm_pose"][i], pts) >= clearance - 1e-9
    used = {f for row in table["fingers_used"] for f, on in zip(table.finger_names, row, strict=True) if on}
    assert used <= set(demo.fingers)


def test_without_table_mode_grasps_reach_below_it() -> None:
    demo = load_demo(DEMO)
    assert demo_table(demo, False) is False
    from augment.autows.build import build_workspace
    from augment.autows.seed import DemoSeed
    from augment.object_cloud import object_cloud
    from dexaug.pipeline.run import demo_fingers, generate_grasps
    from sim.world.objects import load_object

    hand = Hand.load(demo.hand)
    res = generate_grasps(hand, object_cloud(load_object(demo.object)),
                          build_workspace(hand, demo=DemoSeed.from_demo(demo)), n=30, table=False,
                          finger_names=demo_fingers(demo), finger_iteration=False, seed=0,
                          time_budget_s=60.0, workers=1)
    plane = demo_table(demo, None)
    lows = [_lowest_elevation_m(hand, plane, np.r_[g.grasp.palm_pos, g.grasp.palm_quat_wxyz],
                                np.asarray(g.contact_points)) for g in res.grasps]
    assert min(lows) < 0.0, "some grasp of the free object reaches under the demo's table"
