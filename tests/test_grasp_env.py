"""The grasp scene as a dm_env environment (sim.envs, issue #55): it passes dm_env's own
conformance mixin; a reset starts at the validator's pregrasp; the action spec is the
actuators' ranges; lift-drop ends every episode, rewarding a held grasp only; replaying a
rolled-out grasp's actions through it gives the validator's pass/fail; and dm-control stays
out of the base install (an optional extra whose absence is one clear error)."""

from __future__ import annotations

import subprocess
import sys
import tomllib

import numpy as np
import pytest

from sim.episodes.rollout import rollout
from sim.hand.model import Hand
from sim.paths import REPO_ROOT
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb
from tests.test_episodes import shifted_grasps

pytestmark = pytest.mark.slow

try:   # the "envs" extra; without it only the first two tests run
    from absl.testing import absltest
    from dm_env import test_utils

    from sim.envs.grasp_env import episode_actions, grasp_env, run_actions
except ImportError:
    HAVE_DM_CONTROL = False
else:
    HAVE_DM_CONTROL = True

needs_dm_control = pytest.mark.skipif(not HAVE_DM_CONTROL,
                                      reason="dm-control not installed (the 'envs' extra)")

OBJECT = "062_dice"
_CACHE: dict[str, object] = {}


def test_dm_control_is_an_optional_extra_only() -> None:
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    assert not any("dm-control" in d or "dm_control" in d for d in project["dependencies"])
    assert any(d.startswith("dm-control") for d in project["optional-dependencies"]["envs"])


