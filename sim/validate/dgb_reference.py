"""Reading DexGraspBench's reference verdicts (``../shared/reference/dexgraspbench/grasps.jsonl``).

Each line is a Shadow Hand grasp of a YCB object with the verdicts DexGraspBench's own code gave
it under four ways of making its pregrasp/squeeze and object mass (the file's README). This turns
a line into a :class:`sim.grasp.Grasp` of our hand (frame_palm in the object frame, the joint
vector in model order, the file's pregrasp and squeeze attached) so the ``dgb`` protocol can be
compared with the benchmark grasp by grasp. Units: metres, radians.
"""

from __future__ import annotations

import builtins
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.errors import GraspInputError
from sim.grasp import Grasp
from sim.hand.config import hand_names
from sim.hand.model import Hand
from sim.transforms import pose_inv, pose_mul

__all__ = ["VARIANTS", "ReferenceGrasp", "cohen_kappa", "load_reference", "reference_hand"]

#: the file's verdict variants → (our squeeze convention, object mass: "dgb" 0.1 kg or "real")
VARIANTS = {"dexaug_mass0.1": ("dexaug", "dgb"), "bodex_mass0.1": ("bodex", "dgb"),
            "rule_mass0.1": ("dgb-rule", "dgb"), "dexaug_massreal": ("dexaug", "real")}


@dataclass(frozen=True)
class ReferenceGrasp:
    """One reference line: object id, line index, the grasp and the benchmark's verdicts
    (variant → {"success", "delta_pos_m", "delta_angle_deg", ...})."""

    object: str
    index: int
    grasp: Grasp
    verdicts: dict[str, dict[str, builtins.object]]  # the field `object` shadows the builtin here


def _pose(row: dict, key: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    value = np.asarray(row.get(key, ()), dtype=float)
    if value.shape != (7,):
        raise GraspInputError(f"{where}: {key}: expected [x, y, z, qw, qx, qy, qz], got {row.get(key)!r}")
    return value[:3], value[3:] / np.linalg.norm(value[3:])


def _joints(hand: Hand, row: dict, key: str, where: str) -> np.ndarray:
    named = row.get(key)
    if not isinstance(named, dict) or set(named) != set(hand.joint_names):
        raise GraspInputError(f"{where}: {key}: expected angles for the joints of hand {hand.name!r} "
                              f"({len(hand.joint_names)} names)")
    return np.array([float(named[n]) for n in hand.joint_names])


def reference_hand(path: Path | str) -> Hand:
    """The hand of ours the file's grasps are for: the one whose joint names are the first
    line's ``q_grasp`` keys and whose palm body is the file's ``<body>_pose_world``."""
    path = Path(path)
    try:
        row = json.loads(path.read_text().splitlines()[0])
    except (OSError, IndexError, json.JSONDecodeError) as exc:
        raise GraspInputError(f"{path}: cannot read the first grasp: {exc}") from None
    joints = set(row.get("q_grasp", {}))
    for name in hand_names():
        hand = Hand.load(name)
        if set(hand.joint_names) == joints and f"{hand.config.palm.body}_pose_world" in row:
            return hand
    raise GraspInputError(f"{path}: no hand in configs/hands has the joints {sorted(joints)[:4]}…")


def load_reference(path: Path | str, hand: Hand) -> list[ReferenceGrasp]:
    """The grasps of a reference JSONL file for ``hand`` (the file's ``<body>_pose_world`` is
    the pose of the hand config's palm body; :func:`reference_hand` finds the hand)."""
    path = Path(path)
    cfg = hand.config.palm
    out = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        where = f"{path}:{n}"
        try:
            row = json.loads(line)
        except json.JSONDecodeError as exc:
            raise GraspInputError(f"{where}: not a JSON object: {exc}") from None
        obj_pos, obj_quat = _pose(row, "object_pose_world", where)
        body_pos, body_quat = _pose(row, f"{cfg.body}_pose_world", where)
        palm_world = pose_mul(body_pos, body_quat, cfg.pos, cfg.quat_wxyz)
        palm_obj = pose_mul(*pose_inv(obj_pos, obj_quat), *palm_world)
        grasp = Grasp.from_arrays(*palm_obj, _joints(hand, row, "q_grasp", where),
                                  pregrasp=_joints(hand, row, "q_pregrasp", where),
                                  squeeze=_joints(hand, row, "q_squeeze", where))
        out.append(ReferenceGrasp(str(row["object"]), int(row.get("index", n - 1)), grasp,
                                  dict(row.get("dgb", {}))))
    return out


def cohen_kappa(a: np.ndarray, b: np.ndarray) -> float:
    """Cohen's κ of two boolean verdict vectors: agreement beyond chance, (p_o − p_e)/(1 − p_e);
    1.0 when both are constant and equal (no disagreement to explain)."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    p_o = float(np.mean(a == b))
    p_e = float(a.mean() * b.mean() + (1 - a.mean()) * (1 - b.mean()))
    return 1.0 if p_e >= 1.0 else (p_o - p_e) / (1.0 - p_e)
