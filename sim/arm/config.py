"""Arm descriptions read from ``configs/arms/<name>/arm.toml``.

An arm config names a MuJoCo Menagerie model (or an MJCF path), its flange site (the frame the
hand's ``[mount]`` is given in: +z is the tool axis out of the arm), the arm joints IK may move,
a home configuration (radians) and where the arm's base stands relative to the table. Parsing
checks the file on its own terms and against the model, so a typo in a joint name is a one-line
error naming the file and the key, never a KeyError deep inside the IK.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from sim.config import Section, load_toml
from sim.errors import AssetError, ConfigError
from sim.paths import CONFIG_DIR, ensure_menagerie_root

ARMS_DIR = CONFIG_DIR / "arms"


@dataclass(frozen=True)
class ArmConfig:
    """One arm. ``home_rad`` holds one value per joint of ``joints`` (same order);
    ``base_pos_m`` / ``base_quat_wxyz`` place the arm's root body in the world, whose z = 0 is
    the floor (the arm stands on a pedestal of that height, drawn by the scene)."""

    name: str
    file: Path
    model_path: Path
    flange_site: str
    joints: tuple[str, ...]
    home_rad: np.ndarray
    base_pos_m: np.ndarray
    base_quat_wxyz: np.ndarray


def arm_names() -> list[str]:
    """Every arm with a folder under ``configs/arms/`` (sorted)."""
    return sorted(p.parent.name for p in ARMS_DIR.glob("*/arm.toml"))


def arm_config_path(name_or_path: str | Path) -> Path:
    """The TOML file of an arm given by name (``configs/arms/<name>/arm.toml``) or by path."""
    path = Path(name_or_path)
    return path if path.suffix == ".toml" else ARMS_DIR / str(name_or_path) / "arm.toml"


def _model_path(model: Section, config_file: Path) -> Path:
    """The arm's MJCF file: a Menagerie robot folder + xml name, or a path beside the config."""
    menagerie, rel = model.str("menagerie", None), model.str("path", None)
    if (menagerie is None) == (rel is None):
        raise model.error(None, "expected exactly one of 'menagerie' (a Menagerie folder name, "
                          "with 'xml') or 'path' (an MJCF file, relative to this config)")
    if rel is not None:
        path = (config_file.parent / rel).resolve()
        where = model.where("path")
    else:
        root = ensure_menagerie_root()
        if root is None:
            raise AssetError(f"{model.where('menagerie')}: no Menagerie root (set MENAGERIE_ROOT "
                             "or provide ../shared/assets/menagerie)")
        path = root / menagerie / model.str("xml")
        where = model.where("xml")
    if not path.is_file():
        raise AssetError(f"{where}: arm model file {path} does not exist")
    return path


def _quat(sec: Section, key: str, default: list[float]) -> np.ndarray:
    quat = np.array(sec.floats(key, 4, default))
    if abs(np.linalg.norm(quat) - 1.0) > 1e-6:
        raise sec.error(key, f"expected a unit quaternion (w, x, y, z), got norm {np.linalg.norm(quat)}")
    return quat / np.linalg.norm(quat)


def load_arm_config(name_or_path: str | Path) -> ArmConfig:
    """Load an arm by name or TOML path and check it against its MuJoCo model.

    Unknown arm name → ConfigError listing the known arms; a missing key, a joint or site the
    model lacks, a home outside the joint limits → ConfigError naming the file and the key.
    """
    path = arm_config_path(name_or_path)
    if Path(name_or_path).suffix != ".toml" and not path.is_file():
        raise ConfigError(f"unknown arm {name_or_path!r}: no {path}; known arms: {arm_names()}")
    root = load_toml(path)
    root.reject_unknown({"model", "flange", "joints", "placement"})
    model = root.section("model")
    model.reject_unknown({"menagerie", "xml", "path"})
    model_path = _model_path(model, path)
    flange = root.section("flange")
    flange.reject_unknown({"site"})
    joints_sec = root.section("joints")
    joints_sec.reject_unknown({"names", "home_rad"})
    joints = tuple(joints_sec.strs("names"))
    if not joints or len(set(joints)) != len(joints):
        raise joints_sec.error("names", f"expected distinct joint names, got {list(joints)}")
    home = np.array(joints_sec.floats("home_rad", len(joints)))
    placement = root.section("placement")
    placement.reject_unknown({"base_pos", "base_quat_wxyz"})
    config = ArmConfig(
        name=path.parent.name if path.name == "arm.toml" else path.stem, file=path,
        model_path=model_path, flange_site=flange.str("site"), joints=joints, home_rad=home,
        base_pos_m=np.array(placement.floats("base_pos", 3)),
        base_quat_wxyz=_quat(placement, "base_quat_wxyz", [1.0, 0.0, 0.0, 0.0]))
    _check_against_model(config, flange, joints_sec)
    return config


def _check_against_model(config: ArmConfig, flange: Section, joints_sec: Section) -> None:
    """Names and the home configuration must exist in / fit the model (compiled once here)."""
    try:
        m = mujoco.MjModel.from_xml_path(str(config.model_path))
    except Exception as exc:
        raise AssetError(f"{config.model_path}: MuJoCo cannot load the arm model: {exc}") from None
    sites = {m.site(i).name for i in range(m.nsite)}
    if config.flange_site not in sites:
        raise flange.error("site", f"no site {config.flange_site!r} in {config.model_path.name} "
                           f"(sites: {sorted(sites)})")
    names = {m.joint(j).name: j for j in range(m.njnt)}
    for joint in config.joints:
        if joint not in names:
            raise joints_sec.error("names", f"no joint {joint!r} in {config.model_path.name} "
                                   f"(joints: {sorted(names)})")
    for joint, value in zip(config.joints, config.home_rad, strict=True):
        j = names[joint]
        lo, hi = m.jnt_range[j]
        if m.jnt_limited[j] and not lo <= value <= hi:
            raise joints_sec.error("home_rad", f"{joint} = {value} rad is outside its limits "
                                   f"[{lo}, {hi}] rad")
