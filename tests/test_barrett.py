"""The Barrett Hand BH8 model built by dexaug (``configs/hands/barrett_bh8/``), end to end.

The MJCF is ours (from the dex-urdf URDF), so its physics is checked here in MuJoCo itself:
the mass read back from the compiled model, the real hand's coupling (one spread motor for
fingers 1 and 2, one flexion motor per finger driving medial and distal) holding in a
simulation, the actuators' limits, colliding fingertips; then the project's pipeline on it:
an AutoWS workspace, FSG grasps of the soup can and their lift-drop validation.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sim.hand.model import Hand
from sim.paths import SHARED_ASSETS
from tests.conftest import needs_ycb

NAME = "barrett_bh8"
# bh8.xml reads its meshes from the shared asset folder beside the checkout
pytestmark = pytest.mark.skipif(not (SHARED_ASSETS / "barrett_hand").is_dir(),
                                reason=f"no Barrett assets at {SHARED_ASSETS / 'barrett_hand'}")
SETTLE_S = 3.0          # simulated seconds for a position servo to reach its target
ANGLE_TOL_RAD = 0.03    # servo steady-state error allowed (joint damping, coupling compliance)


@pytest.fixture(scope="module")
def hand() -> Hand:
    return Hand.load(NAME)


def _settle(hand: Hand, ctrl: dict[str, float]) -> mujoco.MjData:
    """Simulate the bare hand (base fixed, no gravity: only the servos and the couplings act)
    with the named actuators at ``ctrl`` (radians) and the others at 0; a model of its own,
    so the shared one keeps its gravity."""
    m = hand.spec().compile()
    d = mujoco.MjData(m)
    m.opt.gravity[:] = 0.0
    for name, value in ctrl.items():
        d.ctrl[m.actuator(name).id] = value
    for _ in range(int(SETTLE_S / m.opt.timestep)):
        mujoco.mj_step(m, d)
    return d


def _q(hand: Hand, d: mujoco.MjData, joint: str) -> float:
    return float(d.qpos[hand.model.joint(joint).qposadr[0]])


def test_mass_is_a_real_bh8s(hand: Hand) -> None:
    """About 1.2 kg (a BH8-282), not the URDF's 2.6 kg; read from the compiled model."""
    root = hand.model.body(hand.config.root_body).id
    assert 1.0 <= hand.model.body_subtreemass[root] <= 1.4
    assert (hand.model.body_mass[1:] > 0).all() and (hand.model.body_inertia[1:] > 0).all()


def test_config_coupling_matches_the_model(hand: Hand) -> None:
    """Every coupled_to of the config is an equality constraint of the model with the same
    coefficient (FSG plans with the config's, the simulation holds the model's)."""
    m = hand.model
    model_coupling = {}
    for e in range(m.neq):
        if int(m.eq_type[e]) == int(mujoco.mjtEq.mjEQ_JOINT):
            follower, leader = m.joint(m.eq_obj1id[e]).name, m.joint(m.eq_obj2id[e]).name
            model_coupling[follower] = (leader, float(m.eq_data[e, 1]))
            assert m.eq_data[e, 0] == 0 and not m.eq_data[e, 2:5].any()   # linear, no offset
    config_coupling = {fol: lead for f in hand.config.fingers for fol, lead in f.coupled_to.items()}
    assert len(config_coupling) == 3
    for follower, (leader, coef) in config_coupling.items():
        assert model_coupling[follower][0] == leader
        assert model_coupling[follower][1] == pytest.approx(coef, abs=1e-6)


@pytest.mark.parametrize("finger", ["finger_1", "finger_2", "finger_3"])
def test_one_flexion_motor_drives_medial_and_distal(hand: Hand, finger: str) -> None:
    cfg = hand.config.finger(finger)
    med, dist = f"{finger}_med_joint", f"{finger}_dist_joint"
    _, coef = cfg.coupled_to[dist]
    target = 1.2
    d = _settle(hand, {f"{finger}_flex": target})
    assert _q(hand, d, med) == pytest.approx(target, abs=ANGLE_TOL_RAD)
    assert _q(hand, d, dist) / _q(hand, d, med) == pytest.approx(coef, abs=0.01)
    others = [j for f in hand.config.fingers if f.name != finger for j in f.joints]
    assert all(abs(_q(hand, d, j)) < ANGLE_TOL_RAD for j in others)   # the other fingers stay


