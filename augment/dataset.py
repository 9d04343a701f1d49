"""Grasp datasets in HDF5 (DESIGN §7).

Layout (one group per object, with the reference implementation's column names ``palm_pose`` /
``hand_pose`` / ``gws`` — not its frames or joint set — plus dexaug's own):

``/<object>/``
    ``palm_pose`` (N,7) float64: frame_palm in the object frame, metres; attribute
    ``order = "x y z qw qx qy qz"``. ``hand_pose`` (N,J) radians, attribute ``joint_names``.
    ``gws`` (N) Q1 ε; ``volume`` (N); ``grip_ratio`` (N) the least total normal force that
    holds the validation's loads over the load (:mod:`sim.metrics.holding`; inf: cannot hold,
    NaN: not computed); ``actuator_effort`` (N) the least worst actuator effort, as a fraction of
    the force limits, that holds them at the placed grasp (:mod:`sim.validate.effort`; > 1: the
    actuators cannot); ``fingers_used`` (N,F) bool, attribute ``finger_names``;
    ``contact_points`` / ``contact_normals`` (M,3) all grasps' contacts flat (object frame,
    metres; normals outward) with ``contact_finger`` (M) int8 (index into ``finger_names``) and
    ``contact_offsets`` (N+1) int64: grasp i owns rows ``offsets[i]:offsets[i+1]``;
    validation columns ``passed`` (N) bool, ``failure`` (N) strings ("" when passed or not
    validated), ``displacement_m``, ``rotation_rad``, ``penetration_m`` (the hand's deepest
    into the object or into itself), ``sim_epsilon`` (N) (NaN when not validated; −1 when the
    simulated contacts after closing are not in force closure, the GWS convention of
    :mod:`sim.metrics.gws`); ``pregrasp_pose`` /
    ``squeeze_pose`` (N,J) radians: the joint vectors the validator closed from and to (NaN
    when not simulated), ``touch_pose`` (N,J) radians: the grasp stage ``dgb`` closed through
    between them (NaN for other protocols; :mod:`sim.validate.stages`; a file written before it
    existed reads without it), ``stages_made_by`` (N) strings: how they were made ("dexaug" contact
    targets, "bodex", "dgb-rule", "given"),
    ``closing`` (N) strings: "free" or "pinned" (the object held while the fingers closed);
    ``stopped_early`` (N) strings: where a protocol stopped once the verdict was fixed (e.g.
    "after push +x: slipped", six-dir; :mod:`sim.validate.six_dir`), "" when it ran to its end:
    its ``displacement_m`` / ``rotation_rad`` are then NaN, not a smaller worst drift (a file
    written before it existed reads without it);
    ``demo_id`` (N) strings.
    Attributes (provenance): the writer's (``hand``, ``seed``, options, configs) and, stamped
    by :func:`save` where missing, ``versions``, ``code_version``, ``asset_sha256`` (JSON,
    :mod:`sim.provenance`; :func:`asset_changes` checks the files). A table keeps its first
    rows' attributes; grasps appended under others add them to ``appended``.
``/<object>/rejected/``: the same columns for grasps that failed validation (``failure`` says
    why), so the main table holds only usable grasps when the writer splits them.
The file's own attributes ``versions`` and ``code_version`` name its last writer.

Files are written whole through :func:`sim.io.atomic_path` (temp file + rename): a failed or
interrupted write leaves the previous file untouched, and the temp file of a writer that was
killed is removed by the next write of the same file (:func:`sim.io.sweep_stale_temps`).
:func:`append` reads the existing file, concatenates and rewrites atomically (datasets are
small: thousands of grasps per object); it refuses grasps the file already holds (a repeated
run) unless told otherwise. A file that cannot be read (missing, cut short, not this layout)
raises :class:`DatasetError` naming it, never an h5py traceback.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from augment.grasp_table import (
    STR_COLUMNS,
    ObjectTable,
    brief,
    concat_tables,
    grasp_count,
    select_rows,
    with_rejected,
)
from sim import provenance
from sim.errors import DexaugError
from sim.io import atomic_path
from sim.provenance import AssetChange, decoded, plain
from sim.versions import code_version, describe_code_version, package_versions

__all__ = ["COLUMNS", "Dataset", "DatasetError", "DuplicateGraspsError",
           "ObjectTable", "append", "asset_changes", "existing_rows", "from_fsg", "load", "save",
           "with_rejected"]

log = logging.getLogger(__name__)

PALM_POSE_ORDER = "x y z qw qx qy qz"
#: Per-grasp columns (first axis N) and their dtypes; contacts are stored flat with offsets.
COLUMNS: dict[str, Any] = {
    "palm_pose": np.float64, "hand_pose": np.float64, "gws": np.float64, "volume": np.float64,
    "fingers_used": np.bool_, "passed": np.bool_, "displacement_m": np.float64,
    "rotation_rad": np.float64, "penetration_m": np.float64, "sim_epsilon": np.float64,
    "pregrasp_pose": np.float64, "squeeze_pose": np.float64, "touch_pose": np.float64,
}
#: text columns a validation result fills: (column, ValidationResult field); None is ""
_TEXT_FIELDS = (("stages_made_by", "squeeze_convention"), ("closing", "closing"),
                ("stopped_early", "stopped_early"))
_STR = h5py.string_dtype()
_REPR_OBJECTS = 12   # objects a printed Dataset lists, one line each


class DatasetError(DexaugError):
    """A grasp dataset cannot be read: missing, not HDF5, cut short, or not this layout."""


class DuplicateGraspsError(DexaugError):
    """:func:`append` was given grasps the file already holds (a repeated run)."""


class Dataset(dict[str, ObjectTable]):
    """What :func:`load` returns: object name → table (a dict, as before), with the file's own
    attributes (``attrs``: its last writer's versions and code version) and a repr of a few
    lines, so printing a dataset of thousands of grasps says what it holds, not its arrays."""

    def __init__(self, tables: Mapping[str, ObjectTable] | None = None,
                 attrs: Mapping[str, Any] | None = None, path: Path | None = None) -> None:
        super().__init__(tables or {})
        self.attrs: dict[str, Any] = dict(attrs or {})
        self.path = path

    def __repr__(self) -> str:
        made = describe_code_version(decoded(self.attrs.get("code_version")))
        where = f"{self.path}: " if self.path else ""
        lines = [f"Dataset({where}{len(self)} object{'s' * (len(self) != 1)}, "
                 f"{sum(grasp_count(t) for t in self.values())} grasps; written by {made})"]
        lines += [f"  {name}: {brief(t)}" for name, t in list(self.items())[:_REPR_OBJECTS]]
        if len(self) > _REPR_OBJECTS:
            lines.append(f"  … and {len(self) - _REPR_OBJECTS} more objects")
        return "\n".join(lines)


def from_fsg(grasps: Sequence[Any], joint_names: Sequence[str], finger_names: Sequence[str],
             validation: Sequence[Any] | None = None, demo_id: str = "",
             attrs: Mapping[str, Any] | None = None, split_rejected: bool = True) -> ObjectTable:
    """Build a table from :class:`augment.fsg.result.FsgGrasp` objects and, optionally, their
    :class:`sim.validate.result.ValidationResult` (same order). With ``split_rejected``, grasps that
    failed validation go to the ``rejected`` side table."""
    n = len(grasps)
    if validation is not None and len(validation) != n:
        raise ValueError(f"{n} grasps but {len(validation)} validation results")
    fingers = list(finger_names)
    nan = np.full(n, np.nan)
    cols: dict[str, np.ndarray] = {
        "palm_pose": np.array([np.r_[g.grasp.palm_pos, g.grasp.palm_quat_wxyz] for g in grasps],
                              dtype=float).reshape(n, 7),
        "hand_pose": np.array([g.grasp.joints for g in grasps], dtype=float).reshape(
            n, len(joint_names)),
        "gws": np.array([g.epsilon for g in grasps], dtype=float),
        "grip_ratio": np.array([getattr(g, "grip_ratio", np.nan) for g in grasps], dtype=float),
        "actuator_effort": np.array([getattr(g, "actuator_effort", np.nan) for g in grasps],
                                    dtype=float),
        "volume": np.array([g.volume for g in grasps], dtype=float),
        "fingers_used": np.array([[f in g.fingers for f in fingers] for g in grasps],
                                 dtype=bool).reshape(n, len(fingers)),
        "passed": np.zeros(n, bool), "failure": np.array([""] * n, dtype=object),
        "displacement_m": nan.copy(), "rotation_rad": nan.copy(), "penetration_m": nan.copy(),
        "sim_epsilon": nan.copy(), "demo_id": np.array([demo_id] * n, dtype=object),
        "pregrasp_pose": np.full((n, len(joint_names)), np.nan),
        "squeeze_pose": np.full((n, len(joint_names)), np.nan),
        "touch_pose": np.full((n, len(joint_names)), np.nan),
        "stages_made_by": np.array([""] * n, dtype=object),
        "closing": np.array([""] * n, dtype=object),
        "stopped_early": np.array([""] * n, dtype=object),
    }
    pts, nrm, fin, off = [], [], [], [0]
    for g in grasps:
        pts.append(np.asarray(g.contact_points, float).reshape(-1, 3))
        nrm.append(np.asarray(g.contact_normals, float).reshape(-1, 3))
        fin.append(np.array([fingers.index(g.fingers[k]) for k in g.contact_finger], np.int8))
        off.append(off[-1] + len(pts[-1]))
    cols["contact_points"] = np.concatenate(pts) if pts else np.zeros((0, 3))
    cols["contact_normals"] = np.concatenate(nrm) if nrm else np.zeros((0, 3))
    cols["contact_finger"] = np.concatenate(fin) if fin else np.zeros(0, np.int8)
    cols["contact_offsets"] = np.array(off, dtype=np.int64)
    if validation is not None:
        for i, r in enumerate(validation):
            cols["passed"][i] = bool(r.passed)
            cols["failure"][i] = "" if r.failure is None else str(r.failure)
            cols["displacement_m"][i] = r.displacement_m
            cols["rotation_rad"][i] = r.rotation_rad
            cols["penetration_m"][i] = r.penetration_m
            cols["sim_epsilon"][i] = r.epsilon
            if r.pregrasp is not None:
                cols["pregrasp_pose"][i], cols["squeeze_pose"][i] = r.pregrasp, r.squeeze
            if r.touch is not None:
                cols["touch_pose"][i] = r.touch
            for column, field in _TEXT_FIELDS:
                cols[column][i] = getattr(r, field) or ""
    table = ObjectTable(cols, tuple(joint_names), tuple(fingers), dict(attrs or {}))
    if validation is not None and split_rejected:
        keep = cols["passed"]
        good, bad = select_rows(table, keep), select_rows(table, ~keep)
        good.rejected = bad
        return good
    return table


def _write_group(g: h5py.Group, t: ObjectTable) -> None:
    for k, v in t.columns.items():
        if k in STR_COLUMNS:
            g.create_dataset(k, data=np.array([str(x) for x in v], dtype=object), dtype=_STR)
        else:
            g.create_dataset(k, data=v)
    g["palm_pose"].attrs["order"] = PALM_POSE_ORDER
    g["hand_pose"].attrs["joint_names"] = list(t.joint_names)
    g["hand_pose"].attrs["units"] = "rad"
    g["fingers_used"].attrs["finger_names"] = list(t.finger_names)
    g.attrs["joint_names"] = list(t.joint_names)
    g.attrs["finger_names"] = list(t.finger_names)
    for k, v in t.attrs.items():
        g.attrs[k] = _stored(v)
    if t.rejected is not None:
        _write_group(g.create_group("rejected"), t.rejected)


def _read_group(g: h5py.Group) -> ObjectTable:
    cols: dict[str, np.ndarray] = {}
    for k, ds in g.items():
        if isinstance(ds, h5py.Dataset):
            cols[k] = (np.array(ds.asstr()[()], dtype=object) if k in STR_COLUMNS
                       else ds[()])
    attrs = {k: plain(v) for k, v in g.attrs.items() if k not in ("joint_names", "finger_names")}
    rej = _read_group(g["rejected"]) if "rejected" in g else None
    return ObjectTable(cols, tuple(str(x) for x in g.attrs["joint_names"]),
                       tuple(str(x) for x in g.attrs["finger_names"]), attrs, rej)


def _stored(v: Any) -> Any:
    """An attribute value as HDF5 stores it: scalars as they are, anything else as JSON."""
    return v if isinstance(v, (str, int, float, bool, np.number)) else json.dumps(v)


def _stamped(name: str, t: ObjectTable) -> ObjectTable:
    """``t`` (object ``name``) with the provenance it lacks (:func:`sim.provenance.stamped`)."""
    return dataclasses.replace(t, attrs=provenance.stamped(t.attrs, name))


def save(path: Path | str, tables: Mapping[str, ObjectTable],
         file_attrs: Mapping[str, Any] | None = None) -> None:
    """Write ``tables`` (object name → table) to ``path`` atomically (replacing it). The file
    records the packages and code that wrote it (``versions``, ``code_version``); each table
    keeps the provenance it carries and gets this process's for what it lacks (module
    docstring), so a table made elsewhere keeps what it was made with."""
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = "dexaug-grasps-1"
        f.attrs["versions"] = json.dumps(package_versions())
        f.attrs["code_version"] = json.dumps(code_version())
        for k, v in (file_attrs or {}).items():
            f.attrs[k] = _stored(v)
        for name, t in tables.items():
            _write_group(f.create_group(name), _stamped(name, t))
    log.info("wrote %s: %s", path, ", ".join(f"{k} {len(t)}" for k, t in tables.items()))


def _unreadable(path: Path | str, exc: Exception) -> DatasetError:
    return DatasetError(f"{path}: not a readable grasp dataset: {exc}")


def load(path: Path | str) -> Dataset:
    """Read a dataset: object name → :class:`ObjectTable` (NumPy arrays), a :class:`Dataset`.
    Raises :class:`DatasetError` when the file cannot be read as one."""
    try:
        with h5py.File(path, "r") as f:
            tables = {name: _read_group(g) for name, g in f.items() if isinstance(g, h5py.Group)}
            attrs = {k: plain(v) for k, v in f.attrs.items()}
    except (OSError, KeyError) as exc:  # h5py: unreadable file; KeyError: a missing column/attr
        raise _unreadable(path, exc) from None
    return Dataset(tables, attrs, Path(path))


def _group_rows(g: h5py.Group) -> int:
    return int(g["gws"].shape[0]) + (_group_rows(g["rejected"]) if "rejected" in g else 0)


def existing_rows(path: Path | str) -> int:
    """How many grasps (kept and rejected) ``path`` holds; 0 when there is no such file. For a
    writer that must not add to an earlier run's file unasked (``generate --out`` without
    ``--append``); reads only the shapes. Raises :class:`DatasetError` when ``path`` exists but
    is not a readable dataset."""
    if not Path(path).exists():
        return 0
    try:
        with h5py.File(path, "r") as f:
            return sum(_group_rows(g) for g in f.values() if isinstance(g, h5py.Group))
    except (OSError, KeyError) as exc:
        raise _unreadable(path, exc) from None


def _row_keys(t: ObjectTable | None) -> list[bytes]:
    """Per grasp, kept then rejected, what makes two rows the same grasp: palm pose, joints
    and demo, exactly."""
    if t is None:
        return []
    palm, joints = np.ascontiguousarray(t["palm_pose"]), np.ascontiguousarray(t["hand_pose"])
    return [palm[i].tobytes() + joints[i].tobytes() + str(t["demo_id"][i]).encode()
            for i in range(len(t))] + _row_keys(t.rejected)


def _refuse_duplicates(path: Path, old: Mapping[str, ObjectTable],
                       new: Mapping[str, ObjectTable]) -> None:
    """Raise :class:`DuplicateGraspsError` when ``new`` holds grasps ``old`` already has."""
    seen = {name: set(_row_keys(old.get(name))) for name in new}
    dup = {name: n for name, t in new.items() if (n := sum(k in seen[name] for k in _row_keys(t)))}
    if dup:
        total = sum(grasp_count(t) for t in new.values())
        raise DuplicateGraspsError(
            f"{path}: {sum(dup.values())} of the {total} grasps to append are exact duplicates "
            f"of grasps already in the file ({', '.join(f'{k}: {n}' for k, n in dup.items())};"
            " same palm pose, joints and demo: a repeated run?); nothing written "
            "(allow_duplicates=True appends them anyway)")


def append(path: Path | str, tables: Mapping[str, ObjectTable], *,
           allow_duplicates: bool = False) -> None:
    """Add grasps to ``path`` (created when missing): read, concatenate per object, rewrite
    atomically. Grasps the file already holds (the same palm pose, joints and demo: a repeated
    run) are refused with :class:`DuplicateGraspsError` and nothing is written, unless
    ``allow_duplicates`` (then they are added again). Each table keeps the provenance of its
    first rows; appended grasps made otherwise are recorded in its ``appended`` attribute."""
    path = Path(path)
    existing = load(path) if path.is_file() else Dataset()
    old = {name: dataclasses.replace(t, attrs=provenance.as_recorded(t.attrs))
           for name, t in existing.items()}
    new = {name: _stamped(name, t) for name, t in tables.items()}
    if not allow_duplicates:
        _refuse_duplicates(path, old, new)
    for name, t in new.items():   # old rows first, with their attributes (module docstring)
        old[name] = t if name not in old else dataclasses.replace(
            concat_tables(old[name], t),
            attrs=provenance.merged_attrs(old[name].attrs, t.attrs, grasp_count(t)))
    file_attrs = {k: v for k, v in existing.attrs.items()
                  if k not in ("format", "versions", "code_version")}
    save(path, old, file_attrs)


def asset_changes(path: Path | str) -> list[AssetChange]:
    """The asset files (hand model, object) that differ here from those that made ``path``'s
    grasps, or are missing here, per table (its own and its appended runs'); a table written
    before asset hashes were recorded gives one "not recorded". Empty: the same assets."""
    return [c for name, t in load(path).items() for c in provenance.recorded_changes(t.attrs, name)]
