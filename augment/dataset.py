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
    validated), ``displacement_m``, ``rotation_rad``, ``penetration_m``, ``sim_epsilon`` (N)
    (NaN when not validated; −1 when the simulated contacts after closing are not in force
    closure, the GWS convention of :mod:`sim.metrics.gws`); ``pregrasp_pose`` /
    ``squeeze_pose`` (N,J) radians: the joint vectors the validator closed from and to (NaN
    when not simulated), ``stages_made_by`` (N) strings: how they were made ("dexaug" contact
    targets, "bodex", "dgb-rule", "given"),
    ``closing`` (N) strings: "free" or "pinned" (the object held while the fingers closed);
    ``demo_id`` (N) strings.
    Attributes (provenance): ``hand``, ``config_hash``, ``seed``, ``versions`` (JSON).
``/<object>/rejected/``: the same columns for grasps that failed validation (``failure`` says
    why), so the main table holds only usable grasps when the writer splits them.

Files are written whole through :func:`sim.io.atomic_path` (temp file + rename): a failed or
interrupted write leaves the previous file untouched, and the temp file of a writer that was
killed is removed by the next write of the same file (:func:`sim.io.sweep_stale_temps`).
:func:`append` reads the existing file, concatenates and rewrites atomically (datasets are
small: thousands of grasps per object). A file that cannot be read (missing, cut short, not
this layout) raises :class:`DatasetError` naming it, never an h5py traceback.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from sim.errors import DexaugError
from sim.io import atomic_path
from sim.versions import package_versions

__all__ = ["COLUMNS", "DatasetError", "ObjectTable", "append", "from_fsg", "load", "save",
           "with_rejected"]

log = logging.getLogger(__name__)

PALM_POSE_ORDER = "x y z qw qx qy qz"
#: Per-grasp columns (first axis N) and their dtypes; contacts are stored flat with offsets.
COLUMNS: dict[str, Any] = {
    "palm_pose": np.float64, "hand_pose": np.float64, "gws": np.float64, "volume": np.float64,
    "fingers_used": np.bool_, "passed": np.bool_, "displacement_m": np.float64,
    "rotation_rad": np.float64, "penetration_m": np.float64, "sim_epsilon": np.float64,
    "pregrasp_pose": np.float64, "squeeze_pose": np.float64,
}
_STR_COLUMNS = ("failure", "demo_id", "stages_made_by", "closing")
_STR = h5py.string_dtype()


class DatasetError(DexaugError):
    """A grasp dataset cannot be read: missing, not HDF5, cut short, or not this layout."""


@dataclass
class ObjectTable:
    """One object's grasps as NumPy arrays (see the module docstring for the columns).

    ``contacts(i)`` gives grasp i's ``(points, normals, finger)``; ``rejected`` holds the side
    table (or None); ``attrs`` the provenance attributes."""

    columns: dict[str, np.ndarray]
    joint_names: tuple[str, ...]
    finger_names: tuple[str, ...]
    attrs: dict[str, Any] = field(default_factory=dict)
    rejected: ObjectTable | None = None

    def __len__(self) -> int:
        return len(self.columns["gws"])

    def __getitem__(self, key: str) -> np.ndarray:
        return self.columns[key]

    def __repr__(self) -> str:
        """A summary, not the arrays: a printed table of thousands of grasps stays one line."""
        passed = int(np.count_nonzero(self.columns.get("passed", np.zeros(0, bool))))
        rejected = 0 if self.rejected is None else len(self.rejected)
        return (f"ObjectTable({len(self)} grasps, {passed} passed, {rejected} rejected; "
                f"{len(self.joint_names)} joints, fingers {list(self.finger_names)}; "
                f"columns {sorted(self.columns)}; attrs {sorted(self.attrs)})")

    def contacts(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        o = self.columns["contact_offsets"]
        s = slice(int(o[i]), int(o[i + 1]))
        return (self.columns["contact_points"][s], self.columns["contact_normals"][s],
                self.columns["contact_finger"][s])


def _empty_like_table(t: ObjectTable) -> dict[str, np.ndarray]:
    return {k: v[:0] for k, v in t.columns.items()}


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
        "stages_made_by": np.array([""] * n, dtype=object),
        "closing": np.array([""] * n, dtype=object),
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
            cols["stages_made_by"][i] = r.squeeze_convention or ""
            cols["closing"][i] = r.closing or ""
    table = ObjectTable(cols, tuple(joint_names), tuple(fingers), dict(attrs or {}))
    if validation is not None and split_rejected:
        keep = cols["passed"]
        good, bad = _select(table, keep), _select(table, ~keep)
        good.rejected = bad
        return good
    return table


def _select(t: ObjectTable, mask: np.ndarray) -> ObjectTable:
    idx = np.flatnonzero(mask)
    o = t.columns["contact_offsets"]
    rows = (np.concatenate([np.arange(o[i], o[i + 1]) for i in idx]) if len(idx)
            else np.zeros(0, np.int64))
    cols = {k: v[idx] for k, v in t.columns.items()
            if not k.startswith("contact_")}
    for k in ("contact_points", "contact_normals", "contact_finger"):
        cols[k] = t.columns[k][rows]
    counts = o[1:] - o[:-1]
    cols["contact_offsets"] = np.r_[0, np.cumsum(counts[idx])].astype(np.int64)
    return ObjectTable(cols, t.joint_names, t.finger_names, dict(t.attrs))


def _concat(a: ObjectTable, b: ObjectTable) -> ObjectTable:
    if a.joint_names != b.joint_names or a.finger_names != b.finger_names:
        raise ValueError("cannot append grasps of a different hand layout (joint or finger "
                         "names differ)")
    cols = {}
    for k in a.columns:
        if k == "contact_offsets":
            cols[k] = np.r_[a.columns[k], a.columns[k][-1] + b.columns[k][1:]].astype(np.int64)
        else:
            cols[k] = np.concatenate([a.columns[k], b.columns[k]])
    rej = a.rejected
    if b.rejected is not None:
        rej = b.rejected if rej is None else _concat(rej, b.rejected)
    attrs = dict(a.attrs)
    attrs.update(b.attrs)
    return ObjectTable(cols, a.joint_names, a.finger_names, attrs, rej)


def with_rejected(t: ObjectTable) -> ObjectTable:
    """The table's passing grasps followed by its rejected ones, in one table (no side table):
    for exports that carry every grasp with its verdict."""
    if t.rejected is None or not len(t.rejected):
        return dataclasses.replace(t, rejected=None)
    return dataclasses.replace(_concat(dataclasses.replace(t, rejected=None),
                                       dataclasses.replace(t.rejected, rejected=None)),
                               rejected=None)


def _write_group(g: h5py.Group, t: ObjectTable) -> None:
    for k, v in t.columns.items():
        if k in _STR_COLUMNS:
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
        g.attrs[k] = v if isinstance(v, (str, int, float, bool, np.number)) else json.dumps(v)
    if t.rejected is not None:
        _write_group(g.create_group("rejected"), t.rejected)


def _read_group(g: h5py.Group) -> ObjectTable:
    cols: dict[str, np.ndarray] = {}
    for k, ds in g.items():
        if isinstance(ds, h5py.Dataset):
            cols[k] = (np.array(ds.asstr()[()], dtype=object) if k in _STR_COLUMNS
                       else ds[()])
    attrs = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in g.attrs.items()
             if k not in ("joint_names", "finger_names")}
    rej = _read_group(g["rejected"]) if "rejected" in g else None
    return ObjectTable(cols, tuple(str(x) for x in g.attrs["joint_names"]),
                       tuple(str(x) for x in g.attrs["finger_names"]), attrs, rej)


