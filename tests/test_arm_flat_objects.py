"""Hand–arm grasps of an object lying flat (paper §5.3, #54): the flat screwdriver, its 3 cm
handle on the table, is grasped from above with the grasps made as it lies. Two things make
that possible (:func:`sim.arm.plan.hand_for_approach`): the wrist bends so the forearm need not
come down to the table top, and the pregrasp's fingers open only as far as the table allows.
Before them no (placement, grasp) pair of the screwdriver held on the UR5e (0 of 84 on six
placements, ``benchmarks/bench_arm.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dexaug.pipeline.rest_grasps import RestGrasps
from sim.arm.config import load_arm_config
from sim.arm.evaluate import evaluate_on_arm
from sim.arm.ik import IKSettings, solve_palm_ik
from sim.arm.placement import palm_targets, sample_placements
from sim.arm.plan import hand_for_approach
from sim.arm.scene import ArmScene
from sim.arm.simulate import settle_object
from sim.demo import load_demo
from sim.hand.model import Hand
from sim.validate.config import ValidateConfig
from sim.validate.validator import Validator
from sim.world.objects import load_object
from sim.world.resting import resting_poses
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb, pytest.mark.timeout(600),
              pytest.mark.filterwarnings("ignore:Attach conflict")]

REPO = Path(__file__).resolve().parents[1]
NAME = "043_phillips_screwdriver"


@pytest.fixture(scope="module")
def flat():
    """The screwdriver's demo, hand, object and grasps made for it lying flat (its one resting
    pose), those that hold hanging as it hangs."""
    demo = load_demo(REPO / "recordings" / "demos" / f"{NAME}.json")
    hand, obj = Hand.load(demo.hand), load_object(NAME)
    source = RestGrasps(hand, obj, demo, n=16, workers=1)
    (pose,) = resting_poses(obj).poses   # it only ever lies flat
    grasps = source(0, pose)
    assert len(grasps) >= 2, source.made
    return hand, obj, source


def test_the_pregrasp_opens_only_as_far_as_the_table_allows(flat) -> None:
    """At a palm-down grasp of the lying screwdriver, the pregrasp the validator makes puts a
    finger in the table; the approach's pregrasp keeps the IK's hand margin, lies between that
    pregrasp and the grasp (or is as far from the table as the grasp's own fingers, when they
    are within that margin), and the grasp's fingers are unchanged (the wrist may bend)."""
    hand, obj, source = flat
    cfg = ValidateConfig.load()
    validator = Validator(hand, obj, cfg)
    scene = ArmScene(load_arm_config("ur5e"), hand, obj, contact=cfg.common.contact,
                     servos=validator.servos)
    assert scene.table is not None   # the arm scene's default table
    (place,) = sample_placements(obj, resting_poses(obj), 1, seed=0, area_x_m=(0.45, 0.5),
                                 area_y_m=(-0.05, 0.05), top_z_m=scene.table.top_z_m)
    settled = settle_object(scene, place.pos, place.quat_wxyz)
    q_obj = settled.qpos[scene.obj_qadr:scene.obj_qadr + 7]
    grasps = source(0, resting_poses(obj).poses[0])
    pos, quat = palm_targets(grasps, q_obj[:3], q_obj[3:])
    margin = IKSettings().hand_min_distance_m
    fingers = np.setdiff1d(np.arange(hand.nq), scene.hand_ik_free)
    checked = 0
    for g, p, r in zip(grasps, pos, quat, strict=True):
        pregrasp = validator.stages(g).pregrasp
        at = solve_palm_ik(scene, p, r, g.joints, free_wrist=True)
        if not at.reachable:
            continue
        opened = scene.qpos(at.arm_q_rad, np.where(np.isin(np.arange(hand.nq), fingers),
                                                   pregrasp, at.q[scene.hand_qadr]))
        if scene.table_clearance_m(opened) >= margin:
            continue   # this grasp's pregrasp clears the table anyway
        pre, grasp_q = hand_for_approach(scene, p, r, pregrasp, g.joints)
        np.testing.assert_array_equal(grasp_q[fingers], np.asarray(g.joints)[fingers])
        closed = scene.table_clearance_m(scene.qpos(at.arm_q_rad, grasp_q))
        # the margin, or as near it as the grasp's own fingers come (their pregrasp can be no
        # farther from the table than they are)
        assert scene.table_clearance_m(scene.qpos(at.arm_q_rad, pre)) >= min(margin, closed)
        span = pregrasp[fingers] - grasp_q[fingers]
        t = (pre[fingers] - grasp_q[fingers]) @ span / (span @ span)
        assert 0.0 <= t < 1.0
        np.testing.assert_allclose(pre[fingers], grasp_q[fingers] + t * span, atol=1e-9)
        checked += 1
    assert checked, "no palm-down grasp whose full pregrasp is in the table"


def test_grasps_made_as_it_lies_lift_the_flat_screwdriver_with_the_arm(flat) -> None:
    hand, obj, source = flat
    _, results = evaluate_on_arm(load_arm_config("ur5e"), hand, obj, source, placements=3, seed=0)
    held = [r for r in results if r.passed]
    assert held, sorted({r.detail for r in results})
    assert all(r.lifted_m > 0.05 for r in held)
