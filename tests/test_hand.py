"""Hand model: config validation, batched forward kinematics against MuJoCo, controls."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from sim.errors import ConfigError, GraspInputError
from sim.hand.config import hand_config_path, hand_names, load_hand_config
from sim.hand.model import Hand
from tests.conftest import needs_menagerie

HANDS = hand_names()


def _random_q(hand: Hand, n: int, seed: int) -> np.ndarray:
    lo = np.where(np.isfinite(hand.lower), hand.lower, -1.0)
    hi = np.where(np.isfinite(hand.upper), hand.upper, 1.0)
    return np.random.default_rng(seed).uniform(lo, hi, (n, hand.nq))


@needs_menagerie
@pytest.mark.parametrize("name", HANDS)
def test_fingertip_fk_matches_mujoco(name: str) -> None:
    hand = Hand.load(name)
    q = _random_q(hand, 200, seed=1)
    tips = hand.fingertip_sites(q)
    tips_palm = hand.fingertip_sites(q, frame="palm")
    palm_pos, palm_quat = hand.palm_pose(q)
    data = mujoco.MjData(hand.model)
    for i in range(len(q)):
        data.qpos[:] = q[i]
        mujoco.mj_kinematics(hand.model, data)
        np.testing.assert_allclose(tips[i], data.site_xpos[hand.tip_site_ids], atol=1e-9, rtol=0)
        # the palm-frame answer is the same points seen from frame_palm
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, palm_quat[i])
        world = palm_pos[i] + tips_palm[i] @ rot.reshape(3, 3).T
        np.testing.assert_allclose(world, data.site_xpos[hand.tip_site_ids], atol=1e-9, rtol=0)


@needs_menagerie
@pytest.mark.parametrize("name", HANDS)
def test_one_body_chain_gives_the_numbers_of_the_whole_tree(name: str) -> None:
    """``body_pose`` walks one body's ancestors only (placing a hand at a palm pose: 0.4
    instead of 2.8 ms on the Shadow Hand); every body's pose must be bit for bit the one the
    whole-tree pass gives, so validation places grasps exactly as before."""
    hand = Hand.load(name)
    q = _random_q(hand, 50, seed=3)
    pos, quat = hand.kinematics.body_poses(q)
    for body in range(1, hand.model.nbody):
        one_pos, one_quat = hand.kinematics.body_pose(q, body)
        assert np.array_equal(one_pos, pos[:, body]) and np.array_equal(one_quat, quat[:, body])


@needs_menagerie
def test_skeleton_runs_along_the_links(shadow: Hand) -> None:
    q = _random_q(shadow, 5, seed=2)
    pts = shadow.skeleton(q, "forefinger", spacing_m=0.005)
    gaps = np.linalg.norm(np.diff(pts, axis=1), axis=-1)
    assert gaps.max() <= 0.005 + 1e-9
    np.testing.assert_allclose(pts[:, -1], shadow.fingertip_sites(q, frame="palm")[:, 1], atol=1e-12)


@needs_menagerie
def test_ctrl_for_maps_coupled_tendons(shadow: Hand) -> None:
    q = _random_q(shadow, 1, seed=3)[0]
    ctrl = shadow.ctrl_for(q)
    m = shadow.model
    a = m.actuator("rh_A_FFJ0").id
    ff1, ff2 = (m.joint(n).qposadr[0] for n in ("rh_FFJ1", "rh_FFJ2"))
    expected = np.clip(q[ff1] + q[ff2], *m.actuator_ctrlrange[a])
    assert ctrl[a] == pytest.approx(expected)
    # holding ctrl_for(q) in MuJoCo with gravity off keeps the hand at q (position servo at rest)
    data = mujoco.MjData(m)
    # finger flexion only (abducted fingers would collide with each other and not reach q0)
    flex = [n[-2:] in ("J1", "J2", "J3") and "TH" not in n for n in shadow.joint_names]
    q0 = shadow.clip(shadow.fill_coupled(np.where(flex, 0.3, 0.0)))
    data.qpos[:] = q0
    data.ctrl[:] = shadow.ctrl_for(q0)
    m.opt.gravity[:] = 0
    mujoco.mj_step(m, data, nstep=500)
    # every actuator's transmission (single joints, and J1+J2 for the tendons) is held at q0;
    # how a tendon shares its sum between J1 and J2 is up to the dynamics (underactuated)
    np.testing.assert_allclose(shadow._transmission @ data.qpos, shadow._transmission @ q0,
                               atol=0.03)


@needs_menagerie
def test_wrong_length_joint_vector_is_a_clear_error(shadow: Hand) -> None:
    with pytest.raises(GraspInputError, match=r"expected 24 joint values .* got shape \(23,\)"):
        shadow.fingertip_sites(np.zeros(23))
    with pytest.raises(GraspInputError, match="NaN"):
        shadow.ctrl_for(np.full(24, np.nan))


@needs_menagerie
def test_unknown_joint_in_config_names_file_and_joint(tmp_path: Path) -> None:
    text = hand_config_path("shadow_right").read_text()
    text = text.replace('"rh_FFJ3"', '"rh_FFJ9"', 1).replace("rh_FFJ3 = [20, 50], ", "")
    bad = tmp_path / "bad_hand.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=r"bad_hand\.toml.*unknown joint 'rh_FFJ9'"):
        Hand.load(bad)


@needs_menagerie
def test_a_fingertip_that_cannot_touch_is_refused(shadow: Hand) -> None:
    """A fingertip body whose geoms all have contype = conaffinity = 0 (visual only) is a config
    error naming the file and finger (the real model, its tip geoms' collision switched off)."""
    from sim.hand.model_checks import check_fingertip_collision

    m = shadow.spec().compile()                                    # a copy to edit
    check_fingertip_collision(m, shadow.config, "shadow")          # as shipped: fine
    tip = shadow.config.fingers[1]
    geoms = m.geom_bodyid == m.body(tip.tip_body).id
    m.geom_contype[geoms] = m.geom_conaffinity[geoms] = 0
    with pytest.raises(ConfigError, match=rf"hand\.toml: fingers '{tip.name}'\.tip_body: .*"
                                          r"no collision geometry"):
        check_fingertip_collision(m, shadow.config, "shadow")


@needs_menagerie
def test_a_coupling_the_model_does_not_simulate_is_refused() -> None:
    """The Barrett BH8's distal joints follow their medial joints by an equality constraint
    (coefficient 0.3217); a config with another coefficient, or none, is refused naming the
    file and key."""
    import dataclasses

    barrett = load_hand_config("barrett_bh8")
    finger = barrett.fingers[0]
    follower, (leader, coef) = next(iter(finger.coupled_to.items()))
    for coupled, message in (({follower: (leader, 0.5)}, rf"{follower}: the config says"),
                             ({}, "treats both as independent")):
        bad = dataclasses.replace(barrett, fingers=(dataclasses.replace(finger, coupled_to=coupled),
                                                    *barrett.fingers[1:]))
        with pytest.raises(ConfigError, match=rf"barrett_bh8/hand\.toml: fingers "
                                              rf"'{finger.name}'\.coupled_to.*{message}"):
            Hand(bad)
    assert coef == pytest.approx(0.3217, abs=1e-4)


def test_config_errors_name_the_key(tmp_path: Path) -> None:
    base = hand_config_path("shadow_right").read_text()
    cases = {
        "v_u = [0.0, 0.0, 1.0]": ("v_u = [0.0, -2.0, 0.0]", "parallel"),
        "rh_FFJ3 = [20, 50]": ("rh_FFJ3 = [50, 20]", "empty range"),
        "[palm]": ("[palm]\nbogus = 1", r"unknown key\(s\) \['bogus'\]"),
        "link_radius_m = 0.008": ("link_radius_m = -0.008", r"geometry.*link_radius_m.*positive"),
    }
    for i, (old, (new, message)) in enumerate(cases.items()):
        path = tmp_path / f"case{i}.toml"
        path.write_text(base.replace(old, new, 1))
        with pytest.raises(ConfigError, match=message):
            load_hand_config(path)
    with pytest.raises(ConfigError, match="unknown hand 'no_such_hand'"):
        load_hand_config("no_such_hand")
