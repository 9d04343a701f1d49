"""The grasp assist's squeeze (``teleop.bridge.grasp_squeeze``) lifts what the press alone cannot.

A person's grasp of the master chef can (0.41 kg), with a person's geometry and timing (tips
3–8 mm short of the surface, the lift 0.12–0.60 s after touching: the human-timed operator of
``benchmarks/bench_teleop_loop.py``), replayed through the real bridge with the object free.
With the assist's press alone the can slips back onto the table while the hand rises; with the
validator's force-sized squeeze on the joint targets it goes up with the hand. The bridge
config is the repository's, with ``assist_squeeze`` switched for the second run.

Three operator seeds. Measured since the operator's own pads stop short of the can (commit
cc7742e; before, they sat inside it and the squeezed can rose at least 60 % of the lift): the press
alone holds it 0 mm up in seeds 0–4, the squeeze 47–89 mm of the 100 mm lift. The can slips
about half-way in the hand in most seeds, so the test asserts the squeeze's effect (at least 30
% of the lift more than the press) and not a full lift; the lift itself is the benchmark's
figure (``benchmarks/bench_teleop_loop.py``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from benchmarks.bench_teleop_loop import OPERATORS
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]

OBJECT = "002_master_chef_can"


def _episode(seed: int):
    """The human-timed operator's grasp of the can, where the bridge's table has it."""
    from teleop.bridge.config import load_bridge_config
    from teleop.synthetic.config import load_synth_config
    from teleop.synthetic.synthesize import synthesize

    bridge = load_bridge_config()
    spot = tuple(np.array([*bridge.object_pos_m, 0.0]) - bridge.world_offset_m)
    cfg = dataclasses.replace(load_synth_config(), **OPERATORS["human"], object_pos_m=spot)
    return synthesize(OBJECT, hand="shadow_right", seed=seed, config=cfg), cfg


def _held_m(ep, raw: Path, out: Path, squeeze: bool, monkeypatch: pytest.MonkeyPatch) -> float:
    """How high (metres) above where it started the can is held through the operator's hold
    phase (the median of the states answering its frames), re-recorded free with the assist's
    squeeze on or off."""
    import teleop.bridge.rerecord as rerecord_module
    from teleop.bridge.config import load_bridge_config
    from teleop.record.session import open_session

    def config(path=None):
        cfg = load_bridge_config(path)
        return dataclasses.replace(cfg, assist=dataclasses.replace(cfg.assist, squeeze=squeeze))

    monkeypatch.setattr(rerecord_module, "load_bridge_config", config)
    path = rerecord_module.rerecord(raw, out, object_mode="free")
    states = [m for _, m in open_session(path).json_messages("/state")]
    device_s = {f.seq: f.device_time_s for f in ep.frames}
    lo, hi = ep.phases["hold"]
    z = np.array([m["object_pos_m"][2] for m in states])
    hold = np.array([lo <= device_s.get(m["seq"], np.nan) < hi for m in states])
    assert hold.any(), "the recording answers the hold phase's frames"
    grips = [m["extra"].get("grip_n", 0.0) for m in states]
    assert (max(grips) > 0.0) == squeeze, "the squeeze is planned exactly when it is on"
    return float(np.median(z[hold]) - z[0])


def test_the_squeeze_lifts_what_the_press_alone_leaves(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    from teleop.synthetic.writer import write_session

    for seed in range(3):
        ep, cfg = _episode(seed)
        raw = write_session(ep, tmp_path / f"raw{seed}.mcap")
        pressed = _held_m(ep, raw, tmp_path / f"press{seed}.mcap", False, monkeypatch)
        squeezed = _held_m(ep, raw, tmp_path / f"squeeze{seed}.mcap", True, monkeypatch)
        assert pressed < 0.3 * cfg.lift_height_m, (seed, pressed)
        assert squeezed >= pressed + 0.3 * cfg.lift_height_m, (seed, pressed, squeezed)
