"""Scene composition: the floating hand follows its mocap target, the object is free, the
table and cameras are there."""

from __future__ import annotations

import mujoco
import numpy as np

from sim.hand.model import Hand
from sim.world.objects import load_object
from sim.world.scene import TABLE_TOP_Z, Scene
from tests.conftest import needs_menagerie

pytestmark = needs_menagerie


def test_floating_hand_follows_mocap_target(shadow: Hand) -> None:
    scene = Scene(shadow, load_object("cylinder"), table=True)
    m, d = scene.model, scene.data
    assert m.camera("overview").id >= 0 and m.geom("table").id == scene.table_geom
    mujoco.mj_resetData(m, d)
    scene.set_object_pose(np.array([0.0, 0.0, TABLE_TOP_Z + 0.3]), np.array([1.0, 0, 0, 0]))
    start = np.array([0.3, 0.2, 0.5])
    scene.set_hand_pose(start, np.array([1.0, 0, 0, 0]))
    scene.set_hand_ctrl(np.zeros(shadow.nq))
    target = start + np.array([0.0, 0.0, 0.05])
    scene.set_hand_pose(target, np.array([1.0, 0, 0, 0]), teleport=False)
    mujoco.mj_step(m, d, nstep=500)  # 2 s: the weld pulls the base onto the target
    base = d.qpos[scene.base_qadr:scene.base_qadr + 3]
    assert np.linalg.norm(base - target) < 2e-3
    # the free object fell onto the table and rests there
    obj_pos, _ = scene.object_pose()
    assert abs(obj_pos[2] - (TABLE_TOP_Z + 0.05)) < 5e-3  # cylinder half height 5 cm


def test_scene_joint_and_actuator_maps_match_the_hand(shadow: Hand) -> None:
    scene = Scene(shadow, load_object("box"))
    assert len(scene.hand_qadr) == shadow.nq
    assert len(scene.hand_act) == shadow.model.nu
    q = shadow.clip(np.full(shadow.nq, 0.2))
    scene.set_hand_joints(q)
    np.testing.assert_array_equal(scene.data.qpos[scene.hand_qadr], q)
    assert scene.obj_mass_kg > 0
    assert scene.hand_geom_mask.sum() > 0 and scene.obj_geom_mask.sum() > 0