def save(path: Path | str, tables: Mapping[str, ObjectTable],
         file_attrs: Mapping[str, Any] | None = None) -> None:
    """Write ``tables`` (object name → table) to ``path`` atomically (replacing it); the file
    records the versions of the packages that made it (``versions``, JSON), and each table
    keeps the ``versions`` it was made with (a table without them gets the writer's)."""
    versions = json.dumps(package_versions())
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = "dexaug-grasps-1"
        f.attrs["versions"] = versions
        for k, v in (file_attrs or {}).items():
            f.attrs[k] = v if isinstance(v, (str, int, float, bool)) else json.dumps(v)
        for name, t in tables.items():
            if "versions" not in t.attrs:
                t = dataclasses.replace(t, attrs={**t.attrs, "versions": versions})
            _write_group(f.create_group(name), t)
    log.info("wrote %s: %s", path, ", ".join(f"{k} {len(t)}" for k, t in tables.items()))


def load(path: Path | str) -> dict[str, ObjectTable]:
    """Read a dataset: object name → :class:`ObjectTable` (NumPy arrays). Raises
    :class:`DatasetError` when the file cannot be read as one."""
    try:
        with h5py.File(path, "r") as f:
            return {name: _read_group(g) for name, g in f.items() if isinstance(g, h5py.Group)}
    except (OSError, KeyError) as exc:  # h5py: unreadable file; KeyError: a missing column/attr
        raise DatasetError(f"{path}: not a readable grasp dataset: {exc}") from None


def _row_keys(t: ObjectTable) -> list[bytes]:
    """Per grasp, what makes two rows the same grasp: palm pose, joints and demo, exactly."""
    palm, joints = np.ascontiguousarray(t["palm_pose"]), np.ascontiguousarray(t["hand_pose"])
    return [palm[i].tobytes() + joints[i].tobytes() + str(t["demo_id"][i]).encode()
            for i in range(len(t))]


def _new_rows(old: ObjectTable | None, new: ObjectTable) -> ObjectTable:
    """``new`` without the grasps ``old`` already holds (:func:`_row_keys`)."""
    if old is None or not len(new):
        return new
    seen = set(_row_keys(old))
    return _select(new, np.array([k not in seen for k in _row_keys(new)], bool))


def append(path: Path | str, tables: Mapping[str, ObjectTable]) -> None:
    """Add grasps to ``path`` (created when missing): read, concatenate per object, rewrite
    atomically. Grasps the file already holds (the same palm pose, joints and demo: a re-run
    with the same seed) are not added twice; how many were skipped is logged."""
    path = Path(path)
    existing = load(path) if path.is_file() else {}
    file_attrs: dict[str, Any] = {}
    if path.is_file():
        with h5py.File(path, "r") as f:   # load() just read it: an error here is a race
            file_attrs = {k: v for k, v in f.attrs.items() if k not in ("format", "versions")}
    for name, t in tables.items():
        if name in existing:
            old = existing[name]
            fresh = _new_rows(old, t)
            if t.rejected is not None:
                fresh.rejected = _new_rows(old.rejected, t.rejected)
            skipped = len(t) + (len(t.rejected) if t.rejected is not None else 0) - len(fresh) - (
                len(fresh.rejected) if fresh.rejected is not None else 0)
            if skipped:
                log.warning("%s: %d of the new %s grasps are already in the file; not added "
                            "again", path, skipped, name)
            existing[name] = _concat(old, fresh)
        else:
            existing[name] = t
    save(path, existing, file_attrs)
