"""Power-grasp parameters: the ``[power]`` table of ``configs/augment.toml``, validated on load.

Units: metres, seconds. Kept apart from the generator so the CLI can check them first.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

from augment.autows.params import AUGMENT_TOML
from sim.config import load_toml
from sim.errors import ConfigError

__all__ = ["PowerParams", "load_power_params"]


@dataclass(frozen=True)
class PowerParams:
    """How power grasps are placed, closed and kept (:mod:`augment.power`).

    Attributes:
        standoff_m: gap between the open hand and the object surface before closing.
        max_palm_gap_m: farthest the palm may then be from the object (a thumb sticking out
            of the palm plane touches first on a flat face; a palm that overhangs an edge
            misses).
        approach_pose / close_pose: the hand's named postures (``[grasp]`` of its hand.toml)
            to close from and toward.
        close_time_s / hold_time_s: how long the controls ramp, then hold, while closing.
        settle_free: the object is held still while the fingers close and squeeze, then let
            go while they relax (gravity off), so it settles where the hand holds it — as it
            would in a real hand, and as it is in a validation, whose closing leaves it free
            — and the grasp is read where it came to rest. False: held throughout (the grasp
            records where the links stopped on an object that could not move).
        contact_m: a hand body within this distance of the object touches it.
        max_effort: keep grasps whose least worst actuator effort for the validation's loads
            is at most this fraction of the force limits (1: the actuators can just hold).
        oversample: find this many times the grasps asked for and keep those of least
            actuator effort (README "Power grasps": the effort ranks them, AUC 0.66–0.84).
        auto_pilot: ``dexaug generate --mode auto`` first makes and validates this many grasps
            of each mode (:mod:`dexaug.commands.auto_mode`).
        auto_margin: ... and makes power grasps only when the power pilot's pass share beats the
            fingertip pilot's by more than this (fingertip grasps cost 5–10× less per validated
            grasp, so near-ties go to them).
        tries_per_grasp: closings (one simulation each) per requested grasp before giving up;
            placements, which cost a few collision passes, up to ten times as many.
        seed_overshoot / seed_share / seed_turn_deg / seed_shift_m: with a power demo as the
            seed (:mod:`augment.power.demo_seed`): how far past the person's posture toward
            ``close_pose`` the touching fingers close (0–1), the share of placements that are
            the demo's palm frame turned about the object's centre of mass by up to
            ``seed_turn_deg`` degrees and shifted up to ``seed_shift_m``.
    """

    standoff_m: float = 0.003
    max_palm_gap_m: float = 0.015
    approach_pose: str = "open_pose"
    close_pose: str = "close_pose"
    close_time_s: float = 0.5
    hold_time_s: float = 0.3
    settle_free: bool = True
    contact_m: float = 0.002
    max_effort: float = 1.0
    tries_per_grasp: int = 20
    oversample: float = 2.0
    auto_pilot: int = 10
    auto_margin: float = 0.1
    seed_overshoot: float = 0.5
    seed_share: float = 0.5
    seed_turn_deg: float = 30.0
    seed_shift_m: float = 0.01

    def __post_init__(self) -> None:
        for name in ("standoff_m", "hold_time_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a number >= 0, got {v}")
        for name in ("close_time_s", "contact_m", "max_effort", "max_palm_gap_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v}")
        if not (math.isfinite(self.oversample) and self.oversample >= 1.0):
            raise ValueError(f"oversample must be a number >= 1, got {self.oversample}")
        if not 0.0 <= self.auto_margin <= 1.0:
            raise ValueError(f"auto_margin must be a share from 0 to 1, got {self.auto_margin}")
        if self.auto_pilot < 1:
            raise ValueError(f"auto_pilot must be >= 1 grasp, got {self.auto_pilot}")
        for name in ("seed_overshoot", "seed_share"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be a share from 0 to 1, got {getattr(self, name)}")
        for name in ("seed_turn_deg", "seed_shift_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a number >= 0, got {v}")
        if self.tries_per_grasp < 1:
            raise ValueError(f"tries_per_grasp must be >= 1, got {self.tries_per_grasp}")


def load_power_params(path: Path | str | None = None,
                      hand_file: Path | str | None = None) -> PowerParams:
    """``[power]`` of ``configs/augment.toml`` (or ``path``), then the keys a hand's own
    ``hand.toml`` sets in its ``[power]`` table (``hand_file``; e.g. when its fingers close
    differently); missing keys take the defaults of :class:`PowerParams`; errors name the file
    and key."""
    fields = [f.name for f in dataclasses.fields(PowerParams)]
    params = PowerParams()
    sections = [load_toml(path or AUGMENT_TOML).section("power", {})]
    if hand_file is not None:
        sections.append(load_toml(hand_file).section("power", {}))
    for sec in sections:        # each on top of the last; a bad value names its own file
        sec.reject_unknown(set(fields))
        try:
            params = dataclasses.replace(params, **{name: sec.like(name, getattr(params, name))
                                                    for name in fields if name in sec.data})
        except ValueError as exc:
            raise ConfigError(f"{sec.where()}: {exc}") from None
    return params
