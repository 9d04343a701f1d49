"""Validation protocols are plug-ins (issue #51): a new one is one class, registered by name,
and every validator entry point takes that name; an unknown name is one clear error."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.metrics.holding import HoldLoads
from sim.paths import REPO_ROOT
from sim.validate.config import PROTOCOLS, ValidateConfig
from sim.validate.loads import hold_loads
from sim.validate.program import Advance, Program
from sim.validate.protocols import Bench, ClosingProtocol, Options, get, names, register, unregister
from sim.validate.result import Failure, PhaseResult, ValidationResult
from sim.validate.stepping import drift, relative_object_pose
from sim.validate.targets import GraspTargets
from sim.validate.validator import Validator
from sim.world.objects import ObjectAsset, load_object
from sim.world.scene import PhysicsOptions, Scene
from tests.conftest import needs_menagerie, needs_ycb


class HoldStill(ClosingProtocol):
    """A toy protocol: close as lift-drop does, then only settle a while longer (gravity off)
    and check that the object did not move in the palm."""

    name = "hold-still"
    settle_s = 0.2
    max_displacement_m = 1e-3
    max_rotation_rad = np.deg2rad(2.0)

    def physics(self, config: ValidateConfig) -> PhysicsOptions:
        return PhysicsOptions(timestep_s=config.lift_drop.timestep_s, impratio=config.lift_drop.impratio)

    def hold_loads(self, obj: ObjectAsset, config: ValidateConfig) -> HoldLoads:
        friction = config.common.contact.friction   # its squeeze is sized for the weight
        return HoldLoads(np.array([[0.0, 0.0, -9.81 * obj.mass_kg, 0.0, 0.0, 0.0]]),
                         np.asarray(obj.com_m, float), friction[0], friction[1], self.name)

    def phases(self, bench: Bench, scene: Scene, targets: GraspTargets, result: ValidationResult,
               options: Options) -> Program:
        ref_pos, ref_quat = relative_object_pose(scene)
        yield Advance(round(self.settle_s / scene.model.opt.timestep))
        disp, rot = drift(scene, ref_pos, ref_quat)
        ok = disp <= self.max_displacement_m and rot <= self.max_rotation_rad
        result.phases["still"] = PhaseResult(ok, disp, rot)
        result.displacement_m, result.rotation_rad = disp, rot
        result.passed, result.failure = ok, None if ok else Failure.SLIPPED


@pytest.fixture
def hold_still():
    register(HoldStill)
    yield HoldStill
    unregister(HoldStill.name)


def test_the_built_in_protocols_are_registered_under_their_names() -> None:
    assert names()[:3] == PROTOCOLS
    assert [get(n).name for n in PROTOCOLS] == list(PROTOCOLS)


def test_an_unknown_protocol_is_one_error_listing_the_registered_ones(hold_still) -> None:
    obj = ObjectAsset.__new__(ObjectAsset)
    for call in (lambda: get("shake"), lambda: hold_loads(obj, "shake")):
        with pytest.raises(ValueError, match="unknown protocol 'shake'") as err:
            call()
        for name in (*PROTOCOLS, "hold-still"):
            assert repr(name) in str(err.value)
    with pytest.raises(ValueError, match="registered already"):
        register(HoldStill)
    unregister("hold-still")
    with pytest.raises(ValueError, match="unknown protocol 'hold-still'"):
        get("hold-still")
    register(HoldStill)   # for the fixture to remove


@pytest.mark.parametrize("module", ["validator.py", "grasp_bench.py", "closing.py", "loads.py"])
def test_no_protocol_is_named_in_a_branch_outside_the_protocol_modules(module: str) -> None:
    text = (REPO_ROOT / "sim" / "validate" / module).read_text()
    names_ = "|".join(re.escape(n) for n in PROTOCOLS)
    assert not re.search(rf"""(==|!=|\bin)\s*\(?\s*["']({names_})["']""", text)
    assert not re.search(r"\bprotocol\s*(==|!=)", text)
    assert Path(REPO_ROOT / "sim" / "validate" / "protocols" / "registry.py").is_file()


@needs_menagerie
@needs_ycb
def test_a_registered_toy_protocol_validates_through_the_validator(hold_still, shadow: Hand) -> None:
    v = Validator(shadow, load_object("004_sugar_box"))
    grasp = next(r.grasp for r in load_reference_grasps(shadow) if r.object == "004_sugar_box")
    result = v.validate(grasp, "hold-still")
    assert result.protocol == "hold-still" and result.passed, result.summary()
    assert set(result.phases) == {"still"} and result.n_contacts >= 3
    # the shared placing and closing services decide a grasp on air before any phase of its own
    air = Grasp.from_arrays(grasp.palm_pos + np.array([0.0, 0.0, 0.5]), grasp.palm_quat_wxyz, grasp.joints)
    assert v.validate(air, "hold-still").failure == Failure.NO_CONTACT
    # a program protocol runs batched on mujoco.batch as well, bit for bit
    batched = v.validate_all([grasp, air], "hold-still", nthread=2)
    for got, want in zip(batched, (result, v.validate(air, "hold-still")), strict=True):
        assert (got.passed, got.failure, got.n_contacts) == (want.passed, want.failure, want.n_contacts)
        np.testing.assert_array_equal([got.displacement_m, got.rotation_rad, got.epsilon],
                                      [want.displacement_m, want.rotation_rad, want.epsilon])
    assert hold_loads(v.obj, "hold-still").protocol == "hold-still"
    with pytest.raises(ValueError, match="pushes along fixed axes"):
        v.validate(grasp, "hold-still", gravity_dir=np.array([1.0, 0.0, 0.0]))
