"""Settings of the synthetic operator and its sensor: ``configs/teleop.toml`` ``[synth]``
(:class:`SynthConfig`, :func:`load_synth_config`).

Units: metres, seconds, radians (degrees only in ``*_deg`` keys).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.config import load_toml
from teleop.retarget.config import TELEOP_CONFIG

__all__ = ["SynthConfig", "load_synth_config"]


@dataclass(frozen=True)
class SynthConfig:
    """``[synth]`` of ``configs/teleop.toml``: the synthetic operator and its sensor.

    Timing: rate_hz (frames per second), time_jitter_s (std of device timestamps), latency_s
    and latency_jitter_s (receive − device time). Noise: position_noise_m (per joint, per
    axis), orientation_noise_deg (per joint, per axis of a small random rotation). Dropouts:
    dropout_fraction (long-run fraction of untracked frames), dropout_burst_frames (min, max
    length of a burst, uniform). Hand: hand_length_m (wrist → middle tip, straight hand).
    tip_surface_snap_m: reference pulp sites closer than this to the object surface are put
    on it before the operator's fingers are fitted (0: imitate the reference exactly).
    press_depth_m: in a generic grasp (no reference), how far past the surface the operator
    closes the fingertips (mapped onto the robot): without touch feedback a person closes
    until the object stops the fingers, and a robot fingertip aimed at the surface stops
    short of it by the retargeting error. table_clearance_m: how far above the table the
    operator keeps the fingers while reaching (they see it; :mod:`teleop.synthetic.preshape`).
    grip_friction: the sliding friction a generic grasp's fingertips are counted on to have
    when the operator picks a placement that can hold the object up (a person's dry grip on
    household objects, ≈ 0.5; :mod:`teleop.synthetic.grasp_search`).
    Human geometry and timing (both off, (0, 0), by default: the operator as it always was).
    standoff_m: (min, max) metres; when max > 0 each of the operator's own pads (its tip joint
    less the joint's radius, not the robot tip it maps onto) stops a distance drawn uniformly
    from it *short* of the surface (no press-in): a person's tracked fingertips stop 3–8 mm off
    a virtual object they hold (nothing stops the real finger, and the hand model and tracking
    are off by that much); whether the robot's pads then reach the object is the
    retargeter's job. lift_delay_s: (min, max) seconds; when max > 0 the lift
    begins a time drawn uniformly from it after the fingers reach the object (people lift
    0.12–0.64 s after first contact, median 0.36 s), replacing settle_s. Drawn per episode
    from the seed (:func:`teleop.synthetic.synthesize.synthesize`).
    Episode: approach_distance_m (start of the wrist, back along the palm normal and up),
    lift_height_m, and the phase durations in seconds. Scene: object_pos_m / object_rpy_deg
    (object frame in the world when the caller gives none), head_pos_m, head_pitch_deg
    (looking down).
    """

    rate_hz: float = 72.0
    time_jitter_s: float = 0.0015
    latency_s: float = 0.025
    latency_jitter_s: float = 0.004
    position_noise_m: float = 0.0025
    orientation_noise_deg: float = 2.0
    dropout_fraction: float = 0.03
    dropout_burst_frames: tuple[int, int] = (2, 10)
    hand_length_m: float = 0.185
    tip_surface_snap_m: float = 0.02
    press_depth_m: float = 0.01
    table_clearance_m: float = 0.01
    object_clearance_m: float = 0.015
    grip_friction: float = 0.5
    approach_distance_m: float = 0.25
    lift_height_m: float = 0.10
    still_s: float = 0.4
    approach_s: float = 1.5
    close_s: float = 0.8
    settle_s: float = 0.8
    lift_s: float = 1.0
    hold_s: float = 1.0
    release_s: float = 0.8
    retreat_s: float = 0.8
    object_pos_m: tuple[float, float, float] = (0.35, 0.0, 0.80)
    object_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    head_pos_m: tuple[float, float, float] = (0.0, 0.0, 1.25)
    head_pitch_deg: float = 30.0
    standoff_m: tuple[float, float] = (0.0, 0.0)
    lift_delay_s: tuple[float, float] = (0.0, 0.0)


_SYNTH_FLOATS = {"rate_hz": (1.0, 1000.0), "time_jitter_s": (0.0, 0.1), "latency_s": (0.0, 5.0),
                 "latency_jitter_s": (0.0, 1.0), "position_noise_m": (0.0, 0.1),
                 "orientation_noise_deg": (0.0, 45.0), "dropout_fraction": (0.0, 0.9),
                 "hand_length_m": (0.10, 0.30), "tip_surface_snap_m": (0.0, 0.1),
                 "press_depth_m": (0.0, 0.05), "table_clearance_m": (0.0, 0.1),
                 "object_clearance_m": (0.0, 0.1), "grip_friction": (0.05, 2.0),
                 "approach_distance_m": (0.0, 2.0),
                 "lift_height_m": (0.0, 1.0), "still_s": (0.0, 60.0),
                 "approach_s": (0.05, 60.0), "close_s": (0.05, 60.0), "settle_s": (0.0, 60.0),
                 "lift_s": (0.05, 60.0), "hold_s": (0.0, 60.0), "release_s": (0.05, 60.0),
                 "retreat_s": (0.0, 60.0), "head_pitch_deg": (-90.0, 90.0)}
_SYNTH_VECTORS = ("object_pos_m", "object_rpy_deg", "head_pos_m")
#: (min, max) ranges and the largest max each may have
_SYNTH_RANGES = {"standoff_m": 0.05, "lift_delay_s": 10.0}


def load_synth_config(path: Path | str | None = None) -> SynthConfig:
    """Read ``[synth]`` of ``configs/teleop.toml`` (or ``path``); keys left out keep the
    :class:`SynthConfig` defaults, unknown keys are refused (a typo would silently keep a
    default), bad values are :class:`ConfigError` naming the file and key."""
    root = load_toml(TELEOP_CONFIG if path is None else path)
    sec = root.section("synth", {})
    sec.reject_unknown({*_SYNTH_FLOATS, *_SYNTH_VECTORS, *_SYNTH_RANGES, "dropout_burst_frames"})
    values: dict[str, Any] = {}
    for key, (lo, hi) in _SYNTH_FLOATS.items():
        if key in sec:
            values[key] = sec.float(key, min=lo, max=hi)
    for key in _SYNTH_VECTORS:
        if key in sec:
            values[key] = tuple(sec.floats(key, 3))
    for key, top in _SYNTH_RANGES.items():
        if key in sec:
            lo, hi = sec.floats(key, 2)
            if not 0.0 <= lo <= hi <= top:
                raise sec.error(key, f"expected [min, max] with 0 <= min <= max <= {top}, "
                                f"got {[lo, hi]}")
            values[key] = (lo, hi)
    if "dropout_burst_frames" in sec:
        burst = sec.floats("dropout_burst_frames", 2)
        if not (1 <= burst[0] <= burst[1]) or any(b != int(b) for b in burst):
            raise sec.error("dropout_burst_frames", f"expected two integers 1 <= min <= max, "
                            f"got {burst}")
        values["dropout_burst_frames"] = (int(burst[0]), int(burst[1]))
    return SynthConfig(**values)
