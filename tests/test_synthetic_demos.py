"""The synthetic operator in demonstration mode yields demos: synthesize → write a raw session
→ re-record it through the real bridge with the object settled and held (``object_mode="demo"``)
→ extract the grasp. Objects without a reference grasp, so the searched generic grasp
(:mod:`teleop.synthetic.grasp_search`) is what is exercised: a side grasp (bottle) and a top
grasp (apple)."""

from __future__ import annotations

from pathlib import Path

import pytest

from teleop.bridge.rerecord import rerecord
from teleop.record.demos import extract_demos
from teleop.synthetic.synthesize import synthesize
from teleop.synthetic.writer import write_session
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow


@needs_menagerie
@needs_ycb
@pytest.mark.parametrize("obj", ["006_mustard_bottle", "013_apple"])
def test_generic_grasp_gives_a_demo_in_demo_mode(shadow, obj: str, tmp_path: Path) -> None:
    ep = synthesize(obj, hand=shadow, seed=0)
    assert ep.reference_grasp is None
    raw = write_session(ep, tmp_path / "raw.mcap")
    full = rerecord(raw, tmp_path / "full.mcap", object_mode="demo")
    demos = extract_demos(full)
    assert demos, obj
    best = max(demos, key=lambda d: d.duration_s)
    assert "thumb" in best.fingers and len(best.fingers) >= 2, best.fingers
    assert best.duration_s >= 0.3
