"""``dexgraspbench``: DexGraspBench's reference JSONL, one JSON object per grasp.

The layout of the benchmark reference this project is measured against
(``../shared/reference/dexgraspbench/grasps.jsonl``, its README): ``object``, ``index``,
``object_mass_kg_real``, ``object_pose_world`` and ``<palm body>_pose_world``
(``[x, y, z, qw, qx, qy, qz]``; the palm *body* of the hand config, ``rh_palm`` for the Shadow
Hand, not frame_palm), ``q_grasp``, ``q_pregrasp``, ``q_squeeze`` (radians by joint name), plus
``dexaug`` with our verdict (``passed``, ``failure``, ``stages_made_by``). The object frame is the
mesh origin, placed at ``object_pose_world`` (default: the reference's, 0.3 m above the
origin). A grasp the validator never simulated has no pregrasp or squeeze: those keys are
``null``. ``q_grasp`` is the grasp stage the benchmark closes through: the dataset's
``touch_pose`` where ``dgb`` recorded one, else ``hand_pose``. Compatibility is measured, not
claimed: ``tests/test_export.py`` reads the shared reference file with the reader the ``dgb``
agreement uses, writes it back through this module and gets every pose and joint angle of the
300 lines back (1e-9), and reads an export of a generated dataset back into the same grasps.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from augment.dataset import ObjectTable
from augment.export.foreign import need_columns, same_joints
from augment.grasp_table import grasp_stage_poses
from sim.hand.model import Hand
from sim.io import write_bytes_atomic
from sim.transforms import pose_inv, pose_mul

__all__ = ["REFERENCE_OBJECT_POSE", "dexgraspbench_rows", "write_dexgraspbench"]

#: Where the reference file puts every object: 0.3 m above the world origin, unrotated.
REFERENCE_OBJECT_POSE: tuple[float, ...] = (0.0, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0)


def _named(hand: Hand, q: np.ndarray) -> dict[str, float] | None:
    if not np.isfinite(q).all():
        return None
    return {n: float(v) for n, v in zip(hand.joint_names, q, strict=True)}


def _text(column: np.ndarray | None, i: int) -> str:
    if column is None:
        return ""
    v = column[i]
    return v.decode() if isinstance(v, bytes) else str(v)


def dexgraspbench_rows(table: ObjectTable, hand: Hand, object_name: str, *,
                       object_pose_world: Sequence[float] = REFERENCE_OBJECT_POSE,
                       object_mass_kg: float | None = None,
                       source: str = "dataset") -> list[dict[str, Any]]:
    """One reference-layout row per grasp of ``table`` (module docstring)."""
    where = f"{source}: {object_name}"
    need_columns(table, ("palm_pose", "hand_pose"), where, "dexgraspbench")
    same_joints(table, hand, where)
    pose = np.asarray(object_pose_world, float)
    obj_p, obj_q = pose[:3], pose[3:] / np.linalg.norm(pose[3:])
    cfg = hand.config.palm
    body_from_palm = pose_inv(cfg.pos, cfg.quat_wxyz)
    cols = table.columns
    n = len(table)
    nan = np.full((n, len(hand.joint_names)), np.nan)
    pre, sq = cols.get("pregrasp_pose", nan), cols.get("squeeze_pose", nan)
    grasp = grasp_stage_poses(table)
    passed = cols.get("passed")
    rows = []
    for i in range(n):
        palm = cols["palm_pose"][i]
        palm_world = pose_mul(obj_p, obj_q, palm[:3], palm[3:])
        body_p, body_q = pose_mul(*palm_world, *body_from_palm)
        rows.append({
            "object": object_name, "index": i, "object_mass_kg_real": object_mass_kg,
            "object_pose_world": [*map(float, obj_p), *map(float, obj_q)],
            f"{cfg.body}_pose_world": [*map(float, body_p), *map(float, body_q)],
            "q_grasp": _named(hand, grasp[i]),
            "q_pregrasp": _named(hand, pre[i]), "q_squeeze": _named(hand, sq[i]),
            "dexaug": {"passed": None if passed is None else bool(passed[i]),
                       "failure": _text(cols.get("failure"), i),
                       "stages_made_by": _text(cols.get("stages_made_by"), i)}})
    return rows


def write_dexgraspbench(path: Path | str, tables: Mapping[str, ObjectTable], hand: Hand, *,
                        object_pose_world: Sequence[float] = REFERENCE_OBJECT_POSE,
                        masses_kg: Mapping[str, float] | None = None,
                        source: str = "dataset") -> int:
    """Write every table's rows (object by object) as JSON lines to ``path``; the row count."""
    lines = []
    for name, table in tables.items():
        mass = None if masses_kg is None else masses_kg.get(name)
        lines += [json.dumps(r) for r in dexgraspbench_rows(
            table, hand, name, object_pose_world=object_pose_world, object_mass_kg=mass,
            source=source)]
    write_bytes_atomic(path, ("\n".join(lines) + "\n" if lines else "").encode())
    return len(lines)
