"""Every hand steps cleanly in the validator's scenes (issue #51), as MuJoCo Menagerie checks
its models: each hand of ``configs/hands/`` in each protocol's scene (``Validator.scene``: the
protocol's timestep, solver, contact and servo settings), the palm facing the procedural cylinder
at home, is stepped with seeded random control targets over the actuators' control ranges, and
any MuJoCo warning (``data.warning[i].number > 0``: bad qacc, contact or constraint buffer full,
...) or a non-finite qpos / qacc fails the hand, naming the warning.

The targets are held :data:`HOLD_STEPS` steps each (a new full-range target every 0.1 s, faster
than any protocol moves the servos): a new uniform target every single step (Menagerie's
per-step noise) drives leap_right's stiffened lift-drop servos (``kp_scale`` 1.67) unstable
within 2 s at some seeds, an excitation that no protocol produces."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sim.errors import AssetError
from sim.hand.config import hand_names, load_hand_config
from sim.hand.model import Hand
from sim.validate.config import PROTOCOLS
from sim.validate.validator import Validator
from sim.world.objects import load_primitive
from sim.world.scene import OBJECT_HOME, Scene
from tests.conftest import needs_menagerie

pytestmark = pytest.mark.slow

HANDS = hand_names()
#: each hand, those whose model comes from Menagerie skipped (saying why) where it is absent
HAND_PARAMS = [pytest.param(name, marks=needs_menagerie if load_hand_config(name).menagerie else ())
               for name in HANDS]
OBJECT = "cylinder"      # procedural: no YCB needed
STEPS = 500              # 2 s at the protocols' 4 ms step
HOLD_STEPS = 25          # steps each random control target is held
#: frame_palm from the object's axis (m), its palm face (+y) toward the object: the first of
#: these at which the open hand is clear of the cylinder (r 3.3 cm), the fingers reaching it
#: (the 2F-85's pads stand 13 cm out of its palm face)
PALM_GAPS_M = tuple(np.round(np.arange(0.07, 0.205, 0.01), 2))
SEED = 51


def _hand(name: str) -> Hand:
    try:
        return Hand.load(name)
    except AssetError as exc:   # a model file the config names is not here
        pytest.skip(f"{name}: model assets missing: {exc}")


@pytest.fixture(scope="module")
def cylinder():
    return load_primitive(OBJECT)


def _control_ranges(model: mujoco.MjModel, acts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The control range of each actuator of ``acts``: its ``ctrlrange`` when it has one (the
    dgb servos keep it with ``ctrllimited`` off), else ±1 as Menagerie's test takes."""
    lo, hi = model.actuator_ctrlrange[acts, 0].copy(), model.actuator_ctrlrange[acts, 1].copy()
    empty = hi <= lo
    lo[empty], hi[empty] = -1.0, 1.0
    return lo, hi


def warnings_of(data: mujoco.MjData) -> list[str]:
    """The MuJoCo warnings ``data`` has counted (``name x count``), none when it ran clean."""
    return [f"{mujoco.mjtWarning(i).name} x{data.warning[i].number}"
            for i in range(int(mujoco.mjtWarning.mjNWARNING)) if data.warning[i].number > 0]


def _hand_object_contact(scene: Scene) -> bool:
    d = scene.data
    g1, g2 = d.contact.geom1[:d.ncon], d.contact.geom2[:d.ncon]
    return bool(((scene.hand_geom_mask[g1] & scene.obj_geom_mask[g2])
                 | (scene.obj_geom_mask[g1] & scene.hand_geom_mask[g2])).any())


def step_with_noise(scene: Scene, *, steps: int = STEPS, hold_steps: int = HOLD_STEPS,
                    seed: int = SEED) -> tuple[list[str], int]:
    """Place the open hand just clear of the object (gravity off, as every protocol starts), then
    step ``steps`` times with a uniform random target over the control ranges every
    ``hold_steps`` steps. Returns the problems (MuJoCo warnings, first non-finite state, with
    the step) and how many steps had a hand–object contact."""
    m, d = scene.model, scene.data
    for gap in PALM_GAPS_M:
        scene.reset_with_grasp(OBJECT_HOME - np.array([0.0, gap, 0.0]),
                               np.array([1.0, 0.0, 0.0, 0.0]), scene.hand.open_pose)
        if not _hand_object_contact(scene):
            break
    rng = np.random.default_rng(seed)
    lo, hi = _control_ranges(m, scene.hand_act)
    problems: list[str] = []
    touching = 0
    for k in range(steps):
        if k % hold_steps == 0:
            d.ctrl[scene.hand_act] = rng.uniform(lo, hi)
        mujoco.mj_step(m, d)
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qacc).all()):
            problems.append(f"non-finite qpos/qacc at step {k} (t = {d.time:.3f} s)")
            break
        touching += _hand_object_contact(scene)
    return warnings_of(d) + problems, touching


@pytest.mark.parametrize("name", HAND_PARAMS)
def test_hand_steps_without_mujoco_warnings(name: str, cylinder) -> None:
    hand = _hand(name)
    validator = Validator(hand, cylinder)
    failures, touched = [], {}
    for protocol in PROTOCOLS:
        problems, touched[protocol] = step_with_noise(validator.scene(protocol))
        failures += [f"{name} in the {protocol} scene: {p}" for p in problems]
    assert not failures, "\n".join(failures)
    # the noise did drive the fingers into the object, so contacts were simulated too
    assert any(touched.values()), f"{name}: no hand–object contact in any scene: {touched}"
