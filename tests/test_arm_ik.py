"""Hand–arm grasps on a table (paper §5.3), first slice: each arm config composes with the
default hand on its flange, whole-body IK reaches poses the arm can reach (1 mm / 1°) and says
``reachable=False`` for ones it cannot, and broken arm / mount configs give one-line errors
naming the file and the key."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from sim.arm.config import arm_names, load_arm_config
from sim.arm.ik import IKSettings, solve_palm_ik
from sim.arm.scene import ArmScene
from sim.errors import ConfigError
from sim.hand.config import default_hand_name, hand_dir, load_hand_config
from sim.hand.model import Hand
from sim.transforms import pose_mul, quat_angle
from sim.world.objects import load_object
from tests.conftest import needs_menagerie

pytestmark = [needs_menagerie, pytest.mark.filterwarnings("ignore:Attach conflict")]
ARMS = ("ur5e", "kuka_iiwa_14")


@pytest.fixture(scope="module")
def hand() -> Hand:
    return Hand.load(default_hand_name())


@pytest.fixture(scope="module", params=ARMS)
def scene(request: pytest.FixtureRequest, hand: Hand) -> ArmScene:
    return ArmScene(load_arm_config(request.param), hand)


def _random_reachable_target(scene: ArmScene, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """FK of a seeded random in-limits arm configuration near home whose palm is above the
    table and whose arm and hand keep 1 cm off it (a pose in the table is no fair target):
    (palm pos m, palm quat wxyz, the arm configuration rad)."""
    rng = np.random.default_rng(seed)
    lo, hi = scene.arm_limits()
    for _ in range(100):
        arm_q = np.clip(scene.arm.home_rad + rng.uniform(-0.6, 0.6, len(lo)), lo, hi)
        qpos = scene.qpos(arm_q)
        pos, quat = scene.site_pose(qpos)
        if pos[2] > scene.table.top_z_m + 0.08 and scene.table_clearance_m(qpos) >= 0.01:
            return pos, quat, arm_q
    raise AssertionError("no random configuration with the palm above the table")


def test_both_arms_are_configured() -> None:
    assert set(ARMS) <= set(arm_names())


def test_composed_model_has_the_hand_joints_in_order(scene: ArmScene, hand: Hand) -> None:
    m = scene.model
    assert [m.joint(int(j)).name for j in m.dof_jntid[scene.hand_dadr]] == [
        f"hand/{n}" for n in hand.joint_names]
    assert [m.joint(int(j)).name for j in m.dof_jntid[scene.arm_dadr]] == [
        f"arm/{n}" for n in scene.arm.joints]
    assert len(scene.hand_qadr) == hand.nq and scene.obj_qadr == -1



def test_the_hand_sits_on_the_flange_through_its_mount(scene: ArmScene, hand: Hand) -> None:
    """frame_palm in the world = flange site ∘ [mount] ∘ the hand model's own palm pose, for a
    non-trivial hand posture (this caught the UR5e's unnormalised site quaternion)."""
    hand_q = hand.posture("preshape_pose")
    qpos = scene.qpos(hand_q=hand_q)
    palm_pos, palm_quat = scene.site_pose(qpos)
    flange_pos, flange_quat = scene.site_pose(qpos, scene.flange_site)
    mount = hand.config.mount
    base_pos, base_quat = pose_mul(flange_pos, flange_quat, mount.pos, mount.quat_wxyz)
    in_hand_pos, in_hand_quat = hand.palm_pose(hand_q)
    want_pos, want_quat = pose_mul(base_pos, base_quat, in_hand_pos[0], in_hand_quat[0])
    np.testing.assert_allclose(palm_pos, want_pos, atol=1e-6)
    assert quat_angle(palm_quat, want_quat) < 1e-5
    # and the home posture keeps the arm and hand clear of the table
    assert scene.table_clearance_m(scene.qpos()) > 0.05


@pytest.mark.parametrize("seed", [0, 1])
def test_ik_reaches_a_pose_from_forward_kinematics(scene: ArmScene, hand: Hand, seed: int) -> None:
    pos, quat, _ = _random_reachable_target(scene, seed)
    grasp_q = hand.posture("preshape_pose")
    result = solve_palm_ik(scene, pos, quat, grasp_q)
    assert result.reachable, result
    assert result.pos_err_m <= 1e-3 and result.rot_err_rad <= np.deg2rad(1.0)
    np.testing.assert_allclose(result.q[scene.hand_qadr], grasp_q)   # fingers stayed fixed
    assert result.table_clearance_m >= 0.0   # the collision limit kept the hand off the table
    got_pos, _ = scene.site_pose(result.q)
    assert np.linalg.norm(got_pos - pos) <= 1e-3
    lo, hi = scene.arm_limits()
    assert ((result.arm_q_rad >= lo - 1e-6) & (result.arm_q_rad <= hi + 1e-6)).all()


def test_reachability_check_can_fail(scene: ArmScene) -> None:
    """The solution that passes at 1 mm / 1° fails a 1e-9 tolerance given the same
    iteration budget: ``reachable`` is a real comparison, not a constant."""
    pos, quat, _ = _random_reachable_target(scene, 0)
    loose = solve_palm_ik(scene, pos, quat)
    tight = solve_palm_ik(scene, pos, quat, settings=IKSettings(
        pos_tol_m=1e-9, rot_tol_rad=1e-9, max_iterations=loose.iterations))
    assert loose.reachable and not tight.reachable
    assert tight.pos_err_m == pytest.approx(loose.pos_err_m, abs=1e-9) and tight.pos_err_m > 1e-9


def test_a_target_far_away_is_unreachable(scene: ArmScene) -> None:
    far = scene.arm.base_pos_m + np.array([2.0, 0.0, 0.0])
    result = solve_palm_ik(scene, far, np.array([1.0, 0.0, 0.0, 0.0]),
                           settings=IKSettings(max_iterations=100))
    assert not result.reachable and result.pos_err_m > 0.5
    assert np.isfinite(result.q).all()


def test_an_object_is_composed_and_left_where_it_is(hand: Hand) -> None:
    scene = ArmScene(load_arm_config(ARMS[0]), hand, load_object("cylinder"))
    assert scene.obj_qadr >= 0
    start = scene.qpos()
    pos, quat = scene.site_pose(start)
    result = solve_palm_ik(scene, pos + np.array([0.0, 0.05, -0.05]), quat, q_start=start)
    assert result.reachable
    np.testing.assert_array_equal(result.q[scene.obj_qadr:scene.obj_qadr + 7],
                                  start[scene.obj_qadr:scene.obj_qadr + 7])


def _one_line_error(match: str, fn: object, *args: object) -> str:
    with pytest.raises(ConfigError) as info:
        fn(*args)  # type: ignore[operator]
    message = str(info.value)
    assert "\n" not in message and re.search(match, message), message
    return message


def test_an_unknown_joint_names_the_file_and_key(tmp_path: Path) -> None:
    text = load_arm_config("ur5e").file.read_text()
    bad = tmp_path / "bad_arm.toml"
    bad.write_text(text.replace('"elbow_joint"', '"elbow_jiont"'))
    message = _one_line_error(r"joints\.names", load_arm_config, bad)
    assert str(bad) in message and "elbow_jiont" in message


def test_an_unknown_arm_lists_the_known_ones() -> None:
    message = _one_line_error("unknown arm", load_arm_config, "no_such_arm")
    assert all(a in message for a in ARMS)


def test_a_bad_mount_names_the_file_and_key(tmp_path: Path) -> None:
    text = (hand_dir(default_hand_name()) / "hand.toml").read_text()
    assert "[mount]" in text and load_hand_config(default_hand_name()).mount is not None
    bad = tmp_path / "hand.toml"
    head, _, mount = text.partition("[mount]")
    mount = re.sub(r"(?m)^quat_wxyz = .*$", "quat_wxyz = [2.0, 0.0, 0.0, 0.0]", mount, count=1)
    bad.write_text(f"{head}[mount]{mount}")
    message = _one_line_error(r"mount\.quat_wxyz", load_hand_config, bad)
    assert str(bad) in message


def test_the_mounts_free_wrist_joints_are_checked(tmp_path: Path, hand: Hand) -> None:
    """``[mount] ik_free_joints``: a repeated name is refused on load, a joint the hand lacks
    when the arm scene is built (it would silently stay frozen), both one line naming the key."""
    text = (hand_dir(default_hand_name()) / "hand.toml").read_text()
    assert re.search(r"(?m)^ik_free_joints = ", text)
    bad = tmp_path / "hand.toml"
    bad.write_text(re.sub(r"(?m)^ik_free_joints = .*$", 'ik_free_joints = ["rh_WRJ1", "rh_WRJ1"]',
                          text, count=1))
    assert str(bad) in _one_line_error(r"mount\.ik_free_joints", load_hand_config, bad)
    mount = dataclasses.replace(hand.config.mount, ik_free_joints=("rh_WRJ3",))
    wrong = Hand(dataclasses.replace(hand.config, mount=mount))
    message = _one_line_error(r"ik_free_joints.*rh_WRJ3", ArmScene, load_arm_config("ur5e"), wrong)
    assert str(hand.config.file) in message


def test_a_free_wrist_moves_only_the_mounts_joints(scene: ArmScene, hand: Hand) -> None:
    """With ``free_wrist`` the IK may bend the wrist, and only the wrist: the fingers stay the
    grasp's exactly, frame_palm is on its target, and the wrist stays within its limits."""
    pos, quat, _ = _random_reachable_target(scene, seed=3)
    grasp_q = hand.posture("preshape_pose")
    result = solve_palm_ik(scene, pos, quat, grasp_q, free_wrist=True)
    assert result.reachable
    got = result.q[scene.hand_qadr]
    fingers = np.setdiff1d(np.arange(hand.nq), scene.hand_ik_free)
    np.testing.assert_array_equal(got[fingers], grasp_q[fingers])
    lo, hi = scene.lower[scene.hand_qadr], scene.upper[scene.hand_qadr]
    assert np.all(got >= lo - 1e-6) and np.all(got <= hi + 1e-6)
    frozen = solve_palm_ik(scene, pos, quat, grasp_q)
    np.testing.assert_array_equal(frozen.q[scene.hand_qadr], grasp_q)