def test_without_dm_control_the_error_names_the_extra() -> None:
    code = ("import sys; sys.modules['dm_control'] = None\n"
            "try:\n    import sim.envs.grasp_env\n"
            "except ImportError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=REPO_ROOT, check=True).stdout
    assert out.strip() == "sim.envs needs dm-control: pip install 'dexaug[envs]'"



def _setup() -> tuple[Validator, list, list]:
    """The dice validator, its shifted demo grasps and their rolled-out episodes (once)."""
    if not _CACHE:
        v = Validator(Hand.load("shadow_right"), load_object(OBJECT))
        grasps = shifted_grasps(OBJECT)
        _CACHE.update(v=v, grasps=grasps, episodes=[rollout(v, g, index=i)
                                                    for i, g in enumerate(grasps)])
    return _CACHE["v"], _CACHE["grasps"], _CACHE["episodes"]  # type: ignore[return-value]


if HAVE_DM_CONTROL:
    @needs_menagerie
    @needs_ycb
    class GraspEnvConformanceTest(test_utils.EnvironmentTestMixin, absltest.TestCase):
        """dm_env's own checks, the action sequence a whole passing episode (so its end is
        checked too), 25 physics steps an action."""

        def make_object_under_test(self):
            v, grasps, _ = _setup()
            env = grasp_env(v, grasps[:1], n_sub_steps=25)
            env.task.select(0)
            return env

        def make_action_sequence(self):
            _, _, episodes = _setup()
            actions = episode_actions(episodes[0])
            for _ in range(2):   # the episode ends within the first pass: reset is tested too
                yield from actions[::25]


@needs_dm_control
@needs_menagerie
@needs_ycb
def test_reset_starts_at_the_validators_pregrasp() -> None:
    v, grasps, episodes = _setup()
    env = grasp_env(v, grasps)
    for i in (0, 2):
        env.task.select(i)
        obs = env.reset().observation
        assert np.array_equal(obs["hand_qpos"], episodes[i].states["hand_qpos"][0])
        assert np.array_equal(obs["object_pos"], episodes[i].states["object_pose"][0, :3])
        assert env.task.grasp_index == i


@needs_dm_control
@needs_menagerie
@needs_ycb
def test_action_spec_is_the_actuators_ranges() -> None:
    v, grasps, _ = _setup()
    env = grasp_env(v, grasps)
    spec = env.action_spec()
    scene = env.task.scene
    nu = len(scene.hand_act)
    assert spec.shape == (nu + 6,)
    assert np.array_equal(spec.minimum[:nu], scene.model.actuator_ctrlrange[scene.hand_act, 0])
    assert np.array_equal(spec.maximum[:nu], scene.model.actuator_ctrlrange[scene.hand_act, 1])
    assert set(env.observation_spec()) >= {"hand_qpos", "palm_pos", "object_quat",
                                           "fingertip_contact", "fingertip_force"}


@needs_dm_control
@needs_menagerie
@needs_ycb
def test_replayed_grasps_pass_and_fail_as_lift_drop_says() -> None:
    """Every episode's actions through the environment: the same verdict and reason as the
    validator's (the issue asks ≥ 95 %; here they must all agree), reward 1 only on a pass."""
    v, grasps, episodes = _setup()
    env = grasp_env(v, grasps)
    verdicts = []
    for i, (g, ep) in enumerate(zip(grasps, episodes, strict=True)):
        want = v.validate(g, "lift-drop")
        env.task.select(i)
        env.reset()
        last = run_actions(env, episode_actions(ep))
        assert last.discount == 0.0
        verdicts.append((last.reward == 1.0, env.task.failure))
        assert verdicts[-1] == (want.passed, want.failure), i
    assert {p for p, _ in verdicts} == {True, False}


@needs_dm_control
@needs_menagerie
@needs_ycb
def test_an_approached_episode_replays_through_an_approaching_environment() -> None:
    """With ``approach_m`` the environment starts the hand out along its palm normal and the
    protocol judges from the end of the approach: the rollout's approached episode, replayed,
    gives its states and verdict."""
    v, grasps, _ = _setup()
    ep = rollout(v, grasps[0], approach_m=0.05)
    env = grasp_env(v, grasps, approach_m=0.05)
    env.task.select(0)
    first = env.reset().observation
    assert np.array_equal(first["palm_pos"], ep.states["palm_pose"][0, :3])
    steps = 0
    for a in episode_actions(ep):
        step, steps = env.step(a), steps + 1
        if step.last():
            break
    assert steps == len(ep)   # the verdict comes with the episode's last step, not before
    assert np.array_equal(step.observation["hand_qpos"], ep.states["hand_qpos"][-1])
    assert (step.reward == 1.0, env.task.failure) == (ep.success, ep.failure) == (True, None)


@needs_dm_control
@needs_menagerie
@needs_ycb
def test_a_hand_that_never_closes_is_not_rewarded() -> None:
    v, grasps, _ = _setup()
    env = grasp_env(v, grasps[:1], n_sub_steps=10)
    env.reset()
    last = run_actions(env, np.zeros((0, 0)))   # holds the pregrasp where it stands
    assert last.reward == 0.0 and env.task.failure in ("lost_contact", "slipped")


@needs_dm_control
@needs_menagerie
@needs_ycb
def test_camera_observation() -> None:
    v, grasps, _ = _setup()
    env = grasp_env(v, grasps[:1], camera=(48, 64))
    try:
        image = env.reset().observation["camera"]
    except Exception as exc:   # no EGL/OSMesa here: the image is optional
        pytest.skip(f"no offscreen rendering: {exc}")
    assert image.shape == (48, 64, 3) and image.dtype == np.uint8
    assert image.std() > 1.0   # something drawn, not a blank frame


HAND_FOLDERS = sorted(p.parent.name for p in (REPO_ROOT / "configs" / "hands").glob("*/hand.toml"))


@needs_dm_control
@needs_menagerie
@needs_ycb
@pytest.mark.parametrize("hand_name", HAND_FOLDERS)
def test_every_hand_folder_makes_an_environment(hand_name: str) -> None:
    """Specs from each hand's own actuators and fingers; observations and actions conform;
    the protocol ends the episode as the validator decides (an open hand 7 cm off the can)."""
    from sim.grasp import Grasp

    hand = Hand.load(hand_name)
    v = Validator(hand, load_object("005_tomato_soup_can"))
    grasp = Grasp.from_arrays([0.0, -0.07, 0.05], [1.0, 0.0, 0.0, 0.0], hand.open_pose)
    env = grasp_env(v, [grasp], n_sub_steps=20)
    spec, obs_spec = env.action_spec(), env.observation_spec()
    assert spec.shape == (len(env.task.scene.hand_act) + 6,)
    assert np.isfinite(spec.minimum).all() and (spec.minimum < spec.maximum).all()
    assert obs_spec["fingertip_force"].shape == (len(hand.config.fingers),)
    obs = env.reset().observation
    for k, s in obs_spec.items():
        s.validate(obs[k])
    last = run_actions(env, np.array([spec.generate_value()]))
    assert last.reward == 0.0
    assert env.task.failure == v.validate(grasp, "lift-drop").failure
