"""Teleop retargeting maps of the four-finger hands (Allegro, LEAP): their
``configs/hands/<hand>/retarget.toml`` drives the real retargeter (mink + daqp) on the real
Quest 3 capture, and the synthetic operator's session goes through the real bridge to a
demonstration.

Measured with the shipped maps (``pytest -q tests/test_retarget_hands.py``; median fingertip
error over the capture's 756 tracked frames, scaled operator pad target vs achieved robot pulp
site, mm):

=========  =====  ==========  ======  ====
hand       thumb  forefinger  middle  ring
=========  =====  ==========  ======  ====
Allegro    22.2   11.5        8.8     18.5
LEAP       16.2   6.2         3.9     21.7
=========  =====  ==========  ======  ====

(The Shadow Hand's map: 3.3–6.1 mm.) Why larger: the retarget API scales the operator's hand
uniformly about the wrist, and these hands are not a scaled human hand: their forefinger and
ring knuckles are 9 cm apart, the capture operator's index and ring MCP joints 4.8 cm (median,
scaled), and their thumbs do not reach where the operator's thumb pad maps (mean target −
achieved ≈ 1.5–2 cm), so the ring's and the thumb's targets are partly out of reach.

Synthetic sessions through the bridge (``object_mode="demo"``): both hands give a stable grasp
with the thumb and one to three fingers. The LEAP does so at its own teleop gain (its hand.toml
``[teleop] servo_kp_scale = 1``): at the bridge's (``servo_kp_scale = 5``) its light links and
the 4 ms bridge timestep make MuJoCo go unstable (bad QACC at the free hand joint, the scene
restored again and again) and no fingertip ever touches the object
(:func:`test_leap_at_the_bridge_gain_gives_no_demo`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim.demo import DemoError
from sim.errors import AssetError
from sim.hand.model import Hand
from sim.paths import SHARED_ASSETS
from teleop.input.iwer import iwer_hand_frames, load_iwer_capture
from teleop.messages import JOINT_INDEX
from teleop.retarget.config import load_hand_mapping, load_retarget_config
from teleop.retarget.retargeter import Retargeter
from teleop.retarget.trace import retarget_frames, summarise_errors
from tests.conftest import needs_menagerie, needs_ycb

CAPTURE = SHARED_ASSETS / "handdata" / "quest3_webxr" / "cap.min.js"
HANDS = ("allegro_right", "leap_right")

#: Median fingertip error (mm) measured on the capture with the shipped maps (module docstring);
#: the test allows MARGIN_MM above it, so a change to a map or the solver that moves a finger
#: away from its target shows up.
MEASURED_MEDIAN_MM = {
    "allegro_right": {"thumb": 22.2, "forefinger": 11.5, "middle": 8.8, "ring": 18.5},
    "leap_right": {"thumb": 16.2, "forefinger": 6.2, "middle": 3.9, "ring": 21.7},
}
MARGIN_MM = 3.0

pytestmark = [pytest.mark.slow, needs_menagerie,
              pytest.mark.skipif(not CAPTURE.is_file(), reason=f"no hand capture {CAPTURE}")]


@pytest.fixture(scope="module")
def hands() -> dict[str, Hand]:
    out = {}
    for name in HANDS:
        try:
            out[name] = Hand.load(name)
        except AssetError as exc:
            pytest.skip(f"hand model missing: {exc}")
    return out


@pytest.fixture(scope="module")
def frames():
    return iwer_hand_frames(load_iwer_capture(CAPTURE))


# --- the map ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", HANDS)
def test_map_loads_four_fingers_little_unmapped(hands, name: str) -> None:
    hand = hands[name]
    mapping = load_hand_mapping(name)
    assert mapping.side == "right"
    assert mapping.fingers == {"thumb": "thumb_tip", "forefinger": "index_tip",
                               "middle": "middle_tip", "ring": "ring_tip"}
    assert set(mapping.fingers) == set(hand.finger_names)
    assert not any(j.startswith("little") for j in (*mapping.fingers.values(),
                                                    *mapping.phalanges.values()))
    # phalanx bodies: the PIP and DIP (thumb: MCP and IP) link bodies of each finger
    links = {f.name: f.links for f in hand.config.fingers}
    assert len(mapping.phalanges) == 2 * len(links)
    for finger, body_list in links.items():
        assert len(set(mapping.phalanges) & set(body_list)) == 2, finger
    # the operator's wrist point: the palm's proximal end, within the palm box's back-to-front
    # extent and centred across it (frame_palm, metres)
    lo = hand.config.palm.box_center - hand.config.palm.box_half_extents
    hi = hand.config.palm.box_center + hand.config.palm.box_half_extents
    assert mapping.wrist_pos_m[0] == pytest.approx(0.0)
    assert lo[1] - 0.02 < mapping.wrist_pos_m[1] < hi[1]
    assert mapping.wrist_pos_m[2] == pytest.approx(lo[2], abs=0.005)
    rt = Retargeter(hand)   # checks fingers and phalanx bodies against the model
    assert rt.finger_names == hand.finger_names
    assert len(rt.phalanx_bodies) == len(mapping.phalanges)


# --- the real Quest 3 capture -------------------------------------------------------------------


@pytest.mark.parametrize("name", HANDS)
def test_capture_within_limits_and_fingertip_errors(hands, frames, name: str) -> None:
    hand = hands[name]
    rt = Retargeter(hand, load_retarget_config())
    rt.calibrate_scale(frames)
    # this operator's wrist → middle tip chain ≈ 19 cm; both robot hands ≈ 22 cm
    assert 1.05 < rt.scale < 1.3, rt.scale
    trace = retarget_frames(rt, frames)
    assert trace.q.shape == (len(frames), hand.nq)
    assert np.isfinite(trace.q).all()
    assert (trace.q >= hand.lower - 1e-9).all() and (trace.q <= hand.upper + 1e-9).all()
    missing = sum(f.right is None for f in frames)   # one frame of the capture lacks the hand
    assert trace.held.sum() == missing == rt.held_counts["no_hand"]
    summary = summarise_errors(trace)
    medians_mm = {f: s["median_m"] * 1e3 for f, s in summary["fingers"].items()}
    assert set(medians_mm) == set(MEASURED_MEDIAN_MM[name])
    for finger, measured in MEASURED_MEDIAN_MM[name].items():
        assert medians_mm[finger] < measured + MARGIN_MM, (name, medians_mm)
    # the robot follows the operator's pinch: thumb–index distance of the robot grows with the
    # operator's (open hand wide, pinch close)
    thumb, index = JOINT_INDEX["thumb_tip"], JOINT_INDEX["index_tip"]
    op = np.array([np.linalg.norm(f.right.positions[thumb] - f.right.positions[index])
                   if f.right is not None and f.right.tracked else np.nan for f in frames])
    tips = hand.fingertip_sites(trace.q)
    robot = np.linalg.norm(tips[:, hand.finger_names.index("thumb")]
                           - tips[:, hand.finger_names.index("forefinger")], axis=-1)
    live = np.isfinite(op)
    assert np.corrcoef(op[live], robot[live])[0, 1] > 0.8


# --- the synthetic operator through the bridge --------------------------------------------------


def _session_demo(hand: Hand, obj: str, tmp_path: Path):
    from teleop.bridge.rerecord import rerecord
    from teleop.record.demos import extract_demos
    from teleop.synthetic.synthesize import synthesize
    from teleop.synthetic.writer import write_session

    ep = synthesize(obj, hand=hand, seed=0)
    assert ep.reference_grasp is None   # no grasps.toml: the searched generic grasp
    raw = write_session(ep, tmp_path / "raw.mcap")
    full = rerecord(raw, tmp_path / "full.mcap", object_mode="demo")
    demos = extract_demos(full)
    assert demos, (hand.name, obj)
    return max(demos, key=lambda d: d.duration_s)


def _assert_grasp(best, name: str, obj: str) -> None:
    assert "thumb" in best.fingers and len(best.fingers) >= 2, (name, obj, best.fingers)
    assert best.duration_s >= 0.3, (name, obj, best.duration_s)


@needs_ycb
@pytest.mark.parametrize("name, obj", [
    ("allegro_right", "013_apple"), ("allegro_right", "006_mustard_bottle"),
    ("leap_right", "013_apple"), ("leap_right", "006_mustard_bottle")])
def test_synthetic_session_gives_a_demo(hands, name: str, obj: str, tmp_path: Path) -> None:
    _assert_grasp(_session_demo(hands[name], obj, tmp_path), name, obj)


def test_bridge_servos_follow_the_hand_folder(hands) -> None:
    """The LEAP names its own teleop gain (hand.toml [teleop] servo_kp_scale = 1); the Allegro
    takes the bridge's."""
    from teleop.bridge.config import hand_servos, load_bridge_config

    cfg = load_bridge_config()
    assert hand_servos(cfg, hands["leap_right"]).kp_scale == 1.0
    assert hand_servos(cfg, hands["allegro_right"]).kp_scale == cfg.servos.kp_scale == 5.0


@needs_ycb
def test_leap_at_the_bridge_gain_gives_no_demo(hands, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """Why the LEAP names its own gain: at the bridge's kp × 5 and 4 ms its light links make
    MuJoCo unstable (bad QACC at the free hand joint, the scene restored again and again) and
    no fingertip ever touches the apple — the demo check of the test above can fail."""
    import teleop.bridge.bridge as bridge_module

    monkeypatch.setattr(bridge_module, "hand_servos", lambda cfg, hand: cfg.servos)
    with pytest.raises(DemoError):
        _session_demo(hands["leap_right"], "013_apple", tmp_path)
