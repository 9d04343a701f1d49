"""Validation on mujoco.batch threads gives exactly what stepping from Python gives.

The same protocol programs (sim.validate.program) run on one scene from Python
(``Validator.validate``) and many at once on ``mujoco.batch`` (``Validator.validate_all``); every
field of every result must be equal — not close — over a fixed set of passing and failing
grasps, with more grasps than the batch holds (so simulations are refilled), on two threads.
"""

from __future__ import annotations

import importlib.util
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.validate.config import ValidateConfig
from sim.validate.result import ValidationResult
from sim.validate.validator import BATCH_SIMS, Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]
OBJ = "005_tomato_soup_can"


def _perturbed(hand: Hand, base: Grasp, n: int, seed: int = 0) -> list[Grasp]:
    """``base`` and n − 1 perturbations of it (palm ±6 mm / ±6°, joints ±0.08 rad): a mix of
    grasps that hold, slip, lose contact or penetrate."""
    rng = np.random.default_rng(seed)
    out = [base]
    while len(out) < n:
        rot = Rotation.from_rotvec(rng.normal(0, np.deg2rad(6) / np.sqrt(3), 3))
        quat = (rot * Rotation.from_quat(base.palm_quat_wxyz, scalar_first=True)).as_quat(
            scalar_first=True)
        q = hand.clip(base.joints + rng.uniform(-0.08, 0.08, hand.nq))
        out.append(Grasp.from_arrays(base.palm_pos + rng.uniform(-0.006, 0.006, 3), quat, q))
    return out


def _fields(r: ValidationResult) -> list[object]:
    """Every field of a result, arrays as bytes, so equality is exact (NaN == NaN bitwise)."""
    out: list[object] = []
    for key, value in sorted(vars(r).items()):
        if isinstance(value, np.ndarray):
            out.append((key, value.shape, value.tobytes()))
        elif isinstance(value, float):
            out.append((key, np.float64(value).tobytes()))
        elif key == "phases":
            out.append((key, [(k, p.passed, np.float64(p.displacement_m).tobytes(),
                               np.float64(p.rotation_rad).tobytes()) for k, p in value.items()]))
        else:
            out.append((key, value))
    return out


@pytest.fixture(scope="module")
def grasps(shadow: Hand) -> list[Grasp]:
    base = next(r.grasp for r in load_reference_grasps(shadow) if r.object == OBJ)
    return _perturbed(shadow, base, BATCH_SIMS + 8)


@pytest.mark.parametrize(("protocol", "n", "pinned"), [("lift-drop", None, False),
                                                        ("lift-drop", 10, True),
                                                        ("six-dir", 10, False)])
def test_batched_validation_equals_python_stepping(shadow: Hand, grasps: list[Grasp], protocol: str,
                                                   n: int | None, pinned: bool) -> None:
    config = ValidateConfig.load()
    config = replace(config, common=replace(config.common, pin_while_closing=pinned))
    grasps = grasps[:n]
    here = Validator(shadow, load_object(OBJ), config)
    stepped = [here.validate(g, protocol) for g in grasps]
    batched = Validator(shadow, load_object(OBJ), config).validate_all(grasps, protocol, nthread=2)
    assert [r.failure for r in batched] == [r.failure for r in stepped]
    for k, (a, b) in enumerate(zip(stepped, batched, strict=True)):
        assert _fields(a) == _fields(b), f"grasp {k}"
    if n is None:   # the set is a real mix, not all passing or all failing
        assert 3 <= sum(r.passed for r in stepped) <= len(grasps) - 3, [r.failure for r in stepped]


def test_the_comparison_sees_a_one_nanoradian_change(shadow: Hand, grasps: list[Grasp]) -> None:
    """The exact comparison above can fail: a grasp whose joints differ by 1e-9 rad gives a
    result that differs in some field."""
    g = next(g for g, r in zip(grasps, Validator(shadow, load_object(OBJ)).validate_all(grasps[:6]),
                                strict=False) if r.passed)
    nudged = Grasp.from_arrays(g.palm_pos, g.palm_quat_wxyz, g.joints + 1e-9)
    v = Validator(shadow, load_object(OBJ))
    assert _fields(v.validate(g)) != _fields(v.validate(nudged))


def test_warp_backend_says_what_it_needs_or_agrees(shadow: Hand, grasps: list[Grasp]) -> None:
    """Without MuJoCo Warp (or without a CUDA device) ``backend="warp"`` is one clear error;
    with both, its verdicts on four grasps agree with the C engine's on at least three."""
    from sim.validate.warp_runner import WarpUnavailable, import_warp

    v = Validator(shadow, load_object(OBJ))
    try:
        import_warp("cuda")
    except WarpUnavailable as exc:
        assert "pip install mujoco-warp" in str(exc) or "CUDA device" in str(exc)
        with pytest.raises(WarpUnavailable, match=r"--backend warp needs"):
            v.validate_all(grasps[:2], backend="warp")
        return
    ref = v.validate_all(grasps[:4])
    warp = v.validate_all(grasps[:4], backend="warp", nworld=4)
    assert sum(a.passed == b.passed for a, b in zip(ref, warp, strict=True)) >= 3


@pytest.mark.skipif(importlib.util.find_spec("mujoco_warp") is None,
                    reason="MuJoCo Warp is not installed (optional: pip install mujoco-warp)")
def test_warp_runner_on_the_cpu_backend_agrees_with_and_without_graph_replay(
        shadow: Hand, grasps: list[Grasp]) -> None:
    """The GPU runner's own logic (ramps and pins as device kernels, one step replayed as a
    captured graph, per-field transfers) on Warp's CPU backend: the replayed graph gives the
    verdicts the plain launches give, and both agree with the C engine on at least 5 of 6
    grasps (kernels compile on the first run: about two minutes on 2 cores)."""
    from sim.validate.batched import validate_batched
    from sim.validate.warp_runner import WarpRunner

    v = Validator(shadow, load_object(OBJ))
    ref = v.validate_all(grasps[:6])
    verdicts = []
    for capture in (True, False):
        runner = WarpRunner(v.scene("lift-drop"), 4, "cpu", capture=capture)
        out = validate_batched(runner, grasps[:6],
                               lambda g, view: v.start(g, "lift-drop", scene=view))
        assert runner.graph_captured is capture
        verdicts.append([(r.passed, r.failure) for r in out])
    assert verdicts[0] == verdicts[1]
    assert sum(a.passed == b[0] for a, b in zip(ref, verdicts[0], strict=True)) >= 5
