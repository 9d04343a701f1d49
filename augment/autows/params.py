"""AutoWS parameters (``[autows]`` of ``configs/augment.toml``) and the error of AutoWS.

:class:`AutoWSParams` holds the joint-grid steps, the mean-normal filter band, the skeleton
spacing and the fingertip/contact-face parameters (:class:`augment.autows.fingertip.FingertipParams`);
:func:`load_autows_params` reads them from TOML with errors that name the file and key. The
parameters enter the workspace cache key (:mod:`augment.autows.cache`) through
:meth:`AutoWSParams.to_dict`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from augment.autows.fingertip import FingertipParams
from sim.config import load_toml
from sim.errors import ConfigError, DexaugError
from sim.paths import CONFIG_DIR

__all__ = ["AUGMENT_TOML", "AutoWSParams", "WorkspaceError", "load_autows_params"]

AUGMENT_TOML = CONFIG_DIR / "augment.toml"


class WorkspaceError(DexaugError, ValueError):
    """A workspace cloud cannot be built or read: empty or invalid joint ranges, a demo that does
    not fit the hand, a fingertip without a usable contact face, or a damaged cloud file."""


@dataclass(frozen=True)
class AutoWSParams:
    """AutoWS parameters (``[autows]`` of ``configs/augment.toml``).

    Attributes:
        step_deg: grid step of the manual joint ranges, degrees (paper: 10).
        demo_step_deg: grid step around a demo's joint angles, degrees (paper: 5).
        demo_steps: steps either side of the demo angle (paper: 2 → five values).
        normal_band: half-width of the mean-normal filter's band on the normal y (paper: 0.001).
        skeleton_spacing_m: spacing of the link skeleton points, metres (5 mm).
        fingertip: fingertip cloud and contact-face parameters.
    """

    step_deg: float = 10.0
    demo_step_deg: float = 5.0
    demo_steps: int = 2
    normal_band: float = 0.001
    skeleton_spacing_m: float = 0.005
    fingertip: FingertipParams = field(default_factory=FingertipParams)

    def __post_init__(self) -> None:
        for name in ("step_deg", "demo_step_deg", "skeleton_spacing_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        if self.demo_steps < 0:
            raise ValueError(f"demo_steps must be >= 0, got {self.demo_steps}")
        if not (math.isfinite(self.normal_band) and self.normal_band >= 0):
            raise ValueError(f"normal_band must be >= 0, got {self.normal_band}")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def load_autows_params(path: Path | str | None = None) -> AutoWSParams:
    """Read ``[autows]`` of ``configs/augment.toml`` (or ``path``); missing keys take the
    defaults of :class:`AutoWSParams`. Errors name the file and key."""
    root = load_toml(path or AUGMENT_TOML)
    sec = root.section("autows", {})
    tip_keys = {f.name for f in dataclasses.fields(FingertipParams)} - {"centre"}
    sec.reject_unknown({"step_deg", "demo_step_deg", "demo_steps", "normal_band",
                        "skeleton_spacing_m", "face_centre", *tip_keys})
    d_tip = FingertipParams()
    d = AutoWSParams()
    shape = sec.str("shape", d_tip.shape)
    if shape not in ("circle", "rect"):
        raise sec.error("shape", f"expected 'circle' or 'rect', got {shape!r}")
    centre = sec.str("face_centre", d_tip.centre)
    if centre not in ("point", "inscribed"):
        raise sec.error("face_centre", f"expected 'point' or 'inscribed', got {centre!r}")
    try:
        tip = FingertipParams(
            density_per_m2=sec.float("density_per_m2", d_tip.density_per_m2, min=1.0),
            seed=sec.int("seed", d_tip.seed, min=0),
            depth_m=sec.float("depth_m", d_tip.depth_m, min=1e-6),
            normal_dot=sec.float("normal_dot", d_tip.normal_dot, min=-1.0, max=0.999999),
            shape=shape,  # type: ignore[arg-type]
            centre=centre,  # type: ignore[arg-type]
            extra_faces=sec.bool("extra_faces", d_tip.extra_faces),
            extra_min_area_ratio=sec.float("extra_min_area_ratio", d_tip.extra_min_area_ratio,
                                           min=0.0),
            extra_offset_factor=sec.float("extra_offset_factor", d_tip.extra_offset_factor,
                                          min=1e-6),
            hpr_radius_factor=sec.float("hpr_radius_factor", d_tip.hpr_radius_factor,
                                        min=1.000001))
        return AutoWSParams(
            step_deg=sec.float("step_deg", d.step_deg, min=1e-6),
            demo_step_deg=sec.float("demo_step_deg", d.demo_step_deg, min=1e-6),
            demo_steps=sec.int("demo_steps", d.demo_steps, min=0),
            normal_band=sec.float("normal_band", d.normal_band, min=0.0),
            skeleton_spacing_m=sec.float("skeleton_spacing_m", d.skeleton_spacing_m, min=1e-5),
            fingertip=tip)
    except ValueError as exc:  # cross-field checks of the dataclasses
        raise ConfigError(f"{sec.where()}: {exc}") from None
