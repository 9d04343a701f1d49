"""Whole-hand wraps a person makes become power demos that augment into grasps that hold (#49).

The wrap is the human-timed operator's sugar-box grasp (``benchmarks/bench_power_demos.py``:
a person's geometry and timing, the hand carried onto the box as the fingers close) replayed
through the real bridge in the demonstration mode; the same grasp without the wrap is the
precision demo that must extract as before. The augmentation is the pipeline's
(``augment_demo``), validated with lift-drop at the object's real mass.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow

OBJECT = "004_sugar_box"
HAND = "shadow_right"
REPO = Path(__file__).resolve().parent.parent


def _session(tmp: Path, wrap: bool) -> Path:
    from benchmarks.bench_power_demos import human_episode, wrap_episode
    from sim.hand.model import Hand
    from teleop.bridge.rerecord import rerecord
    from teleop.synthetic.writer import write_session

    hand = Hand.load(HAND)
    ep = human_episode(OBJECT, 0, hand)
    raw = write_session(wrap_episode(ep, hand) if wrap else ep, tmp / "raw.mcap")
    return rerecord(raw, tmp / "demo.mcap", object_mode="demo")


@pytest.fixture(scope="module")
def wrap_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _session(tmp_path_factory.mktemp("wrap"), wrap=True)


@pytest.fixture(scope="module")
def plain_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _session(tmp_path_factory.mktemp("plain"), wrap=False)


def _moments(demos: list) -> list[tuple]:
    return [(d.id, d.how, d.fingers, d.grasp_type, np.round(d.joints, 9).tolist())
            for d in demos]


@needs_menagerie
@needs_ycb
def test_a_lifted_wrap_is_a_power_demo(wrap_session: Path) -> None:
    """The palm and the thumb's base lie on the box with the thumb and the fingers, and the
    hand lifts off it: a power demo, thumb included; with the wrap rule off the same
    recording gives only fingertip demos."""
    from sim.demo import POWER
    from teleop.record.demos import DemoParams, extract_demos

    power = [d for d in extract_demos(wrap_session) if d.grasp_type == POWER]
    assert len(power) == 1, _moments(extract_demos(wrap_session))
    (d,) = power
    assert "thumb" in d.fingers and len(d.fingers) >= 3, d.fingers
    assert d.link_contacts and set(d.link_contacts) & {"rh_palm", "rh_thbase"}, d.link_contacts
    assert d.contact_points_obj.keys() == set(d.fingers)
    off = extract_demos(wrap_session, DemoParams(power_min_s=math.inf))
    assert off and all(x.grasp_type != POWER for x in off)


@needs_menagerie
@needs_ycb
def test_a_power_demo_augments_into_grasps_that_hold(wrap_session: Path,
                                                     tmp_path: Path) -> None:
    """The power demo goes to the demo-seeded power generator (FSG's palm check refuses a
    wrap) and at least one of its grasps passes lift-drop, touching with the thumb and two
    other fingers."""
    from augment import dataset
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_demo
    from sim.demo import POWER
    from teleop.record.demos import extract_demos

    (d,) = [x for x in extract_demos(wrap_session) if x.grasp_type == POWER]
    s = augment_demo(d, tmp_path, AugmentOptions(n=3, time_budget_s=120, gallery=0, workers=1))
    assert s.generated >= 1 and s.passed >= 1, (s.generated, s.passed, s.failures)
    table = dataset.load(s.dataset)[OBJECT]
    assert len(table) == s.passed
    provenance = json.loads(table.attrs["demo"])
    assert provenance["grasp_type"] == POWER


@needs_menagerie
@needs_ycb
def test_zero_power_grasps_is_a_result(wrap_session: Path, tmp_path: Path) -> None:
    """A power augmentation that finds nothing (no time at all) ends with a summary that says
    so, its files written, not a crash."""
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_demo
    from sim.demo import POWER
    from teleop.record.demos import extract_demos

    (d,) = [x for x in extract_demos(wrap_session) if x.grasp_type == POWER]
    s = augment_demo(d, tmp_path, AugmentOptions(n=3, time_budget_s=0.0, gallery=0, workers=1))
    assert s.generated == 0 and s.passed == 0 and s.fsg_stopped == "time budget"
    assert (Path(s.dataset).parent / "summary.json").is_file()


@needs_menagerie
@needs_ycb
def test_a_fingertip_grasp_extracts_as_before(plain_session: Path) -> None:
    """The same person's grasp without the wrap (fingertips, palm clear): precision demos,
    exactly those of the extraction without the wrap rule."""
    from sim.demo import PRECISION
    from teleop.record.demos import DemoParams, extract_demos

    demos = extract_demos(plain_session)
    assert demos and all(d.grasp_type == PRECISION for d in demos)
    assert _moments(demos) == _moments(extract_demos(plain_session,
                                                     DemoParams(power_min_s=math.inf)))


@needs_menagerie
def test_the_wrap_rule_needs_the_thumb_and_the_palm_side() -> None:
    """A state is a wrap with the thumb, two other fingers and the palm side (or the inner
    links of two fingers) on the object; never without the thumb, and one finger's middle
    phalanx beside fingertips is a precision grasp."""
    from sim.hand.model import Hand
    from teleop.record.demo_track import Track
    from teleop.record.power_demo import wrap_mask

    bodies = [{"rh_thdistal", "rh_ffdistal", "rh_mfdistal", "rh_palm"},          # wrap
              {"rh_ffdistal", "rh_mfdistal", "rh_rfdistal", "rh_palm"},          # no thumb
              {"rh_thdistal", "rh_ffdistal", "rh_mfdistal", "rh_rfmiddle"},      # one knuckle
              {"rh_thmiddle", "rh_ffmiddle", "rh_mfproximal", "rh_rfdistal"},    # inner links
              {"rh_thdistal", "rh_ffdistal", "rh_palm"}]                         # one finger
    n = len(bodies)
    track = Track(np.arange(n), np.arange(n) * 4_000_000, None, list(range(n)), [{}] * n,
                  [[]] * n, [frozenset()] * n, [[]] * n, [frozenset(b) for b in bodies])
    assert wrap_mask(track, Hand.load(HAND), 2, 2).tolist() == [True, False, False, True, False]


def test_an_old_demo_file_loads_as_precision(tmp_path: Path) -> None:
    """Demo files written before the grasp type existed load as precision demos and write
    back byte-for-byte the same fields (the run keys of their results stay the same); a power
    demo keeps its type and link contacts through a file; a bad type names the field."""
    import dataclasses

    from sim.demo import POWER, PRECISION, DemoError, demo_to_json, load_demo, save_demo

    path = REPO / "recordings" / "demos" / "004_sugar_box.json"
    doc = json.loads(path.read_text())
    assert "grasp_type" not in doc
    old = load_demo(path)
    assert old.grasp_type == PRECISION and old.link_contacts == ()
    assert set(demo_to_json(old)) <= set(doc) | {"table", "flags"}
    wrap = dataclasses.replace(old, grasp_type=POWER, link_contacts=("rh_palm",))
    save_demo(tmp_path / "wrap.json", wrap)
    back = load_demo(tmp_path / "wrap.json")
    assert back.grasp_type == POWER and back.link_contacts == ("rh_palm",)
    (tmp_path / "bad.json").write_text(json.dumps({**doc, "grasp_type": "fist"}))
    with pytest.raises(DemoError, match="grasp_type"):
        load_demo(tmp_path / "bad.json")
