"""The synthetic operator with a person's geometry and timing (``[synth] standoff_m`` and
``lift_delay_s``): fingertips that stop short of the object, and a lift soon after touching.

Why these matter: the operator's old settings press the tips 1 cm into the object and hold,
which real people do not (their tracked tips stop 3–8 mm off a virtual object, and they lift
0.12–0.64 s after first contact); a benchmark judged on those settings flatters the teleop path.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sim.errors import ConfigError
from teleop.synthetic.config import load_synth_config
from teleop.synthetic.episode import TOUCH_AT
from teleop.synthetic.human_hand import FINGERS
from teleop.synthetic.synthesize import synthesize
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow

HUMAN = {"close_s": 0.3, "standoff_m": (0.003, 0.008), "lift_delay_s": (0.12, 0.60),
         "press_depth_m": 0.0}


def _human_cfg():
    return dataclasses.replace(load_synth_config(), **HUMAN)


def _pad_gaps_at_grasp_m(ep) -> dict[str, float]:
    """Per finger, the gap (metres, negative: inside) between the operator's own pad (tip
    joint less its radius) and the object's surface in the frame nearest the grasp moment,
    exact over the mesh's triangles."""
    from sim.transforms import quat_to_mat
    from sim.world.objects import load_object
    from teleop.messages import JOINT_INDEX
    from teleop.synthetic.surface import surface_distance_m

    frame = min((f for f in ep.frames if f.right is not None and f.right.tracked),
                key=lambda f: abs(f.device_time_s - ep.grasp_time_s)).right
    rows = [JOINT_INDEX[f"{f}_tip"] for f in FINGERS]
    local = (frame.positions[rows] - ep.object_pos_m) @ quat_to_mat(ep.object_quat_wxyz)
    gaps = surface_distance_m(load_object(ep.object_name).surface_mesh(), local)
    return dict(zip(FINGERS, (gaps - frame.radii[rows]).tolist(), strict=True))


@needs_menagerie
@needs_ycb
def test_the_operators_own_pads_stop_short_of_the_surface() -> None:
    """The operator's tracked pads (not the robot tips they map onto) end the drawn standoff
    *outside* the surface at the grasp, sensor noise off. Measured on the version that put
    the standoff on the mapped robot tips: the human pads then sat 2–10 mm *inside* (the
    retargeter's scale maps a robot pad on the surface back into the object)."""
    quiet = {"position_noise_m": 0.0, "orientation_noise_deg": 0.0, "dropout_fraction": 0.0}
    ep = synthesize("006_mustard_bottle", hand="shadow_right", seed=3,
                    config=dataclasses.replace(_human_cfg(), **quiet))
    standoff = ep.metadata["standoff_m"]
    assert set(standoff) == set(FINGERS)
    assert all(0.003 <= v <= 0.008 for v in standoff.values())
    gaps = _pad_gaps_at_grasp_m(ep)
    touching = {f for f in FINGERS if abs(gaps[f] - standoff[f]) < 0.01}
    assert "thumb" in touching and len(touching) >= 3, gaps
    for f in touching:
        assert gaps[f] > 0.0, f"{f}'s pad ends {gaps[f] * 1e3:.1f} mm inside the object"
        assert abs(gaps[f] - standoff[f]) < 0.003, (f, gaps[f], standoff[f])
    old = synthesize("006_mustard_bottle", hand="shadow_right", seed=3,
                     config=dataclasses.replace(load_synth_config(), close_s=0.3, **quiet))
    assert min(_pad_gaps_at_grasp_m(old)[f] for f in touching) < 0.0   # the old one presses in


@needs_menagerie
@needs_ycb
def test_the_lift_follows_the_touch_by_the_drawn_delay() -> None:
    delays = []
    for seed in (0, 1):
        ep = synthesize("005_tomato_soup_can", hand="shadow_right", seed=seed,
                        config=_human_cfg())
        close0, close1 = ep.phases["close"]
        touch_s = close0 + TOUCH_AT * (close1 - close0)
        delay = ep.phases["lift"][0] - touch_s
        assert delay == pytest.approx(ep.metadata["lift_delay_s"], abs=1e-6)
        assert 0.12 - 1e-9 <= delay <= 0.60 + 1e-9
        delays.append(delay)
    assert delays[0] != delays[1]   # drawn per episode from the seed


def test_ranges_are_validated(tmp_path: Path) -> None:
    bad = tmp_path / "teleop.toml"
    bad.write_text("[synth]\nstandoff_m = [0.008, 0.003]\n")
    with pytest.raises(ConfigError, match="standoff_m"):
        load_synth_config(bad)
    ok = tmp_path / "ok.toml"
    ok.write_text("[synth]\nstandoff_m = [0.003, 0.008]\nlift_delay_s = [0.1, 0.6]\n")
    cfg = load_synth_config(ok)
    assert cfg.standoff_m == (0.003, 0.008) and cfg.lift_delay_s == (0.1, 0.6)
    assert np.isclose(load_synth_config().standoff_m[1], 0.0)   # off unless asked for
