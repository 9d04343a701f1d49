"""``bodex``: DexGraspBench's per-grasp files — what its evaluation reads, and what its format
task makes of BODex's output — and a reader that follows its logic.

Layout — DexGraspBench (GitHub JYChen18/DexGraspBench @ 1e7a5a6): its evaluation
(``src/task/evaluation.py``, ``src/task/eval_func/base.py`` and ``fc_mocap.py``,
``src/util/hand_util.py`` ``MjHO``) globs ``<grasp_dir>/**/*.npy`` and loads each with
``np.load(path, allow_pickle=True).item()``, a dict (its ``output/example_shadow`` files)::

    obj_path   str     the object folder (MeshProcess output: info/simplified.json, urdf/meshes)
    obj_scale  float   the mesh scale
    obj_pose   (7,)    the object's free joint: x y z qw qx qy qz in the world
    pregrasp_qpos, grasp_qpos, squeeze_qpos  (29,)
                       [0:3] position and [3:7] quaternion (w x y z) of the hand's floating
                       root, then the 22 finger joints in its MJCF's order
                       (assets/hand/shadow/right_hand.xml): FFJ4..FFJ1 MFJ4..MFJ1 RFJ4..RFJ1
                       LFJ5..LFJ1 THJ5..THJ1 (radians)

The palm body and that joint order are the hand's declaration, ``[formats.bodex]`` in
the Shadow Hand's ``configs/hands/<hand>/hand.toml`` (:class:`~augment.export.foreign.ForeignHand`); a hand
without one is refused.

Its Shadow asset is Menagerie's right hand without forearm and wrist (``assets/hand/README.md``):
the worldbody holds ``rh_palm`` at ``pos="0 0 0.034"``, and ``MjHO`` attaches it under a free
joint driven by a mocap weld, so ``qpos[:7]`` is the frame ``rh_palm`` hangs from —
``rh_palm`` − (0, 0, 0.034) in ``rh_palm``'s frame, where Menagerie's ``rh_wrist`` is with the
wrist at 0. Its format task (``src/task/convert_format.py``, ``BODex``) makes that shift from
BODex's raw ``robot_pose`` (BODex's URDF palm, ``example_grasp/plan_batch_env.py``) and moves the
thumb joints from first to last; the files here are in the converted form DGB evaluates. The
offset is computed from our model (the palm body's parent at zero joints,
:meth:`ForeignHand.parent_in_body`) and ``tests/test_export_bodex.py`` checks it against DGB's
(0, 0, 0.034). The wrist joints are dropped as :mod:`augment.export.foreign` explains.

Files: ``<out>/<object>/<i>.npy`` (i: the grasp's row in the exported table) and
``<out>/dexaug_export.json``, the manifest (layout, hand, joints, root, object frame, where
every grasp's stages came from). Each ``.npy`` also holds ``stages_made_by``,
``dexaug_object`` and ``dexaug_index``; DGB reads only its keys. The folder is written whole
(a temp folder, then renamed) and replaces only an earlier export (one with the manifest).

Stages: the dataset's ``pregrasp_pose`` / ``squeeze_pose`` where a row has both (what the
validator simulated: ``dataset:<stages_made_by>``), with ``grasp_qpos`` its ``touch_pose``
where ``dgb`` recorded one (the grasp stage it closed through) and ``hand_pose`` otherwise;
else made as the validator makes them
(:meth:`sim.validate.validator.Validator.stages` with a squeeze convention, default the
validate config's ``[dgb] squeeze_convention``: ``derived:<convention>``). BODex's own
convention is ``bodex`` (squeeze = 2·grasp − pregrasp, its ``plan_batch_env.py``). dexaug's
stages are joint vectors under a fixed palm: the three qpos share the root pose.

``obj_pose``: default the identity (DGB's example files); ``obj_scale`` 1 (dexaug's meshes are
metric); ``obj_path`` = ``<object_root>/<object>``, where DGB needs the object processed by
MeshProcess with its mesh frame kept. Units: metres, radians.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from augment.dataset import ObjectTable
from augment.export.foreign import ForeignHand, need_columns, same_joints, split_pose
from augment.grasp_table import grasp_stage_poses
from sim.errors import DexaugError
from sim.hand.model import Hand
from sim.io import replace_folder
from sim.transforms import pose_inv, pose_mul

__all__ = ["BODEX_LAYOUT", "IDENTITY_POSE", "MANIFEST", "BodexExport", "bodex_hand",
           "bodex_to_dexaug", "read_bodex", "table_stages", "write_bodex"]

BODEX_LAYOUT = "dexaug-dgb-graspdata-1"
MANIFEST = "dexaug_export.json"
IDENTITY_POSE: tuple[float, ...] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
_STAGES = ("pregrasp_qpos", "grasp_qpos", "squeeze_qpos")
_KEYS = ("obj_path", "obj_scale", "obj_pose", *_STAGES)


def bodex_hand(hand: Hand) -> ForeignHand:
    """``hand`` as DexGraspBench knows it (its ``[formats.bodex]``); refused (one line) when it
    declares none or cannot be."""
    return ForeignHand(hand, "bodex")


@dataclass(frozen=True)
class BodexExport:
    """What :func:`write_bodex` wrote: grasps, grasps with a dropped joint off 0, and how many
    grasps' stages came from where (``dataset:…`` / ``derived:…``)."""

    grasps: int
    dropped_moved: int
    stages: dict[str, int]


