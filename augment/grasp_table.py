"""One object's grasps in memory (:class:`ObjectTable`) and the row operations on it: select,
concatenate, join a table with its rejected side table.

Kept apart from :mod:`augment.dataset`, which reads and writes these tables as HDF5 files
(its docstring lists the columns): exports and viewers that only read tables need no file
code. Concatenation tolerates a column only one side has (a file written before the column
existed): the other side's rows get NaN, or "" for strings.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.grasp import Grasp

__all__ = ["STR_COLUMNS", "ObjectTable", "brief", "concat_tables", "grasp_count",
           "grasp_stage_poses", "grasps_of", "select_rows", "with_rejected"]

#: per-grasp columns stored as strings
STR_COLUMNS = ("failure", "demo_id", "stages_made_by", "closing", "stopped_early")


@dataclass
class ObjectTable:
    """One object's grasps as NumPy arrays (the columns: :mod:`augment.dataset`).

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
        return (f"ObjectTable({brief(self)}; {len(self.joint_names)} joints, fingers "
                f"{list(self.finger_names)}; columns {sorted(self.columns)}; "
                f"attrs {sorted(self.attrs)})")

    def contacts(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        o = self.columns["contact_offsets"]
        s = slice(int(o[i]), int(o[i + 1]))
        return (self.columns["contact_points"][s], self.columns["contact_normals"][s],
                self.columns["contact_finger"][s])


def grasp_count(t: ObjectTable) -> int:
    """Kept and rejected grasps of ``t``."""
    return len(t) + (len(t.rejected) if t.rejected is not None else 0)


def brief(t: ObjectTable) -> str:
    passed = int(np.count_nonzero(t.columns.get("passed", np.zeros(0, bool))))
    rejected = 0 if t.rejected is None else len(t.rejected)
    return (f"{len(t)} grasps ({passed} passed), {rejected} rejected, "
            f"hand {t.attrs.get('hand', '?')}")


def select_rows(t: ObjectTable, mask: np.ndarray) -> ObjectTable:
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


def concat_tables(a: ObjectTable, b: ObjectTable) -> ObjectTable:
    if a.joint_names != b.joint_names or a.finger_names != b.finger_names:
        raise ValueError("cannot append grasps of a different hand layout (joint or finger "
                         "names differ)")
    cols = {}
    for k in a.columns | b.columns:
        if k == "contact_offsets":
            cols[k] = np.r_[a.columns[k], a.columns[k][-1] + b.columns[k][1:]].astype(np.int64)
        else:
            cols[k] = np.concatenate([_column(a, k, b), _column(b, k, a)])
    rej = a.rejected
    if b.rejected is not None:
        rej = b.rejected if rej is None else concat_tables(rej, b.rejected)
    # the first rows' attributes: a table's provenance is never overwritten by later rows'
    return ObjectTable(cols, a.joint_names, a.finger_names, dict(a.attrs), rej)


def _column(t: ObjectTable, key: str, other: ObjectTable) -> np.ndarray:
    """``t``'s column ``key``, or, where ``t`` was written before the column existed (it is
    ``other``'s), one of ``t``'s length that says "not recorded": NaN, or "" for strings."""
    if key in t.columns:
        return t.columns[key]
    like = other.columns[key]
    if key in STR_COLUMNS:
        return np.array([""] * len(t), dtype=object)
    return np.full((len(t), *like.shape[1:]), np.nan)


def with_rejected(t: ObjectTable) -> ObjectTable:
    """The table's passing grasps followed by its rejected ones, in one table (no side table):
    for exports that carry every grasp with its verdict."""
    if t.rejected is None or not len(t.rejected):
        return dataclasses.replace(t, rejected=None)
    return dataclasses.replace(concat_tables(dataclasses.replace(t, rejected=None),
                                       dataclasses.replace(t.rejected, rejected=None)),
                               rejected=None)


def grasp_stage_poses(t: ObjectTable) -> np.ndarray:
    """(N, J) radians: per grasp the joints the benchmark closed through between pregrasp and
    squeeze — its ``touch_pose`` where ``dgb`` recorded one, else its ``hand_pose``. What an
    export writes as the grasp stage, so it runs what was validated."""
    hand = np.asarray(t.columns["hand_pose"], dtype=float)
    touch = np.asarray(t.columns.get("touch_pose", np.full_like(hand, np.nan)), dtype=float)
    return np.where(np.isfinite(touch).all(axis=1)[:, None], touch, hand)


def grasps_of(t: ObjectTable | None, limit: int | None = None) -> list[Grasp]:
    """The first ``limit`` (default all) rows of ``t`` as :class:`sim.grasp.Grasp` (palm pose and
    joints; stages are left for the validator to derive), none for a missing table."""
    if t is None:
        return []
    n = len(t) if limit is None else min(limit, len(t))
    return [Grasp.from_arrays(t["palm_pose"][i][:3], t["palm_pose"][i][3:], t["hand_pose"][i])
            for i in range(n)]
