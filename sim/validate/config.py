"""The validator's parameters: ``configs/validate.toml`` read into frozen dataclasses.

One section per part of a validation: ``[common]`` (placement, closing, contacts, servos, grasp
wrench space of lift-drop and six-dir), ``[lift_drop]`` and ``[six_dir]`` (each protocol's
physics and limits) and ``[dgb]`` (DexGraspBench's protocol, self-contained). Every key is
checked on load (unknown keys and out-of-range values raise ``ConfigError`` naming the file and
key), so a validator never runs on a misspelt setting. Units: metres, seconds, newtons, radians
(the TOML gives rotation limits in degrees, converted here).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.config import Section, load_toml
from sim.paths import CONFIG_DIR
from sim.world.hand_spec import ServoSettings
from sim.world.object_spec import ContactParams

__all__ = ["GRAVITY_MPS2", "PROTOCOLS", "SQUEEZE_CONVENTIONS", "VALIDATE_TOML", "CommonParams",
           "DgbParams", "LiftDropParams", "SixDirParams", "ValidateConfig"]

PROTOCOLS = ("lift-drop", "six-dir", "dgb")
#: how a grasp's pregrasp and squeeze are made when it does not carry them (sim.validate.stages)
SQUEEZE_CONVENTIONS = ("dexaug", "bodex", "dgb-rule")
#: how the squeeze splits its grip force over the contacts (sim.validate.contact_forces)
SQUEEZE_FORCES = ("balanced", "equal")
VALIDATE_TOML = CONFIG_DIR / "validate.toml"
GRAVITY_MPS2 = 9.81


@dataclass(frozen=True)
class CommonParams:
    max_penetration_m: float
    contact_search_m: float
    pregrasp_backoff_m: float
    squeeze_depth_m: float
    grip_safety: float
    max_grip_safety: float
    servo_headroom: float
    min_grip_force_n: float
    squeeze_forces: str
    close_time_s: float
    settle_time_s: float
    pin_while_closing: bool
    servos: ServoSettings
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
    drop_max_time_s: float
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
    #: stop after the first direction the object slips in (the verdict is then fixed; the
    #: worst drift over all six is not measured); False pushes all six
    early_exit: bool = True


@dataclass(frozen=True)
class DgbParams:
    """DexGraspBench's fc evaluation (``[dgb]``): its own contacts, servos, object mass (None:
    the object's real mass), solver, penetration filter, closing stages and pushes, and
    whether the ``dexaug`` convention's pregrasp starts the fingers' free modes where pressing
    leaves them (:mod:`sim.validate.free_modes`), and whether its targets are chosen by
    rehearsing the closing (:mod:`sim.validate.rehearsal`)."""

    object_mass_kg: float | None
    contact: ContactParams
    servos: ServoSettings
    weld_solref: tuple[float, float]
    timestep_s: float
    impratio: float
    noslip_iterations: int
    solver_iterations: int
    ccd_iterations: int
    multiccd: bool
    islands: bool
    max_penetration_m: float
    contact_search_m: float
    stage_increments: int
    steps_per_increment: int
    force_per_kg: float
    push_time_s: float
    check_every_steps: int
    max_displacement_m: float
    max_rotation_rad: float
    squeeze_convention: str
    settle_free_modes: bool
    rehearse_closing: bool
    rehearsal_pregrasp_shares: tuple[float, ...]
    rehearsal_fallback_squeeze_scales: tuple[float, ...]
    rehearsal_drift_corrections: int
    rehearsal_rest_s: float
    rehearsal_calm_score: float
    #: skip the rehearsal's simulation whose outcome is already known (sim.validate.rehearsal:
    #: a shared pregrasp → grasp stage, corrections of a pregrasp that penetrates); False
    #: simulates every rehearsal in full. The stages chosen, and so every result, are the same.
    early_exit: bool = True


def _pair(sec: Section, key: str) -> tuple[float, float]:
    a, b = sec.floats(key, 2)  # floats() has checked the length
    return a, b


def _triple(sec: Section, key: str) -> tuple[float, float, float]:
    a, b, c = sec.floats(key, 3)  # floats() has checked the length
    return a, b, c


def _contact(sec: Section) -> ContactParams:
    friction = _triple(sec, "friction")
    if friction[0] <= 0.0:  # the grip force is weight / friction
        raise sec.error("friction", f"sliding friction must be > 0, got {friction[0]}")
    solref, solimp = _pair(sec, "solref"), _triple(sec, "solimp")
    if solref[0] <= 0 or not 0 < solimp[0] <= solimp[1] < 1 or solimp[2] <= 0:
        raise sec.error("solref", f"expected solref time constant > 0 and 0 < dmin ≤ dmax < 1, "
                        f"width > 0; got solref {solref}, solimp {solimp}")
    return ContactParams(friction=friction, solref=solref, solimp=solimp)


def _load_dgb(sec: Section) -> DgbParams:
    sec.reject_unknown({"object_mass_kg", "friction", "solref", "solimp", "servo_kp",
                        "servo_force_limit", "weld_solref", "timestep_s", "impratio",
                        "noslip_iterations", "solver_iterations", "ccd_iterations", "multiccd",
                        "islands", "max_penetration_m", "contact_search_m", "stage_increments",
                        "steps_per_increment",
                        "force_per_kg", "push_time_s", "check_every_steps",
                        "max_displacement_m", "max_rotation_deg", "squeeze_convention",
                        "settle_free_modes", "rehearse_closing", "rehearsal_pregrasp_shares",
                        "rehearsal_fallback_squeeze_scales", "rehearsal_drift_corrections",
                        "rehearsal_rest_s", "rehearsal_calm_score", "early_exit"})
    shares = tuple(sec.floats("rehearsal_pregrasp_shares"))
    if not shares or any(not 0.0 <= s <= 1.0 for s in shares):
        raise sec.error("rehearsal_pregrasp_shares",
                        f"expected one or more shares of the back-off in [0, 1], got {list(shares)}")
    key = "rehearsal_fallback_squeeze_scales"
    scales = tuple(sec.floats(key))
    if any(not 0.0 < s <= 1.0 for s in scales):
        raise sec.error(key, f"expected gentler squeezes, scales in (0, 1], got {list(scales)}")
    mass = sec.data.get("object_mass_kg")
    if mass == "real":
        mass_kg = None
    elif isinstance(mass, int | float) and not isinstance(mass, bool) and mass > 0:
        mass_kg = float(mass)
    else:
        raise sec.error("object_mass_kg", f'expected a mass > 0 (kg) or "real", got {mass!r}')
    convention = _choice(sec, "squeeze_convention", SQUEEZE_CONVENTIONS)
    servos = ServoSettings(kp=sec.float("servo_kp", min=1e-6),
                           force_limit=sec.float("servo_force_limit", min=1e-6), ctrl_limited=False)
    return DgbParams(
        object_mass_kg=mass_kg, contact=_contact(sec), servos=servos,
        weld_solref=_pair(sec, "weld_solref"),
        timestep_s=sec.float("timestep_s", min=1e-4, max=0.02), impratio=sec.float("impratio", min=1.0),
        noslip_iterations=sec.int("noslip_iterations", min=0),
        solver_iterations=sec.int("solver_iterations", min=1),
        ccd_iterations=sec.int("ccd_iterations", min=1), multiccd=sec.bool("multiccd"),
        islands=sec.bool("islands"),
        max_penetration_m=sec.float("max_penetration_m", min=0.0),
        contact_search_m=sec.float("contact_search_m", min=0.0, max=0.05),
        stage_increments=sec.int("stage_increments", min=1),
        steps_per_increment=sec.int("steps_per_increment", min=1),
        force_per_kg=sec.float("force_per_kg", min=0.0), push_time_s=sec.float("push_time_s", min=0.0),
        check_every_steps=sec.int("check_every_steps", min=1),
        max_displacement_m=sec.float("max_displacement_m", min=0.0),
        max_rotation_rad=np.deg2rad(sec.float("max_rotation_deg", min=0.0, max=180.0)),
        squeeze_convention=convention, settle_free_modes=sec.bool("settle_free_modes"),
        rehearse_closing=sec.bool("rehearse_closing"), rehearsal_pregrasp_shares=shares,
        rehearsal_fallback_squeeze_scales=scales,
        rehearsal_drift_corrections=sec.int("rehearsal_drift_corrections", min=0),
        rehearsal_rest_s=sec.float("rehearsal_rest_s", min=0.0, max=10.0),
        rehearsal_calm_score=sec.float("rehearsal_calm_score", min=0.0, max=1.0),
        early_exit=sec.bool("early_exit", True))


def _choice(sec: Section, key: str, allowed: tuple[str, ...]) -> str:
    """The string at ``key``, which must be one of ``allowed``."""
    value = sec.str(key)
    if value not in allowed:
        raise sec.error(key, f"expected one of {allowed}, got {value!r}")
    return value


@dataclass(frozen=True)
class ValidateConfig:
    common: CommonParams
    lift_drop: LiftDropParams
    six_dir: SixDirParams
    dgb: DgbParams

    @classmethod
    def load(cls, path: Path | str = VALIDATE_TOML) -> ValidateConfig:
        root = load_toml(path)
        root.reject_unknown({"common", "lift_drop", "six_dir", "dgb"})
        c = root.section("common")
        c.reject_unknown({"max_penetration_m", "contact_search_m", "pregrasp_backoff_m",
                          "squeeze_depth_m", "grip_safety", "max_grip_safety", "servo_headroom",
                          "min_grip_force_n", "squeeze_forces",
                          "close_time_s",
                          "settle_time_s", "pin_while_closing", "servo_kp_scale", "friction",
                          "solref", "solimp", "gws_mu"})
        pos = {"min": 0.0}
        common = CommonParams(
            max_penetration_m=c.float("max_penetration_m", **pos),
            contact_search_m=c.float("contact_search_m", **pos),
            pregrasp_backoff_m=c.float("pregrasp_backoff_m", **pos),
            squeeze_depth_m=c.float("squeeze_depth_m", **pos),
            grip_safety=c.float("grip_safety", **pos),
            max_grip_safety=c.float("max_grip_safety", min=c.float("grip_safety", **pos)),
            servo_headroom=c.float("servo_headroom", min=1e-6, max=1.0),
            min_grip_force_n=c.float("min_grip_force_n", **pos),
            squeeze_forces=_choice(c, "squeeze_forces", SQUEEZE_FORCES),
            close_time_s=c.float("close_time_s", min=1e-3),
            settle_time_s=c.float("settle_time_s", **pos),
            pin_while_closing=c.bool("pin_while_closing"),
            servos=ServoSettings(kp_scale=c.float("servo_kp_scale", min=1e-3)),
            contact=_contact(c),
            gws_mu=c.float("gws_mu", min=0.0))
        ld = root.section("lift_drop")
        ld.reject_unknown({"timestep_s", "impratio", "lift_height_m", "lift_time_s", "hold_time_s",
                           "drop_time_s", "drop_max_time_s", "max_displacement_m",
                           "max_rotation_deg", "drop_min_fall_m"})
        lift = LiftDropParams(
            timestep_s=ld.float("timestep_s", min=1e-4, max=0.02),
            impratio=ld.float("impratio", min=1.0),
            lift_height_m=ld.float("lift_height_m", **pos), lift_time_s=ld.float("lift_time_s", min=1e-3),
            hold_time_s=ld.float("hold_time_s", **pos), drop_time_s=ld.float("drop_time_s", **pos),
            drop_max_time_s=ld.float("drop_max_time_s", **pos),
            max_displacement_m=ld.float("max_displacement_m", **pos),
            max_rotation_rad=np.deg2rad(ld.float("max_rotation_deg", min=0.0, max=180.0)),
            drop_min_fall_m=ld.float("drop_min_fall_m", **pos))
        sd = root.section("six_dir")
        sd.reject_unknown({"timestep_s", "impratio", "noslip_iterations", "force_per_kg", "push_time_s",
                           "max_displacement_m", "max_rotation_deg", "early_exit"})
        six = SixDirParams(
            timestep_s=sd.float("timestep_s", min=1e-4, max=0.02),
            impratio=sd.float("impratio", min=1.0),
            noslip_iterations=sd.int("noslip_iterations", min=0),
            force_per_kg=sd.float("force_per_kg", **pos), push_time_s=sd.float("push_time_s", **pos),
            max_displacement_m=sd.float("max_displacement_m", **pos),
            max_rotation_rad=np.deg2rad(sd.float("max_rotation_deg", min=0.0, max=180.0)),
            early_exit=sd.bool("early_exit", True))
        return cls(common, lift, six, _load_dgb(root.section("dgb")))

