"""The squeeze of the push protocols (``dgb``, ``six-dir``) is sized for their own pushes.

The squeeze presses each contact with a force sized for what the protocol asks the grasp to
hold (:mod:`sim.validate.targets`). For ``dgb`` that is not the object's weight in a lift but
six 1 N pushes on a 0.1 kg object, with the benchmark's friction (μ 0.6 / 0.02) and its servos
(kp 5 on every finger servo), and the stages are simulated in the benchmark's scene. Sized for
the real weight instead, a 5 g dice got the 0.25 N floor per contact against 1 N pushes.
``six-dir`` pushes 10·m N along ±x, ±y, ±z: its squeeze is sized for those six, not for the
weight along −z. Measured on the augmentations of the demonstrations (docs/validation.md).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.grasp import Grasp
from sim.metrics.holding import HoldLoads
from sim.validate.config import ValidateConfig
from sim.validate.dgb import run_dgb
from sim.validate.result import ValidationResult
from sim.validate.targets import least_grip_total_n, servo_stiffness_from
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_ycb, without_drift_correction, without_grip_boost, without_settled_modes

pytestmark = pytest.mark.slow

#: a grasp of the same augmentation that holds six-dir's pushes with the squeeze sized for them
#: (5 mm, 6°) and turns 20° out of it with the one sized for the weight
SIX_DIR_GRASP = Grasp(
    np.array([-0.03546825425588464, 0.09443484745332723, 0.03534751549979625]),
    np.array([0.4053875543742801, 0.6731240732339961, -0.04137489836024043, 0.6171329115976509]),
    np.array([0.0, 0.0, 0.01778353740028353, -0.05254292519943295, 0.9124164625997165,
              0.9094764625997165, 0.329292925199433, 0.27557, 0.77596, 0.77192,
              -0.2927364625997165, 0.3843064625997165, 0.6817035374002836, 0.6781835374002835,
              0.08532646259971648, -0.20308, 0.4404464625997165, 0.49224707480056706,
              0.488897074800567, 0.39785646259971646, 0.92592, 0.19558292519943293, 0.35953,
              0.15464353740028353]))

#: an opposed pinch along x through the centre of mass
PINCH = np.array([[-0.02, 0.0, 0.0], [0.02, 0.0, 0.0]])
PINCH_IN = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])

#: a grasp of the authors' sugar-box demonstration's augmentation (frame_palm in the object
#: frame, metres, wxyz; 24 joints) that holds the benchmark's pushes with the squeeze sized for
#: them and slips with the one sized for the box's weight
SUGAR_BOX_GRASP = Grasp(
    np.array([-0.05125007826212098, 0.08845426620533732, 0.0816095225770692]),
    np.array([0.08383009878696554, 0.7745981374070723, -0.10168848974941033, 0.6185706840089883]),
    np.array([0.0, 0.0, 0.19231646259971646, 0.29652292519943296, 0.82515, 0.82221,
              0.06749353740028353, 0.45010292519943296, 0.77596, 0.77192, -0.20547,
              0.47157292519943295, 0.76897, 0.76545, 0.17259292519943295, -0.02854707480056706,
              0.2659135374002835, 0.7540464625997165, 0.7506964625997165, 0.2233235374002835,
              0.8386535374002835, 0.19558292519943293, 0.27226353740028353,
              0.06737707480056704]))

#: a grasp of the same augmentation with hand bodies 5–10 mm from the box: squeezed with the
#: grasp's contacts only it passes the benchmark (7.8°, 5 mm); with every body within 1 cm
#: pressed in as well, the squeeze turns the free box 40° (measured 2026-12-05, with the
#: normal-first squeeze and the touching grasp stage; the grasp here before them turns 13° at
#: 1 cm since, inside the limits)
SPARE_LINKS_GRASP = Grasp(
    np.array([-0.0390123057666961, 0.024192787347492792, -0.035077480140068375]),
    np.array([0.5404174036415154, 0.5598054070531351, 0.22891914214453152, 0.5849469740371769]),
    np.array([0.0, 0.0, 0.10505, 0.29652292519943296, 0.9124164625997165, 0.9094764625997165,
              0.06749353740028353, 0.45010292519943296, 0.77596, 0.77192, -0.20547,
              0.47157292519943295, 0.76897, 0.76545, 0.0, -0.028547074800567063,
              0.5277129251994329, 0.66678, 0.66343, 0.2233235374002835, 1.1004529251994328,
              0.19558292519943293, 0.4467964625997165, 0.24191]))


#: a thumb + forefinger pinch of the dice from the authors' demonstration's augmentation
DICE_PINCH = Grasp(
    np.array([0.031095, -0.024793, 0.097883]),
    np.array([0.517409, -0.830567, -0.205787, -0.009896]),
    np.array([0.0, 0.0, -0.174067, 0.194046, 0.97884, 0.98423, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
              0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.255814, 0.80587, -0.092774, 0.362006,
              0.379606]))


def _pushes(force_n: float) -> np.ndarray:
    return np.hstack([np.vstack([np.eye(3), -np.eye(3)]) * force_n, np.zeros((6, 3))])


def test_the_least_grip_of_several_loads_is_the_largest_one_they_can_hold() -> None:
    mu = 0.5
    pushes = HoldLoads(_pushes(1.0), np.zeros(3), mu, 0.0)
    # along the pinch one finger alone holds 1 N; across it friction needs 1 N / μ
    assert least_grip_total_n(PINCH, PINCH_IN, pushes, 2.0) == pytest.approx(2.0 / mu, rel=1e-6)
    # a twist about the pinch axis (no torsional friction) cannot be held: it does not size
    # the squeeze, the loads the contacts can hold do
    twist = np.array([[0.0, 0.0, 0.0, 0.01, 0.0, 0.0]])
    both = HoldLoads(np.vstack([_pushes(1.0), twist]), np.zeros(3), mu, 0.0)
    assert least_grip_total_n(PINCH, PINCH_IN, both, 2.0) == pytest.approx(2.0 / mu, rel=1e-6)
    assert least_grip_total_n(PINCH, PINCH_IN, HoldLoads(twist, np.zeros(3), mu, 0.0),
                              2.0) == np.inf


@needs_ycb
def test_dgb_stages_use_the_benchmarks_servo_stiffness_read_from_its_model(shadow) -> None:
    v = Validator(shadow, load_object("062_dice"))
    lift = v.scene("lift-drop")
    k = servo_stiffness_from(v.scene("dgb"), lift)
    names = [lift.model.actuator(int(a)).name for a in lift.hand_act]
    dgb = v.scene("dgb")
    dgb_names = {dgb.model.actuator(int(a)).name for a in dgb.hand_act}
    want = v.config.dgb.servos.kp
    for name, kp in zip(names, k, strict=True):
        assert kp == (want if name in dgb_names else 0.0), name
    assert (k == 0.0).sum() == len(names) - len(dgb_names) > 0   # the wrist: not in dgb's hand


@needs_ycb
def test_a_dice_pinch_is_squeezed_for_the_benchmarks_pushes_not_its_weight(shadow) -> None:
    cfg = without_grip_boost(ValidateConfig.load())   # the grip as sized, before the boost
    dice = load_object("062_dice")
    v = Validator(shadow, dice, cfg)
    scene = v.scene("lift-drop")
    v._place(scene, DICE_PINCH, DICE_PINCH.joints)
    for_weight = v.derive_targets(scene, DICE_PINCH.joints)
    for_dgb = v.derive_targets(scene, DICE_PINCH.joints, sized_for="dgb")
    assert for_weight.n_bodies_near == for_dgb.n_bodies_near >= 2
    # 5 g: the floor per contact; 1 N pushes: at least grip_safety · 1 N / (μ · n) each
    assert for_weight.grip_force_n == pytest.approx(cfg.common.min_grip_force_n)
    push_n = cfg.dgb.force_per_kg * cfg.dgb.object_mass_kg
    assert for_dgb.grip_force_n >= (cfg.common.grip_safety * push_n
                                    / (cfg.dgb.contact.friction[0] * for_dgb.n_bodies_near))
    np.testing.assert_allclose(for_dgb.pregrasp, for_weight.pregrasp)   # geometry only


@needs_ycb
@pytest.mark.parametrize("sized_for", ["dgb", "lift-drop"])
def test_a_sugar_box_grasp_holds_the_benchmark_only_when_squeezed_for_it(shadow,
                                                                         sized_for: str) -> None:
    # the grip as sized for each protocol's loads, before the headroom boost scales it (and
    # before the benchmark's pregrasp settled the fingers' free modes, which this grasp's
    # measurement predates)
    v = Validator(shadow, load_object("004_sugar_box"),
                  without_settled_modes(without_grip_boost(ValidateConfig.load())))
    stages = v.stages(SUGAR_BOX_GRASP, "dexaug", sized_for=sized_for)
    result = ValidationResult("dgb", False, None, 0.0)
    run_dgb(v.scene("dgb"), v.config.dgb, v.palm_world(SUGAR_BOX_GRASP), stages, result)
    assert bool(result.passed) is (sized_for == "dgb"), (result.displacement_m, result.rotation_rad)
    if sized_for == "dgb":   # and the protocol itself sizes it so
        assert v.validate(SUGAR_BOX_GRASP, "dgb", squeeze_convention="dexaug").passed


@needs_ycb
@pytest.mark.parametrize("sized_for", ["six-dir", "lift-drop"])
def test_six_dir_squeezes_for_its_pushes(shadow, monkeypatch, sized_for: str) -> None:
    # the grip as sized for each protocol's loads, before the headroom boost scales it
    v = Validator(shadow, load_object("004_sugar_box"), without_grip_boost(ValidateConfig.load()))
    if sized_for == "lift-drop":   # the squeeze as it was: sized for the weight along −z
        derive = v.derive_targets
        monkeypatch.setattr(v, "derive_targets",
                            lambda scene, q, down=None, **_: derive(scene, q, down))
    result = v.validate(SIX_DIR_GRASP, "six-dir")
    assert bool(result.passed) is (sized_for == "six-dir"), (result.failure,
                                                             result.displacement_m,
                                                             result.rotation_rad)


@needs_ycb
@pytest.mark.parametrize("search", ["dgb", "common"])
def test_the_benchmarks_squeeze_presses_only_the_grasps_contacts(shadow, search: str) -> None:
    """``[dgb] contact_search_m`` (5 mm) picks the bodies the benchmark's squeeze presses; the
    wider ``[common]`` one (1 cm) also pulls spare links onto the free box and turns it out of
    the benchmark's 15°. Measured with the grasp's own split of the fingers' free modes
    (settling them alone also keeps the 1 cm squeeze of this grasp within the limits)."""
    cfg = without_settled_modes(ValidateConfig.load())
    assert cfg.dgb.contact_search_m < cfg.common.contact_search_m
    if search == "common":
        cfg = dataclasses.replace(cfg, dgb=dataclasses.replace(
            cfg.dgb, contact_search_m=cfg.common.contact_search_m))
    v = Validator(shadow, load_object("004_sugar_box"), cfg)
    scene = v.scene("lift-drop")
    v._place(scene, SPARE_LINKS_GRASP, SPARE_LINKS_GRASP.joints)
    near = v.near_contacts(scene)
    within = {int(b) for b, dist in zip(near.body_a, near.dist, strict=True)
              if dist <= cfg.dgb.contact_search_m}
    for_dgb = v.derive_targets(scene, SPARE_LINKS_GRASP.joints, sized_for="dgb")
    assert for_dgb.n_bodies_near == len(within)
    assert (len(within) < len(set(near.body_a.tolist()))) is (search == "dgb")
    result = v.validate(SPARE_LINKS_GRASP, "dgb", squeeze_convention="dexaug")
    assert bool(result.passed) is (search == "dgb"), np.degrees(result.rotation_rad)


#: a bowl rim grasp of the authors' demonstration's augmentation whose contacts within 5 mm
#: cannot hold every push: it passes the benchmark (3°) with the links 5–10 mm off pressed
#: too, and turns 16° with its contacts alone (measured 2026-12-05)
BOWL_RIM_GRASP = Grasp(
    np.array([0.027286384061525254, -0.10892196682507452, 0.10637603941235357]),
    np.array([0.3823636327973942, -0.5568987028383511, 0.6913197926441808, -0.25639584900959095]),
    np.array([0.0, 0.0, -0.2368835374002835, 0.76506, 0.6099270748005671, 0.607887074800567,
              0.15382292519943294, 1.0391, 0.482527074800567, 0.48148707480056707, 0.0, 0.0, 0.0,
              0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5096629251994329, 0.8589835374002835, 0.1782,
              0.26131646259971647, 0.20349]))


@needs_ycb
@pytest.mark.parametrize("widen", [True, False])
def test_contacts_that_cannot_hold_a_push_get_the_spare_links_pressed_too(
        shadow, monkeypatch, widen: bool) -> None:
    import sim.validate.validator as validator_module
    from sim.validate.loads import hold_loads
    from sim.validate.targets import holds_every_load, loads_in_world

    # measured with the grasp's own split of the fingers' free modes (settling them alone
    # also holds this grasp with its 5 mm contacts)
    # and before the squeeze's drift correction, which holds it either way (13.8°)
    v = Validator(shadow, load_object("024_bowl"),
                  without_drift_correction(without_settled_modes(ValidateConfig.load())))
    cfg = v.config
    scene = v.scene("lift-drop")
    v._place(scene, BOWL_RIM_GRASP, BOWL_RIM_GRASP.joints)
    loads = loads_in_world(hold_loads(v.obj, "dgb", cfg), scene)
    contacts = v.near_contacts(scene, cfg.dgb.contact_search_m)
    every = v.near_contacts(scene)
    assert not holds_every_load(contacts, loads)
    assert holds_every_load(every, loads)
    assert len(set(every.body_a.tolist())) > len(set(contacts.body_a.tolist()))
    if not widen:   # the squeeze as it was: the 5 mm contacts whatever they can hold
        monkeypatch.setattr(validator_module, "holds_every_load", lambda *a, **k: True)
    targets = v.derive_targets(scene, BOWL_RIM_GRASP.joints, sized_for="dgb")
    assert targets.n_bodies_near == len(set((every if widen else contacts).body_a.tolist()))
    result = v.validate(BOWL_RIM_GRASP, "dgb", squeeze_convention="dexaug")
    assert bool(result.passed) is widen, np.degrees(result.rotation_rad)