def test_one_spread_motor_turns_fingers_1_and_2_opposite_ways(hand: Hand) -> None:
    target = 0.8
    d = _settle(hand, {"spread": target})
    assert _q(hand, d, "finger_1_prox_joint") == pytest.approx(target, abs=ANGLE_TOL_RAD)
    assert _q(hand, d, "finger_2_prox_joint") == pytest.approx(target, abs=ANGLE_TOL_RAD)
    tips = {f: d.xpos[hand.model.body(f"{f}_dist_link").id] for f in ("finger_1", "finger_2")}
    # mirror images across the base's x = 0 plane: they turned in opposite directions, apart
    assert tips["finger_1"][0] == pytest.approx(-tips["finger_2"][0], abs=1e-3)
    assert tips["finger_1"][0] - tips["finger_2"][0] > 0.1
    assert tips["finger_1"][1:] == pytest.approx(tips["finger_2"][1:], abs=1e-3)


def test_actuators_follow_the_joint_limits(hand: Hand) -> None:
    """Control ranges are the URDF's joint ranges; every servo is force-limited."""
    m = hand.model
    assert m.nu == 4
    for finger in ("finger_1", "finger_2", "finger_3"):
        a = m.actuator(f"{finger}_flex")
        np.testing.assert_allclose(a.ctrlrange, m.joint(f"{finger}_med_joint").range)
    np.testing.assert_allclose(m.actuator("spread").ctrlrange, m.joint("finger_1_prox_joint").range)
    assert m.actuator_forcelimited.all() and (m.actuator_forcerange[:, 1] > 0).all()
    # ctrl_for maps a joint vector to these actuators: the spread is the two joints' mean
    q = np.zeros(hand.nq)
    q[hand.joint_names.index("finger_1_prox_joint")] = 0.4
    q[hand.joint_names.index("finger_2_prox_joint")] = 0.6
    q[hand.joint_names.index("finger_3_med_joint")] = 1.0
    ctrl = hand.ctrl_for(q)
    assert ctrl[m.actuator("spread").id] == pytest.approx(0.5)
    assert ctrl[m.actuator("finger_3_flex").id] == pytest.approx(1.0)


def test_every_fingertip_collides_with_its_sampled_mesh(hand: Hand) -> None:
    """The fingertip surface AutoWS samples (tip_mesh) is a colliding geom of the tip body."""
    m = hand.model
    for f in hand.config.fingers:
        body = m.body(f.tip_body).id
        mesh = m.mesh(f.tip_mesh).id
        colliding = [g for g in range(m.ngeom) if m.geom_bodyid[g] == body
                     and (m.geom_contype[g] or m.geom_conaffinity[g])]
        assert colliding, f.name
        assert any(m.geom_dataid[g] == mesh for g in colliding), f.name


@needs_ycb
def test_workspace_fsg_and_lift_drop_on_the_soup_can(hand: Hand) -> None:
    from augment.autows.build import build_workspace
    from augment.object_cloud import object_cloud
    from dexaug.pipeline.run import generate_grasps
    from sim.validate.batch import validate_many
    from sim.world.objects import load_object

    ws = build_workspace(hand, cache=False)
    assert ws.finger_names == hand.finger_names
    assert all(f.n_points > 0 and f.n_faces > 0 for f in ws.fingers)
    obj = load_object("005_tomato_soup_can")
    res = generate_grasps(hand, object_cloud(obj), ws, n=2, seed=0, time_budget_s=30.0, workers=1)
    assert res.grasps, res.stats
    for g in res.grasps:   # the planned spread is one the hand can hold: fingers 1 and 2 equal
        q = g.grasp.joints
        assert q[hand.joint_names.index("finger_1_prox_joint")] == pytest.approx(
            q[hand.joint_names.index("finger_2_prox_joint")])
    results = validate_many(hand.name, obj.name, [g.grasp for g in res.grasps], "lift-drop",
                            workers=1)
    assert len(results) == len(res.grasps)
    assert all(r.passed == (r.failure is None) for r in results)
