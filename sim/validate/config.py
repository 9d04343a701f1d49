"""The validator's parameters: ``configs/validate.toml`` read into frozen dataclasses.

One section per part of a validation: ``[common]`` (placement, closing, contacts, grasp wrench
space), ``[lift_drop]`` and ``[six_dir]`` (each protocol's physics and limits). Every key is
checked on load (unknown keys and out-of-range values raise ``ConfigError`` naming the file and
key), so a validator never runs on a misspelt setting. Units: metres, seconds, newtons, radians
(the TOML gives rotation limits in degrees, converted here).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.config import load_toml
from sim.paths import CONFIG_DIR
from sim.world.object_spec import ContactParams

__all__ = ["GRAVITY_MPS2", "PROTOCOLS", "VALIDATE_TOML", "CommonParams", "LiftDropParams",
           "SixDirParams", "ValidateConfig"]

PROTOCOLS = ("lift-drop", "six-dir")
VALIDATE_TOML = CONFIG_DIR / "validate.toml"
GRAVITY_MPS2 = 9.81


@dataclass(frozen=True)
class CommonParams:
    max_penetration_m: float
    contact_search_m: float
    pregrasp_backoff_m: float
    squeeze_depth_m: float
    grip_safety: float
    min_grip_force_n: float
    close_time_s: float
    settle_time_s: float
    pin_while_closing: bool
    servo_kp_scale: float
    contact: ContactParams
    gws_mu: float


@dataclass(frozen=True)
class LiftDropParams:
    timestep_s: float
    impratio: float
    lift_height_m: float
    lift_time_s: float
    hold_time_s: float
    drop_time_s: float
    max_displacement_m: float
    max_rotation_rad: float
    drop_min_fall_m: float


@dataclass(frozen=True)
class SixDirParams:
    timestep_s: float
    impratio: float
    noslip_iterations: int
    force_per_kg: float
    push_time_s: float
    max_displacement_m: float
    max_rotation_rad: float


@dataclass(frozen=True)
class ValidateConfig:
    common: CommonParams
    lift_drop: LiftDropParams
    six_dir: SixDirParams

    @classmethod
    def load(cls, path: Path | str = VALIDATE_TOML) -> ValidateConfig:
        root = load_toml(path)
        root.reject_unknown({"common", "lift_drop", "six_dir"})
        c = root.section("common")
        c.reject_unknown({"max_penetration_m", "contact_search_m", "pregrasp_backoff_m",
                          "squeeze_depth_m", "grip_safety", "min_grip_force_n", "close_time_s",
                          "settle_time_s", "pin_while_closing", "servo_kp_scale", "friction",
                          "solref",
                          "gws_mu"})
        pos = {"min": 0.0}
        friction = tuple(c.floats("friction", 3))
        if friction[0] <= 0.0:  # the grip force is weight / friction
            raise c.error("friction", f"sliding friction must be > 0, got {friction[0]}")
        common = CommonParams(
            max_penetration_m=c.float("max_penetration_m", **pos),
            contact_search_m=c.float("contact_search_m", **pos),
            pregrasp_backoff_m=c.float("pregrasp_backoff_m", **pos),
            squeeze_depth_m=c.float("squeeze_depth_m", **pos),
            grip_safety=c.float("grip_safety", **pos),
            min_grip_force_n=c.float("min_grip_force_n", **pos),
            close_time_s=c.float("close_time_s", min=1e-3),
            settle_time_s=c.float("settle_time_s", **pos),
            pin_while_closing=c.bool("pin_while_closing"),
            servo_kp_scale=c.float("servo_kp_scale", min=1e-3),
            contact=ContactParams(friction=friction, solref=tuple(c.floats("solref", 2))),
            gws_mu=c.float("gws_mu", min=0.0))
        ld = root.section("lift_drop")
        ld.reject_unknown({"timestep_s", "impratio", "lift_height_m", "lift_time_s", "hold_time_s",
                           "drop_time_s", "max_displacement_m", "max_rotation_deg",
                           "drop_min_fall_m"})
        lift = LiftDropParams(
            timestep_s=ld.float("timestep_s", min=1e-4, max=0.02),
            impratio=ld.float("impratio", min=1.0),
            lift_height_m=ld.float("lift_height_m", **pos), lift_time_s=ld.float("lift_time_s", min=1e-3),
            hold_time_s=ld.float("hold_time_s", **pos), drop_time_s=ld.float("drop_time_s", **pos),
            max_displacement_m=ld.float("max_displacement_m", **pos),
            max_rotation_rad=np.deg2rad(ld.float("max_rotation_deg", min=0.0, max=180.0)),
            drop_min_fall_m=ld.float("drop_min_fall_m", **pos))
        sd = root.section("six_dir")
        sd.reject_unknown({"timestep_s", "impratio", "noslip_iterations", "force_per_kg", "push_time_s",
                           "max_displacement_m", "max_rotation_deg"})
        six = SixDirParams(
            timestep_s=sd.float("timestep_s", min=1e-4, max=0.02),
            impratio=sd.float("impratio", min=1.0),
            noslip_iterations=sd.int("noslip_iterations", min=0),
            force_per_kg=sd.float("force_per_kg", **pos), push_time_s=sd.float("push_time_s", **pos),
            max_displacement_m=sd.float("max_displacement_m", **pos),
            max_rotation_rad=np.deg2rad(sd.float("max_rotation_deg", min=0.0, max=180.0)))
        return cls(common, lift, six)
