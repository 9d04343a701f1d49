"""The bridge's settings: ``configs/teleop.toml`` ``[bridge]`` as a :class:`BridgeConfig`.

Why apart from the loop: rerecording, benchmarks and tests build a config (or change one field
of it with :func:`dataclasses.replace`) before any bridge exists. Units are in the names
(``_hz``, ``_m``, ``_deg``, ``_s``, ``_mps``); ``recordings_dir`` is relative to the repository
root. ``object_mode`` is one of :data:`OBJECT_MODES` (:mod:`teleop.bridge.object_mode`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.config import Section, load_toml
from sim.errors import ConfigError
from sim.hand.model import Hand
from sim.world.hand_spec import ServoSettings
from teleop.bridge.grasp_assist import AssistSettings
from teleop.retarget.config import TELEOP_CONFIG

__all__ = ["OBJECT_MODES", "BridgeConfig", "check_object_mode", "hand_servos", "load_bridge_config"]

Array = np.ndarray

#: "demo": the object settles on the table and is held fixed while the operator grasps (the
#: paper's demonstration mode); "free": it stays a free body (lift it for real)
OBJECT_MODES: tuple[str, ...] = ("demo", "free")

_BRIDGE_KEYS = {"state_rate_hz", "view_enabled", "view_rate_hz", "view_max_duty", "view_width",
                "view_height",
                "jpeg_quality", "world_offset_m", "object", "object_pos_m", "object_yaw_deg",
                "table", "object_mode", "settle_speed_mps", "settle_still_s",
                "settle_timeout_s", "timestep_s", "max_catchup_steps", "steps_per_frame", "recordings_dir",
                "deterministic", "hand_max_step_m", "floor", "entry_gap_s", "entry_arrive_m",
                "entry_arrive_deg", "object_reset_below_m", "object_reset_beyond_m",
                "object_reset_after_s", "assist_press_m", "assist_engage_s", "assist_ramp_s",
                "assist_release_s", "assist_squeeze", "servo_kp_scale"}


@dataclass
class BridgeConfig:
    """``configs/teleop.toml`` ``[bridge]``; see the file for what each key does."""

    file: Path | None = None
    state_rate_hz: float = 120.0
    view_enabled: bool = True
    view_rate_hz: float = 30.0
    view_max_duty: float = 0.25
    view_width: int = 320
    view_height: int = 240
    jpeg_quality: int = 80
    world_offset_m: Array = field(default_factory=lambda: np.array([0.0, 0.0, -0.8]))
    object: str = "box"
    object_pos_m: Array = field(default_factory=lambda: np.array([0.35, 0.0]))
    object_yaw_deg: float = 0.0
    table: bool = True
    object_mode: str = "demo"
    settle_speed_mps: float = 0.005
    settle_still_s: float = 0.1
    settle_timeout_s: float = 2.0
    timestep_s: float = 0.004
    max_catchup_steps: int = 25
    steps_per_frame: int = 3
    recordings_dir: Path = Path("recordings")
    deterministic: bool = False
    #: metres per processed frame the hand base may move at most (teleop.bridge.faults)
    hand_max_step_m: float = 0.1
    #: a floor plane at the operator's floor (``world_offset_m`` z, below the table top)
    floor: bool = True
    #: the hand enters again (hand–object contacts off, teleop.bridge.entry) after a tracking
    #: gap longer than this (seconds, the sender's clock); it has entered once its base is
    #: within ``entry_arrive_m`` (metres) and ``entry_arrive_deg`` (degrees) of the operator's
    entry_gap_s: float = 0.2
    entry_arrive_m: float = 0.01
    entry_arrive_deg: float = 5.0
    #: the object has left the table when its centre of mass is more than
    #: ``object_reset_below_m`` below the table top or ``object_reset_beyond_m`` past its edge
    #: (metres); after ``object_reset_after_s`` (simulated seconds) off it, it is placed again
    #: (teleop.bridge.object_watch)
    object_reset_below_m: float = 0.05
    object_reset_beyond_m: float = 0.1
    object_reset_after_s: float = 1.0
    #: grasp assist (teleop.bridge.grasp_assist): press (metres into the object; 0: off) and
    #: its timing (simulated seconds)
    assist: AssistSettings = field(default_factory=AssistSettings)
    #: the hand's position servos (each servo's own kp × servo_kp_scale; force limits the model's)
    servos: ServoSettings = field(default_factory=lambda: ServoSettings(kp_scale=5.0))


def load_bridge_config(path: Path | str | None = None) -> BridgeConfig:
    """Read ``[bridge]`` of ``configs/teleop.toml`` (or ``path``); a missing table gives the
    defaults. Unknown keys are refused; errors are ConfigError naming the file and key."""
    path = Path(path) if path is not None else TELEOP_CONFIG
    root = load_toml(path)
    sec: Section = root.section("bridge", {})
    sec.reject_unknown(_BRIDGE_KEYS)
    d = BridgeConfig()
    rec_dir = Path(sec.str("recordings_dir", str(d.recordings_dir)))
    if not rec_dir.is_absolute():
        rec_dir = path.parent.parent / rec_dir  # relative to the repository root
    offset = np.array(sec.floats("world_offset_m", 3, list(d.world_offset_m)))
    floor = sec.bool("floor", d.floor)
    if floor and offset[2] >= 0.0:
        raise ConfigError(f"{sec.where('floor')}: the floor lies at world_offset_m z = "
                          f"{offset[2]:g} m, expected below the table top (z < 0), or floor = false")
    return BridgeConfig(
        file=path,
        state_rate_hz=sec.float("state_rate_hz", d.state_rate_hz, min=1e-3),
        view_enabled=sec.bool("view_enabled", d.view_enabled),
        view_rate_hz=sec.float("view_rate_hz", d.view_rate_hz, min=1e-3),
        view_max_duty=sec.float("view_max_duty", d.view_max_duty, min=0.01, max=1.0),
        view_width=sec.int("view_width", d.view_width, min=16),
        view_height=sec.int("view_height", d.view_height, min=16),
        jpeg_quality=sec.int("jpeg_quality", d.jpeg_quality, min=1),
        world_offset_m=offset,
        object=sec.str("object", d.object),
        object_pos_m=np.array(sec.floats("object_pos_m", 2, list(d.object_pos_m))),
        object_yaw_deg=sec.float("object_yaw_deg", d.object_yaw_deg),
        table=sec.bool("table", d.table),
        object_mode=check_object_mode(sec.str("object_mode", d.object_mode),
                                      sec.where("object_mode")),
        settle_speed_mps=sec.float("settle_speed_mps", d.settle_speed_mps, min=1e-6),
        settle_still_s=sec.float("settle_still_s", d.settle_still_s, min=0.0),
        settle_timeout_s=sec.float("settle_timeout_s", d.settle_timeout_s, min=0.0),
        timestep_s=sec.float("timestep_s", d.timestep_s, min=1e-4, max=0.05),
        max_catchup_steps=sec.int("max_catchup_steps", d.max_catchup_steps, min=1),
        steps_per_frame=sec.int("steps_per_frame", d.steps_per_frame, min=0),
        recordings_dir=rec_dir,
        deterministic=sec.bool("deterministic", d.deterministic),
        hand_max_step_m=sec.float("hand_max_step_m", d.hand_max_step_m, min=1e-4),
        floor=floor,
        entry_gap_s=sec.float("entry_gap_s", d.entry_gap_s, min=0.0),
        entry_arrive_m=sec.float("entry_arrive_m", d.entry_arrive_m, min=1e-4),
        entry_arrive_deg=sec.float("entry_arrive_deg", d.entry_arrive_deg, min=0.01, max=180.0),
        object_reset_below_m=sec.float("object_reset_below_m", d.object_reset_below_m, min=0.0),
        object_reset_beyond_m=sec.float("object_reset_beyond_m", d.object_reset_beyond_m,
                                        min=0.0),
        object_reset_after_s=sec.float("object_reset_after_s", d.object_reset_after_s, min=0.0),
        servos=ServoSettings(kp_scale=sec.float("servo_kp_scale", d.servos.kp_scale, min=0.1,
                                                max=100.0)),
        assist=AssistSettings(
            press_m=sec.float("assist_press_m", d.assist.press_m, min=0.0, max=0.05),
            engage_s=sec.float("assist_engage_s", d.assist.engage_s, min=0.0, max=5.0),
            ramp_s=sec.float("assist_ramp_s", d.assist.ramp_s, min=0.0, max=5.0),
            release_s=sec.float("assist_release_s", d.assist.release_s, min=0.0, max=5.0),
            squeeze=sec.bool("assist_squeeze", d.assist.squeeze)),
    )


def hand_servos(cfg: BridgeConfig, hand: Hand) -> ServoSettings:
    """The servos the bridge gives ``hand``: its ``hand.toml`` ``[teleop] servo_kp_scale`` when
    it names one (a hand that is unstable at the bridge's scale, such as the LEAP), else the
    bridge's ``servo_kp_scale``."""
    scale = hand.config.teleop_kp_scale
    return cfg.servos if scale is None else ServoSettings(kp_scale=scale)


def check_object_mode(mode: Any, where: str) -> str:
    """``mode`` if it is one of :data:`OBJECT_MODES`, else ConfigError naming ``where`` (a
    file and key, a control request, a session's metadata)."""
    if mode not in OBJECT_MODES:
        raise ConfigError(f"{where}: expected one of {', '.join(OBJECT_MODES)}, got {mode!r}")
    return str(mode)
