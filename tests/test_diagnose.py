"""The slip diagnosis (sim.validate.diagnose, ``dexaug diagnose``): the replay gives the
validator's own verdict; in a grasp that holds (the Shadow Hand's soup-can wrap) the contact
forces carry the object's weight (the vertical shares sum to ~1 during the hold); the paper
authors' sugar-box grasp, which slips, shows the slip starting in the lift with sliding
contacts — so the force bookkeeping and the slip detection can each fail."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.validate.diagnose import diagnose, summarise
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb, without_grip_boost

pytestmark = [needs_menagerie, needs_ycb]


@pytest.fixture(scope="module")
def wrap():
    hand = Hand.load("shadow_right")
    ref = next(r for r in load_reference_grasps(hand) if r.name == "can_side_wrap")
    return hand, load_object(ref.object), ref.grasp


def test_a_holding_grasp_carries_its_weight(wrap) -> None:
    hand, obj, grasp = wrap
    validator = Validator(hand, obj)
    expected = validator.validate(grasp, "lift-drop")
    d = diagnose(validator, grasp)
    assert d.result.passed == expected.passed and d.result.failure == expected.failure
    assert d.result.displacement_m == pytest.approx(expected.displacement_m, abs=1e-9)
    assert expected.passed, "the reference wrap holds the can"
    hold = [s for s in d.samples if s.phase == "hold"]
    assert hold and d.samples[0].phase == "closed"
    carried = np.median([sum(s.support.values()) for s in hold])
    assert carried == pytest.approx(1.0, abs=0.15)
    assert d.findings["onset_phase"] is None
    assert all(c.fn >= 0 for s in hold for c in s.contacts)


def test_the_authors_sugar_box_grasp_slips_with_sliding_contacts() -> None:
    """The paper authors' five-finger sugar-box demonstration slips in lift-drop under an
    equal-force squeeze (it holds under the default balanced one: tests/test_squeeze_balance.py):
    the diagnosis sees the slip start in the lift, contacts at the friction cone's edge, and the
    slip's direction; the summary counts it."""
    from dataclasses import replace

    from sim.demo import load_demo
    from sim.paths import REPO_ROOT
    from sim.validate.config import ValidateConfig

    demo = load_demo(REPO_ROOT / "recordings" / "demos" / "human" / "004_sugar_box.json")
    base = ValidateConfig.load()
    # and without the grip's headroom boost, which turns this slip into one with no contact
    # at the cone's edge
    equal = without_grip_boost(replace(base, common=replace(base.common, squeeze_forces="equal")))
    validator = Validator(Hand.load(demo.hand), load_object(demo.object), equal)
    d = diagnose(validator, demo.grasp)
    assert not d.result.passed and d.result.failure == "slipped"
    f = d.findings
    assert f["onset_phase"] == "lift" and f["onset_after_gravity_s"] < d.samples[-1].t_s
    assert f["contacts_sliding"] >= 1
    assert f["weight_n"] == pytest.approx(validator.scene("lift-drop").obj_mass_kg * 9.81)
    assert f["mode"] in ("translation", "rotation") and f["axis"][1] in "xyz"
    s = summarise([d])
    assert s["verdicts"] == {"slipped": 1} and sum(s["slip_modes"].values()) == 1


def test_cli_diagnoses_a_dataset(tmp_path, wrap) -> None:
    """``dexaug diagnose`` on a dataset written by the real pipeline's writer."""
    from augment import dataset
    from augment.fsg.result import FsgGrasp

    hand, obj, grasp = wrap
    result = Validator(hand, obj).validate(grasp, "lift-drop")
    fg = FsgGrasp(grasp=grasp, fingers=tuple(hand.finger_names), contact_points=np.zeros((0, 3)),
                  contact_normals=np.zeros((0, 3)), contact_finger=np.zeros(0, int),
                  ws_index=(), face_index=(), epsilon=0.0, volume=0.0)
    table = dataset.from_fsg([fg], hand.joint_names, hand.finger_names, [result],
                             attrs={"hand": hand.name}, split_rejected=True)
    path = tmp_path / "grasps.h5"
    dataset.save(path, {obj.name: table})
    out = tmp_path / "diag.json"
    proc = subprocess.run([sys.executable, "-m", "dexaug", "diagnose", str(path), "--json", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(out.read_text())[obj.name]
    assert report["summary"]["verdicts"] == {"pass": 1}
    assert report["grasps"][0]["set"] == "passing"