def table_stages(table: ObjectTable, hand: Hand, object_name: str, *,
                 convention: str | None = None,
                 validator: Callable[[], Any] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Pregrasp, grasp and squeeze joint vectors (N, nq each) of every grasp of ``table`` and
    where each row's came from (module docstring). ``validator()`` gives the
    :class:`Validator` for the object (default: one built for ``hand`` and ``object_name``),
    called only when a row needs it."""
    n, nq = len(table), hand.nq
    nan = np.full((n, nq), np.nan)
    pre = np.array(table.columns.get("pregrasp_pose", nan), dtype=float)
    sq = np.array(table.columns.get("squeeze_pose", nan), dtype=float)
    grasp = grasp_stage_poses(table)
    made = table.columns.get("stages_made_by")
    stored = np.isfinite(pre).all(axis=1) & np.isfinite(sq).all(axis=1)
    labels = [f"dataset:{(str(made[i]) if made is not None else '') or 'unknown'}"
              if stored[i] else "" for i in range(n)]
    if stored.all():
        return pre, grasp, sq, labels
    if validator is None:
        def validator() -> Any:
            from sim.validate.validator import Validator
            from sim.world.objects import load_object

            return Validator(hand, load_object(object_name))
    from sim.grasp import Grasp

    v = validator()
    for i in np.flatnonzero(~stored):
        palm = table["palm_pose"][i]
        own = {k: (a[i] if np.isfinite(a[i]).all() else None)
               for k, a in (("pregrasp", pre), ("squeeze", sq))}
        stages = v.stages(Grasp.from_arrays(palm[:3], palm[3:], table["hand_pose"][i], **own),
                          convention, sized_for="dgb")
        pre[i], grasp[i], sq[i] = stages.pregrasp, stages.grasp, stages.squeeze
        labels[i] = f"derived:{stages.made_by}"
    return pre, grasp, sq, labels


def write_bodex(out: Path | str, tables: Mapping[str, ObjectTable], hand: Hand, *,
                object_pose_world: Sequence[float] = IDENTITY_POSE, object_scale: float = 1.0,
                object_root: str = "assets/object", squeeze_convention: str | None = None,
                source: str = "dataset") -> BodexExport:
    """Write ``tables`` as DexGraspBench per-grasp files under the folder ``out`` (module
    docstring); ``squeeze_convention`` makes the stages of grasps the dataset has none for."""
    foreign = bodex_hand(hand)
    obj_p, obj_q = split_pose(np.asarray(object_pose_world, float))
    root_in_body = foreign.parent_in_body()
    files: dict[str, dict[str, Any]] = {}
    counts: Counter[str] = Counter()
    moved = 0
    for name, table in tables.items():
        where = f"{source}: {name}"
        need_columns(table, ("palm_pose", "hand_pose"), where, "bodex")
        same_joints(table, hand, where)
        if not len(table):
            continue
        q = np.asarray(table["hand_pose"], dtype=float)
        pre, grasp, sq, labels = table_stages(table, hand, name, convention=squeeze_convention)
        body = foreign.to_body(table["palm_pose"], q)          # rh_palm in the object frame
        root_p, root_q = pose_mul(obj_p, obj_q, *pose_mul(*body, *root_in_body))
        base = np.c_[root_p, root_q]
        moved += int(foreign.dropped_moved(q).sum())
        for i in range(len(table)):
            files[f"{name}/{i}.npy"] = {
                "obj_path": f"{object_root.rstrip('/')}/{name}", "obj_scale": float(object_scale),
                "obj_pose": np.r_[obj_p, obj_q],
                **{key: np.r_[base[i], stage[i, foreign.index]]
                   for key, stage in zip(_STAGES, (pre, grasp, sq), strict=True)},
                "stages_made_by": labels[i], "dexaug_object": name, "dexaug_index": i}
        counts.update(labels)
    manifest = {
        "format": BODEX_LAYOUT, "hand": hand.name, "source": source,
        "reader": "DexGraspBench: np.load(path, allow_pickle=True).item() of <dir>/**/*.npy",
        "qpos": "[0:3] root position (m), [3:7] root quaternion w x y z, "
                f"[7:{7 + len(foreign.joints)}] joints (rad)",
        "root": f"the frame {foreign.body} hangs from: {foreign.body} at root_to_palm_body",
        "root_to_palm_body": [float(x) + 0.0 for x in np.r_[pose_inv(*root_in_body)]],
        "joint_names": list(foreign.joints), "dropped_joints": list(foreign.dropped),
        "grasps_with_dropped_joints_moved": moved,
        "object_frame": "the object's mesh origin (dexaug's YCB textured.obj)",
        "obj_pose": list(map(float, np.r_[obj_p, obj_q])), "obj_scale": float(object_scale),
        "grasps": {name: len(t) for name, t in tables.items()}, "stages_made_by": dict(counts)}
    _write_folder(Path(out), files, manifest)
    return BodexExport(len(files), moved, dict(counts))


def _write_folder(out: Path, files: Mapping[str, dict[str, Any]], manifest: dict) -> None:
    """Write the files into a temp folder beside ``out``, then put it in ``out``'s place."""
    def fill(tmp: Path) -> None:
        for rel, data in files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            np.save(tmp / rel, np.array(data, dtype=object), allow_pickle=True)
        (tmp / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")

    replace_folder(out, fill, marker=MANIFEST, what="bodex export")


def read_bodex(out: Path | str, hand: Hand | None = None) -> list[dict[str, Any]]:
    """Every grasp file under ``out`` the way DexGraspBench reads it (``**/*.npy``, sorted,
    ``np.load(…, allow_pickle=True).item()``), with ``"path"`` added; a file without its keys
    or with wrong shapes is refused (one line naming it). The stages are the root's 7 numbers
    and the joints of ``hand``'s ``[formats.bodex]`` (without ``hand``: the joints of the
    manifest beside the files, else as many as the first file has)."""
    out = Path(out)
    joints = (len(bodex_hand(hand).joints) if hand is not None else _manifest_joints(out))
    records = []
    for path in sorted(out.glob("**/*.npy")):
        try:
            d = np.load(path, allow_pickle=True).item()
        except (OSError, ValueError) as exc:
            raise DexaugError(f"{path}: not a DexGraspBench grasp file ({exc})") from None
        missing = [k for k in _KEYS if k not in d] if isinstance(d, dict) else list(_KEYS)
        if missing:
            raise DexaugError(f"{path}: no {', '.join(missing)}")
        if joints is None:
            joints = max(0, len(np.ravel(d[_STAGES[0]])) - 7)
        for key, shape in (("obj_pose", (7,)), *((k, (7 + joints,)) for k in _STAGES)):
            if np.shape(d[key]) != shape:
                raise DexaugError(f"{path}: {key} has shape {np.shape(d[key])}, expected {shape}")
        records.append({**d, "path": path})
    return records


def _manifest_joints(out: Path) -> int | None:
    """How many joints the export's manifest lists (None: no readable manifest)."""
    try:
        names = json.loads((out / MANIFEST).read_text())["joint_names"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return len(names) if isinstance(names, list) else None


def bodex_to_dexaug(records: Sequence[Mapping[str, Any]], hand: Hand) -> dict[str, np.ndarray]:
    """Grasp files (:func:`read_bodex`) back in dexaug's terms, one row per record:
    ``palm_pose`` (N,7) frame_palm in the object frame and ``hand_pose`` / ``pregrasp_pose`` /
    ``squeeze_pose`` (N,nq) our joint vectors (dropped joints at 0)."""
    foreign = bodex_hand(hand)
    if not len(records):
        return {"palm_pose": np.zeros((0, 7)),
                **{c: np.zeros((0, hand.nq)) for c in ("hand_pose", "pregrasp_pose", "squeeze_pose")}}
    body_in_root = pose_inv(*foreign.parent_in_body())
    obj_inv = pose_inv(*split_pose(np.array([r["obj_pose"] for r in records], dtype=float)))
    out: dict[str, np.ndarray] = {}
    for key, col in zip(_STAGES, ("pregrasp_pose", "hand_pose", "squeeze_pose"), strict=True):
        qpos = np.array([r[key] for r in records], dtype=float)
        body = pose_mul(*obj_inv, *pose_mul(*split_pose(qpos[:, :7]), *body_in_root))
        palm, out[col] = foreign.from_body(np.c_[body[0], body[1]], qpos[:, 7:])
        if key == "grasp_qpos":
            out["palm_pose"] = palm
    return out
