"""FSG parameters: the ``[fsg]`` table of ``configs/augment.toml`` and the package's error type.

Kept apart from the sampler so that the CLI and the pipeline can read and check the options
(and name the config file) without importing the sampling code.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from augment.autows.params import AUGMENT_TOML
from sim.config import load_toml
from sim.errors import ConfigError, DexaugError
from sim.hand.config import HandConfig

__all__ = ["HAND_FIELDS", "FsgError", "FsgParams", "load_fsg_params"]



class FsgError(DexaugError, ValueError):
    """FSG cannot run on these inputs (a workspace cloud of another hand, bad options)."""


@dataclass(frozen=True)
class FsgParams:
    """FSG parameters (``[fsg]`` of ``configs/augment.toml``, and the hand's geometry from
    ``[geometry]`` of its ``hand.toml``); metres and radians.

    ``fingertip_width_m`` (w_tip of the paper's eq. 2) and ``link_clearance_m`` (the link
    radius of the link check) are properties of the hand, so they have no default here: they
    come from the hand's folder (:func:`load_fsg_params`). The other defaults are the paper's /
    the authors' numbers where they exist (DESIGN §4); the rest are marked "dexaug" in the
    config file. What each one does: the step of the :mod:`augment.fsg` overview that uses it.
    """

    fingertip_width_m: float
    link_clearance_m: float
    outer: int = 200
    inner: int = 15
    outer_batch: int = 40
    max_palm_points: int = 3
    table_clearance_m: float = 0.005
    match_distance_m: float = 0.008
    normal_dot: float = -0.98
    k_neighbours: int = 4
    contact_plane_m: float = 0.005
    min_contacts: int = 3
    max_contacts_per_finger: int = 4
    max_face_depth_m: float = 0.003
    mu: float = 0.5
    n_edges: int = 8
    min_epsilon: float = 0.0
    relax_closure: bool = True
    min_valid: int = 10
    min_fingers: int = 2
    dedup_pos_m: float = 0.005
    dedup_quat: float = 5e-3
    dedup_joint_rad: float = 0.1
    hold_oversample: float = 1.0
    dgb_hold_oversample: float = 1.0
    max_actuator_effort: float = math.inf

    def __post_init__(self) -> None:
        for name in ("outer", "inner", "outer_batch", "k_neighbours", "min_contacts",
                     "max_contacts_per_finger", "n_edges", "min_fingers"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("hold_oversample", "dgb_hold_oversample"):
            if not getattr(self, name) >= 1.0:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.max_actuator_effort > 0:
            raise ValueError(f"max_actuator_effort must be > 0 (inf: off), got "
                             f"{self.max_actuator_effort}")
        for name in ("match_distance_m", "fingertip_width_m", "contact_plane_m", "mu"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v}")


#: the FsgParams a hand's ``hand.toml`` gives (``[geometry]``), not ``configs/augment.toml``
HAND_FIELDS = ("fingertip_width_m", "link_clearance_m")


def load_fsg_params(hand: HandConfig, path: Path | str | None = None) -> FsgParams:
    """Read ``[fsg]`` of ``configs/augment.toml`` (or ``path``) for ``hand`` (whose
    ``[geometry]`` gives :data:`HAND_FIELDS`); missing keys (or a missing table) take the
    defaults of :class:`FsgParams`. Errors name the file and key."""
    root = load_toml(path or AUGMENT_TOML)
    sec = root.section("fsg", {})
    fields = {f.name: f for f in dataclasses.fields(FsgParams)}
    for name in HAND_FIELDS:
        if name in sec.data:
            raise sec.error(name, "is a property of the hand: set it in [geometry] of "
                                  "configs/hands/<hand>/hand.toml")
    sec.reject_unknown(set(fields) - set(HAND_FIELDS))
    geometry = {"fingertip_width_m": hand.fingertip_width_m,
                "link_clearance_m": hand.link_radius_m}
    d = FsgParams(fingertip_width_m=hand.fingertip_width_m, link_clearance_m=hand.link_radius_m)
    kw: dict[str, Any] = dict(geometry)
    for name in set(fields) - set(HAND_FIELDS):
        kw[name] = sec.like(name, getattr(d, name))
    try:
        return FsgParams(**kw)
    except ValueError as exc:
        raise ConfigError(f"{sec.where()}: {exc}") from None
