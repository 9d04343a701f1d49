"""Early exit (issue #53) changes what is simulated, never a verdict or a failure reason.

Each grasp is validated twice, with the protocol's ``early_exit`` off and on, and the results
compared; MuJoCo's steps are counted on the way (a counter around the real ``mujoco.mj_step``:
every protocol steps through it, the program executor included). Grasps that pass and grasps
that fail for each reason the exits touch:

- ``dgb`` (the rehearsal that chooses the closing, then the benchmark): the sugar-box grasp
  whose rehearsed closing holds, the same grasp with its fingers half closed (slips under the
  first push), and pushed 3 cm into the box (every pregrasp refused for penetration). Early
  exit copies the pregrasp → grasp stage that corrections share and skips correcting a refused
  pregrasp, so every field of every result must be equal, and the steps fewer;
- ``six-dir``: the tomato can's hand-built grasp (holds all six pushes) and two FSG grasps of
  the can that slip, one under the first push (+x) and one under the fourth (-y). Early exit
  stops after the push that slipped: verdict, failure and the phases run must equal the full
  run's, and the worst drift, which the skipped pushes would have measured, is NaN.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
import pytest

from sim.errors import ConfigError
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.transforms import rotate
from sim.validate.config import VALIDATE_TOML, ValidateConfig
from sim.validate.result import Failure, ValidationResult
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb
from tests.test_rehearsal import SUGAR_BOX_GRASP

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]

#: FSG grasps of 005_tomato_soup_can (seed 0, the manual workspace; frame_palm in the object
#: frame, metres, wxyz; 24 joints) that slip in six-dir: under +x, the first push, and under
#: -y, the fourth
CAN_SLIPS_FIRST = Grasp.from_arrays(
    [-0.05888253187121206, -0.06331826073962589, 0.04061539371766867],
    [0.5354701115667861, -0.3876473382376304, -0.5601807118719055, -0.4991982279842538],
    [0.0, 0.0, 0.0, 0.8726646259971647, 0.3490658503988659, 0.3490658503988659, 0.0,
     0.8726646259971647, 0.3490658503988659, 0.3490658503988659, 0.0, 0.5235987755982988,
     0.6981317007977318, 0.6981317007977318, 0.0, 0.0, 0.8726646259971647, 0.17453292519943295,
     0.17453292519943295, 0.17453292519943295, 1.22173, 0.17453292519943295,
     -0.17453292519943295, 0.34906585039886584])
CAN_SLIPS_FOURTH = Grasp.from_arrays(
    [0.08678528448634375, 0.022915325599127363, 0.10876827392000109],
    [0.3694410438642531, -0.7554677982840098, -0.14319164396024206, 0.5218025239152885],
    [0.0, 0.0, 0.17453292519943295, 0.3490658503988659, 0.5235987755982988,
     0.5235987755982988, 0.17453292519943295, 0.6981317007977318, 0.17453292519943295,
     0.17453292519943295, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5235987755982988,
     1.22173, 0.17453292519943295, 0.0, 0.0])


@pytest.fixture
def steps(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """``[n]``: MuJoCo steps taken since the test last set ``n`` (the real step, counted)."""
    counted = [0]
    real = mujoco.mj_step

    def step(m: mujoco.MjModel, d: mujoco.MjData, nstep: int = 1) -> None:
        counted[0] += nstep
        real(m, d, nstep=nstep)

    monkeypatch.setattr(mujoco, "mj_step", step)
    yield counted


def _validators(hand: Hand, obj: str, section: str) -> dict[bool, Validator]:
    cfg = ValidateConfig.load()
    assert getattr(cfg, section).early_exit            # on by default
    return {on: Validator(hand, load_object(obj), dataclasses.replace(
        cfg, **{section: dataclasses.replace(getattr(cfg, section), early_exit=on)}))
        for on in (False, True)}


def _run(v: Validator, grasp: Grasp, protocol: str, steps: list[int]) -> tuple[ValidationResult, int]:
    steps[0] = 0
    result = v.validate(grasp, protocol)
    return result, steps[0]


def _flat(result: ValidationResult) -> str:
    return json.dumps(result.summary(), default=str, sort_keys=True)


def test_dgb_early_exit_keeps_every_result_and_saves_steps(shadow: Hand, steps: list[int]) -> None:
    vs = _validators(shadow, "004_sugar_box", "dgb")
    g = SUGAR_BOX_GRASP
    into_box = rotate(g.palm_quat_wxyz, np.array([0.0, 1.0, 0.0]))
    grasps = {"holds": g,
              "half closed": Grasp.from_arrays(g.palm_pos, g.palm_quat_wxyz, 0.5 * g.joints),
              "3 cm into the box": Grasp.from_arrays(g.palm_pos + 0.03 * into_box,
                                                     g.palm_quat_wxyz, g.joints)}
    want = {"holds": None, "half closed": Failure.SLIPPED, "3 cm into the box": Failure.PENETRATION}
    for name, grasp in grasps.items():
        (off, n_off), (on, n_on) = (_run(vs[e], grasp, "dgb", steps) for e in (False, True))
        assert off.failure == want[name], (name, off.summary())
        # every figure, and the stages the benchmark ran, bit for bit
        assert _flat(on) == _flat(off), name
        for key in ("pregrasp", "squeeze", "touch", "contact_pos_obj"):
            np.testing.assert_array_equal(getattr(on, key), getattr(off, key), err_msg=name)
        assert on.stopped_early is None                # nothing it would have measured is lost
        assert n_on < n_off, (name, n_on, n_off)       # corrections share the first stage
    # a refused pregrasp is not corrected: nothing at all is simulated
    assert _run(vs[True], grasps["3 cm into the box"], "dgb", steps)[1] == 0


def test_six_dir_stops_after_the_first_slip_with_the_same_verdict(shadow: Hand,
                                                                  steps: list[int],
                                                                  tmp_path: Path) -> None:
    vs = _validators(shadow, "005_tomato_soup_can", "six_dir")
    holds = next(r.grasp for r in load_reference_grasps(shadow) if r.object == "005_tomato_soup_can")
    for name, grasp, slips_in in (("holds", holds, None), ("slips first", CAN_SLIPS_FIRST, "+x"),
                                  ("slips fourth", CAN_SLIPS_FOURTH, "-y")):
        (off, n_off), (on, n_on) = (_run(vs[e], grasp, "six-dir", steps) for e in (False, True))
        assert (on.passed, on.failure) == (off.passed, off.failure), name
        if slips_in is None:
            assert off.passed and _flat(on) == _flat(off) and n_on == n_off, name
            continue
        assert off.failure == Failure.SLIPPED and len(off.phases) == 6, name
        # the pushes up to the slip are the full run's; the ones after it are not simulated
        run = list(on.phases)
        assert run == list(off.phases)[:len(run)] and run[-1] == slips_in, (name, run)
        assert all(on.phases[k] == off.phases[k] for k in run), name
        assert not on.phases[slips_in].passed and all(on.phases[k].passed for k in run[:-1])
        assert on.stopped_early == f"after push {slips_in}: slipped"
        assert math.isnan(on.displacement_m) and math.isnan(on.rotation_rad)
        assert off.stopped_early is None and not math.isnan(off.displacement_m)
        assert (on.n_contacts, on.epsilon, on.penetration_m) == (off.n_contacts, off.epsilon,
                                                                 off.penetration_m)
        assert _stored_stop(shadow, grasp, on, tmp_path) == on.stopped_early   # a dataset says so
        # each skipped push is a restore and 2 s of stepping (500 steps at 4 ms)
        assert n_off - n_on >= 500 * (6 - len(run)), (name, n_on, n_off)


def _stored_stop(hand: Hand, grasp: Grasp, result: ValidationResult, tmp_path: Path) -> str:
    """``stopped_early`` of ``grasp`` validated as ``result``, written by the pipeline's dataset
    writer and read back: NaN drifts in a dataset must say why."""
    from augment import dataset
    from augment.fsg.result import FsgGrasp

    fg = FsgGrasp(grasp=grasp, fingers=tuple(hand.finger_names), contact_points=np.zeros((0, 3)),
                  contact_normals=np.zeros((0, 3)), contact_finger=np.zeros(0, int),
                  ws_index=(), face_index=(), epsilon=0.0, volume=0.0)
    table = dataset.from_fsg([fg], hand.joint_names, hand.finger_names, [result],
                             split_rejected=False)
    dataset.save(tmp_path / "grasps.h5", {"object": table})
    return str(dataset.load(tmp_path / "grasps.h5")["object"].columns["stopped_early"][0])


@pytest.mark.parametrize("section", ["six_dir", "dgb"])
def test_early_exit_is_a_checked_setting(tmp_path: Path, section: str) -> None:
    text = VALIDATE_TOML.read_text()
    head, sep, tail = text.partition(f"[{section}]")
    assert sep and "early_exit = true" in tail
    bad = tmp_path / "validate.toml"
    bad.write_text(head + sep + tail.replace("early_exit = true", 'early_exit = "yes"', 1))
    with pytest.raises(ConfigError, match=rf"validate\.toml: {section}\.early_exit"):
        ValidateConfig.load(bad)
    off = tmp_path / "off.toml"
    off.write_text(head + sep + tail.replace("early_exit = true", "early_exit = false", 1))
    assert not getattr(ValidateConfig.load(off), section).early_exit
    absent = tmp_path / "absent.toml"
    absent.write_text(head + sep + tail.replace("early_exit = true", "", 1))
    assert getattr(ValidateConfig.load(absent), section).early_exit   # the default: on
