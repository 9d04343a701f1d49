"""Retargeting settings: the solver and scale (``configs/teleop.toml`` ``[retarget]``) and, per
robot hand, the operator mapping (``configs/hands/<hand>/retarget.toml``).

Why two files: the solver settings belong to the teleop chain and hold for every hand, while
which operator hand drives a robot hand, where the operator's wrist sits in its ``frame_palm``
and which OpenXR joint drives each robot fingertip is knowledge about that hand, so it lives in
the hand's folder with the rest of it (:func:`sim.hand.config.hand_dir`). A hand's mapping is
read when that hand is retargeted (:meth:`RetargetConfig.hand`); a hand without the file can do
everything else. Errors are :class:`ConfigError` naming the file and the dotted key.

Units: metres, seconds, radians (degrees only in ``*_deg`` keys); quaternions wxyz.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.config import Section, load_toml
from sim.errors import ConfigError
from sim.hand.config import hand_dir, hand_names
from sim.paths import CONFIG_DIR
from sim.transforms import rpy_deg_to_quat
from teleop.messages import JOINT_INDEX, OPENXR_JOINTS
from teleop.retarget.input_filter import InputFilterSettings

__all__ = ["TELEOP_CONFIG", "WRIST_TO_PALM_CONVENTION", "HandMapping", "RetargetConfig",
           "hand_mapping_path", "load_hand_mapping", "load_retarget_config"]

Array = np.ndarray

TELEOP_CONFIG = CONFIG_DIR / "teleop.toml"
#: The per-hand mapping file, inside the hand's folder.
HAND_MAPPING_FILE = "retarget.toml"

#: Operator wrist axes expressed in frame_palm (columns: x, y, z of the wrist frame):
#: x_wrist (distal) → z_palm, y_wrist → −x_palm, z_wrist (dorsal) → −y_palm.
WRIST_TO_PALM_CONVENTION: Array = np.array([[0.0, -1.0, 0.0],
                                            [0.0, 0.0, -1.0],
                                            [1.0, 0.0, 0.0]])
WRIST_TO_PALM_CONVENTION.setflags(write=False)


@dataclass(frozen=True)
class HandMapping:
    """``configs/hands/<hand>/retarget.toml``: how one robot hand is driven.

    side: the operator hand ("left"/"right"). fingers: robot finger name → OpenXR joint name
    (its tip joint, whose pad drives the finger's pulp site). phalanges: robot link body name →
    OpenXR joint (an intermediate/distal joint, whose centre drives the body's origin, the
    joint at the link's proximal end; empty: no phalanx tasks).
    scale_finger: the robot finger whose wrist→pulp length calibrates the scale. wrist_pos_m:
    the operator's wrist point in the robot's frame_palm (metres). wrist_quat_wxyz: extra
    rotation of the operator's wrist frame before the convention map (from ``wrist_rpy_deg``).
    file: the file it was read from (for error messages).
    """

    hand: str
    side: str
    fingers: dict[str, str]
    phalanges: dict[str, str]
    scale_finger: str
    wrist_pos_m: Array
    wrist_quat_wxyz: Array
    file: Path


@dataclass(frozen=True)
class RetargetConfig:
    """``configs/teleop.toml`` ``[retarget]`` (see the file for what each key does).

    hands: mappings given here instead of read from the hands' folders (empty from
    :func:`load_retarget_config`; tests and experiments put variants in)."""

    file: Path
    solver: str
    iterations: int
    dt_s: float
    fingertip_cost: float
    posture_cost: float
    task_lm_damping: float
    damping: float
    limit_gain: float
    filter_time_constant_s: float | None
    filter_alpha: float | None
    scale: float
    operator_hand_length_m: float
    wrist_position_scale: float
    world_offset_m: Array
    pinch_release_gap_m: float
    pinch_cost: float
    pad_targets: bool
    phalanx_cost: float
    snap_distance_m: float
    operator_snap_distance_m: float
    operator_touch_depth_m: float
    snap_in_sim_frame: bool
    input_filter: InputFilterSettings
    calibration_s: float
    hands: Mapping[str, HandMapping] = field(default_factory=dict)

    def hand(self, name: str) -> HandMapping:
        """The mapping of robot hand ``name``: from :attr:`hands`, else read from its folder
        (:func:`load_hand_mapping`; a hand without one is a ConfigError naming the file)."""
        mapping = self.hands.get(name)
        return mapping if mapping is not None else load_hand_mapping(name)


_RETARGET_KEYS = {"solver", "iterations", "dt_s", "fingertip_cost", "posture_cost",
                  "task_lm_damping", "damping", "limit_gain", "filter_time_constant_s",
                  "filter_alpha", "scale", "operator_hand_length_m", "wrist_position_scale",
                  "world_offset_m", "pinch_release_gap_m", "pinch_cost", "pad_targets",
                  "phalanx_cost", "snap_distance_m", "operator_snap_distance_m", "operator_touch_depth_m",
                  "snap_in_sim_frame", "calibration_s",
                  "input_min_cutoff_hz", "input_beta", "input_d_cutoff_hz", "input_beta_rotation"}
_HAND_KEYS = {"side", "fingers", "phalanges", "scale_finger", "wrist_pos_m", "wrist_rpy_deg"}


def hand_mapping_path(name: str) -> Path:
    """Where the operator mapping of robot hand ``name`` lives."""
    return hand_dir(name) / HAND_MAPPING_FILE


def load_hand_mapping(name: str, path: Path | str | None = None) -> HandMapping:
    """Read and check the operator mapping of robot hand ``name`` from its folder's
    ``retarget.toml`` (or ``path``); a missing file is a ConfigError naming it and the hands
    that have one."""
    file = hand_mapping_path(name) if path is None else Path(path)
    if not file.is_file():
        mapped = [h for h in hand_names() if hand_mapping_path(h).is_file()]
        raise ConfigError(f"{file}: missing file: no retargeting mapping for hand {name!r} "
                          f"(hands with one: {mapped})")
    sec = load_toml(file)
    sec.reject_unknown(_HAND_KEYS)
    side = sec.str("side")
    if side not in ("left", "right"):
        raise sec.error("side", f"expected 'left' or 'right', got {side!r}")
    fingers_sec = sec.section("fingers")
    fingers: dict[str, str] = {}
    for finger in fingers_sec.data:
        joint = fingers_sec.str(finger)
        if joint not in JOINT_INDEX or joint in ("palm", "wrist"):
            raise fingers_sec.error(finger, f"unknown OpenXR finger joint {joint!r}; expected "
                                    f"one of {list(OPENXR_JOINTS[2:])}")
        fingers[finger] = joint
    if not fingers:
        raise fingers_sec.error(None, "expected at least one finger = \"<openxr joint>\"")
    if len(set(fingers.values())) != len(fingers):
        raise fingers_sec.error(None, "two robot fingers are driven by the same OpenXR joint")
    phalanges = _phalanges(sec, set(fingers.values()))
    scale_finger = sec.str("scale_finger")
    if scale_finger not in fingers:
        raise sec.error("scale_finger", f"{scale_finger!r} is not one of the mapped fingers "
                        f"{sorted(fingers)}")
    return HandMapping(hand=name, side=side, fingers=fingers, phalanges=phalanges,
                       scale_finger=scale_finger,
                       wrist_pos_m=np.array(sec.floats("wrist_pos_m", 3)),
                       wrist_quat_wxyz=rpy_deg_to_quat(
                           sec.floats("wrist_rpy_deg", 3, [0.0, 0.0, 0.0])),
                       file=file)


def load_retarget_config(path: Path | str | None = None) -> RetargetConfig:
    """Read and check ``[retarget]`` of ``configs/teleop.toml`` (or ``path``).

    Other top-level tables of the file belong to other loaders and are ignored here; unknown
    keys inside ``[retarget]`` are refused (a typo would otherwise silently use a default).
    Errors are :class:`ConfigError` naming the file and the dotted key.
    """
    root = load_toml(TELEOP_CONFIG if path is None else path)
    sec = root.section("retarget")
    sec.reject_unknown(_RETARGET_KEYS)
    solver = sec.str("solver", "daqp")
    import qpsolvers

    if solver not in qpsolvers.available_solvers:
        raise sec.error("solver", f"QP solver {solver!r} is not installed; available: "
                        f"{sorted(qpsolvers.available_solvers)}")
    tau = sec.float("filter_time_constant_s", None, min=0.0)
    alpha = sec.float("filter_alpha", None, min=0.0, max=1.0)
    if tau is not None and alpha is not None:
        raise sec.error("filter_alpha", "give either filter_time_constant_s or filter_alpha, "
                        "not both")
    if alpha is not None and alpha <= 0.0:
        raise sec.error("filter_alpha", "expected 0 < alpha <= 1 (1 = no filtering)")
    d_in = InputFilterSettings()
    return RetargetConfig(
        file=Path(root.file), solver=solver,
        iterations=_bounded_int(sec, "iterations", 2, 1, 10),
        dt_s=_positive(sec, "dt_s", 0.011),
        fingertip_cost=_positive(sec, "fingertip_cost", 1.0),
        posture_cost=sec.float("posture_cost", 0.003, min=0.0),
        task_lm_damping=sec.float("task_lm_damping", 0.0, min=0.0),
        damping=sec.float("damping", 1e-6, min=0.0),
        limit_gain=_positive(sec, "limit_gain", 0.95, max=1.0),
        filter_time_constant_s=None if alpha is not None else (0.015 if tau is None else tau),
        filter_alpha=alpha,
        scale=_positive(sec, "scale", 1.0),
        operator_hand_length_m=_positive(sec, "operator_hand_length_m", 0.19),
        wrist_position_scale=sec.float("wrist_position_scale", 1.0),
        world_offset_m=np.array(sec.floats("world_offset_m", 3, [0.0, 0.0, 0.0])),
        pinch_release_gap_m=sec.float("pinch_release_gap_m", 0.03, min=0.0),
        pinch_cost=sec.float("pinch_cost", 5.0, min=0.0),
        pad_targets=sec.bool("pad_targets", True),
        phalanx_cost=sec.float("phalanx_cost", 0.5, min=0.0),
        snap_distance_m=sec.float("snap_distance_m", 0.015, min=0.0, max=0.05),
        operator_snap_distance_m=sec.float("operator_snap_distance_m", 0.02, min=0.0, max=0.05),
        operator_touch_depth_m=sec.float("operator_touch_depth_m", 0.003, min=0.0, max=0.02),
        snap_in_sim_frame=sec.bool("snap_in_sim_frame", True),
        input_filter=InputFilterSettings(
            min_cutoff_hz=sec.float("input_min_cutoff_hz", d_in.min_cutoff_hz, min=0.0, max=100.0),
            beta=sec.float("input_beta", d_in.beta, min=0.0),
            d_cutoff_hz=_positive(sec, "input_d_cutoff_hz", d_in.d_cutoff_hz),
            beta_rotation=sec.float("input_beta_rotation", d_in.beta_rotation, min=0.0)),
        calibration_s=sec.float("calibration_s", 1.0, min=0.0, max=60.0),
    )


def _phalanges(sec: Section, tip_joints: set[str]) -> dict[str, str]:
    """``[phalanges]``: robot link body → OpenXR joint, each joint a finger joint that is not
    also a fingertip target and used once (the bodies are checked against the hand model by
    the retargeter)."""
    phal_sec = sec.section("phalanges", {})
    out: dict[str, str] = {}
    for body in phal_sec.data:
        joint = phal_sec.str(body)
        if joint not in JOINT_INDEX or joint in ("palm", "wrist") or joint in tip_joints:
            raise phal_sec.error(body, f"expected an OpenXR finger joint that is not a fingertip "
                                 f"target (e.g. 'index_intermediate'), got {joint!r}")
        out[body] = joint
    if len(set(out.values())) != len(out):
        raise phal_sec.error(None, "two robot bodies are driven by the same OpenXR joint")
    return out


def _positive(sec: Section, key: str, default: float, max: float | None = None) -> float:
    value = sec.float(key, default, max=max)
    if value <= 0.0:
        raise sec.error(key, f"expected a number > 0, got {value}")
    return value


def _bounded_int(sec: Section, key: str, default: int, lo: int, hi: int) -> int:
    value = sec.int(key, default, min=lo)
    if value > hi:
        raise sec.error(key, f"expected an integer in [{lo}, {hi}], got {value}")
    return value
