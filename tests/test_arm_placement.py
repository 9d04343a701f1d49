"""Placements for hand–arm grasping: seeded resting placements on the table, hand-only grasps
carried to the object's pose, and the table pre-filter (a hand under the table top is rejected,
one above it kept)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.arm.placement import palm_targets, sample_placements, table_clear
from sim.grasp import Grasp
from sim.hand.config import default_hand_name
from sim.hand.model import Hand
from sim.transforms import pose_mul, quat_to_mat
from sim.world.objects import load_object
from sim.world.resting import resting_poses
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [needs_menagerie, needs_ycb]

TOP_Z = 0.75
AREA = ((0.45, 0.7), (-0.2, 0.2))


@pytest.fixture(scope="module")
def can():
    obj = load_object("005_tomato_soup_can")
    return obj, resting_poses(obj)


def test_placements_are_seeded_on_the_table_and_in_the_area(can) -> None:
    obj, poses = can
    a = sample_placements(obj, poses, 8, seed=1, area_x_m=AREA[0], area_y_m=AREA[1], top_z_m=TOP_Z)
    b = sample_placements(obj, poses, 8, seed=1, area_x_m=AREA[0], area_y_m=AREA[1], top_z_m=TOP_Z)
    c = sample_placements(obj, poses, 8, seed=2, area_x_m=AREA[0], area_y_m=AREA[1], top_z_m=TOP_Z)
    assert [p.pos.tolist() for p in a] == [p.pos.tolist() for p in b]
    assert [p.pos.tolist() for p in a] != [p.pos.tolist() for p in c]
    verts = obj.collision_mesh().vertices
    for p in a:
        assert AREA[0][0] <= p.pos[0] <= AREA[0][1] and AREA[1][0] <= p.pos[1] <= AREA[1][1]
        low = (verts @ quat_to_mat(p.quat_wxyz).T)[:, 2].min() + p.pos[2]
        assert low == pytest.approx(TOP_Z + 1e-3, abs=1e-6)   # resting just above the top
        assert 0 <= p.rest_index < len(poses)


def test_palm_targets_compose_object_and_grasp_poses() -> None:
    rng = np.random.default_rng(0)
    grasps = [Grasp.from_arrays(rng.normal(size=3) * 0.1, q / np.linalg.norm(q), np.zeros(3))
              for q in rng.normal(size=(4, 4))]
    obj_pos, obj_quat = np.array([0.6, 0.1, 0.8]), np.array([0.9, 0.1, -0.3, 0.2])
    obj_quat /= np.linalg.norm(obj_quat)
    wp, wq = palm_targets(grasps, obj_pos, obj_quat)
    for g, p, q in zip(grasps, wp, wq, strict=True):
        ep, eq = pose_mul(obj_pos, obj_quat, g.palm_pos, g.palm_quat_wxyz)
        assert np.allclose(p, ep) and np.allclose(q, eq)


def test_a_hand_under_the_table_top_is_filtered() -> None:
    hand = Hand.load(default_hand_name())
    q = np.zeros(len(hand.joint_names))
    upright = np.array([1.0, 0.0, 0.0, 0.0])
    obj_pos = np.array([0.6, 0.0, TOP_Z + 0.001])
    # frame_palm +y toward the object: from above (+y = world -z) and from below (+y = +z)
    down = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])    # +90° about x: y → z
    up = np.array([np.cos(np.pi / 4), -np.sin(np.pi / 4), 0.0, 0.0])     # -90° about x: y → -z
    above = Grasp.from_arrays([0.0, 0.0, 0.25], up, q)
    below = Grasp.from_arrays([0.0, 0.0, -0.05], down, q)
    mask = table_clear(hand, [above, below], obj_pos, upright, top_z_m=TOP_Z)
    assert mask.tolist() == [True, False]
