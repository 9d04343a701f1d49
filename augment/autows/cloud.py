"""AutoWS workspace clouds as data (paper section 3.2; DESIGN §4), and their ``.npz`` file format.

A workspace cloud holds, per finger, every place the finger's contact faces can be put by a grid
of joint angles, in ``frame_palm``: each point carries the face centre position and normal, the
finger's joint angles that put it there, and the face shape (circle radius or rectangle half-edge
vectors), plus the link skeleton of that pose. FSG samples these points directly, so no inverse
kinematics is ever solved. :class:`FingerCloud` is one finger's cloud (read-only arrays),
:class:`WorkspaceCloud` a hand's, fingers in priority order; built by
:func:`augment.autows.build.build_workspace`.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from augment.autows.params import WorkspaceError
from sim.io import atomic_path

__all__ = ["FACE_KINDS", "FORMAT_VERSION", "FingerCloud", "WorkspaceCloud", "summarise"]

#: Bumped whenever the algorithm or the file layout changes: old cache files stop matching.
FORMAT_VERSION = 2
#: Face kinds as stored in ``FingerCloud.face_kind`` (index into this tuple).
FACE_KINDS = ("circle", "rect")


@dataclass(frozen=True, eq=False)
class FingerCloud:
    """The workspace cloud of one finger (arrays in ``frame_palm``, metres, radians).

    Attributes:
        name: finger name.
        joint_names: the finger's joints (config order, coupled followers included).
        positions: (N,3) contact-face centres.
        normals: (N,3) unit face normals (out of the fingertip).
        joints: (N, len(joint_names)) joint angles that put the face there.
        face_index: (N,) int16, which contact face (0 = main, then the kept extra faces).
        face_kind: (N,) uint8, index into :data:`FACE_KINDS`.
        radius: (N,) circle radius (NaN for rectangles).
        half_edges: (N,2,3) rectangle half-edge vectors (NaN for circles).
        skeleton: (N,K,3) float32 link skeleton points (fingertip link excluded).
        tip_centres, tip_normals: (F,3) the faces in the tip body frame.
        tip_radius: (F,) radii (NaN for rectangles); tip_half_edges: (F,2,3) (NaN for circles).
        tip_area: (F,) face areas, square metres.
        tip_skeleton: (N,J,3) float32 points along the fingertip link beyond ``skeleton``'s
            last one, to the pulp: not for the link check (the fingertip touches by design) but
            for a table, which no part of the finger may enter. Empty (N,0,3) when not built.
    """

    name: str
    joint_names: tuple[str, ...]
    positions: np.ndarray
    normals: np.ndarray
    joints: np.ndarray
    face_index: np.ndarray
    face_kind: np.ndarray
    radius: np.ndarray
    half_edges: np.ndarray
    skeleton: np.ndarray
    tip_centres: np.ndarray
    tip_normals: np.ndarray
    tip_radius: np.ndarray
    tip_half_edges: np.ndarray
    tip_area: np.ndarray
    tip_skeleton: np.ndarray | None = None

    ARRAYS = ("positions", "normals", "joints", "face_index", "face_kind", "radius", "half_edges",
              "skeleton", "tip_centres", "tip_normals", "tip_radius", "tip_half_edges", "tip_area",
              "tip_skeleton")

    def __post_init__(self) -> None:
        if self.tip_skeleton is None:
            object.__setattr__(self, "tip_skeleton", np.zeros((len(self.positions), 0, 3), np.float32))
        for a in self.ARRAYS:  # the arrays are shared, never copied: make them read-only
            arr = np.asarray(getattr(self, a))
            arr.flags.writeable = False
            object.__setattr__(self, a, arr)

    @property
    def n_points(self) -> int:
        return len(self.positions)

    @property
    def n_faces(self) -> int:
        return len(self.tip_centres)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, a).nbytes for a in self.ARRAYS)


@dataclass(frozen=True, eq=False)
class WorkspaceCloud:
    """AutoWS workspace clouds of a hand: one :class:`FingerCloud` per finger, in priority
    order (the hand config's finger order), plus provenance (mode, demo id, parameters, grids,
    cache key). ``from_cache`` says whether this object was read from the disk cache."""

    hand: str
    fingers: tuple[FingerCloud, ...]
    provenance: dict[str, Any]
    from_cache: bool = False

    @property
    def finger_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fingers)

    def finger(self, name: str) -> FingerCloud:
        for f in self.fingers:
            if f.name == name:
                return f
        raise KeyError(f"no finger {name!r} in the workspace cloud of {self.hand!r} "
                       f"({list(self.finger_names)})")

    @property
    def nbytes(self) -> int:
        return sum(f.nbytes for f in self.fingers)

    def save(self, path: Path | str) -> None:
        """Write the cloud to ``path`` (``.npz``, uncompressed for fast loading) atomically."""
        arrays: dict[str, np.ndarray] = {}
        for i, f in enumerate(self.fingers):
            for a in FingerCloud.ARRAYS:
                arrays[f"f{i}_{a}"] = getattr(f, a)
        meta = {"format": FORMAT_VERSION, "hand": self.hand,
                "fingers": [{"name": f.name, "joint_names": list(f.joint_names)}
                            for f in self.fingers],
                "provenance": self.provenance}
        arrays["meta"] = np.array(json.dumps(meta))
        buf = io.BytesIO()
        np.savez(buf, **arrays)  # type: ignore[arg-type]  # numpy stubs type **kwds as allow_pickle's bool
        with atomic_path(path) as tmp:
            tmp.write_bytes(buf.getbuffer())

    @classmethod
    def load(cls, path: Path | str) -> WorkspaceCloud:
        """Read a cloud written by :meth:`save`.

        Raises:
            WorkspaceError: the file is missing, damaged, of another format version, or not a
                workspace cloud.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"][()]))
                if meta.get("format") != FORMAT_VERSION:
                    raise WorkspaceError(f"{path}: workspace cloud format {meta.get('format')}, "
                                         f"expected {FORMAT_VERSION}")
                fingers = tuple(
                    FingerCloud(name=fm["name"], joint_names=tuple(fm["joint_names"]),
                                **{a: z[f"f{i}_{a}"] for a in FingerCloud.ARRAYS})
                    for i, fm in enumerate(meta["fingers"]))
        except WorkspaceError:
            raise
        except FileNotFoundError:
            raise WorkspaceError(f"{path}: no such workspace cloud file") from None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise WorkspaceError(f"{path}: not a readable workspace cloud ({exc})") from None
        return cls(hand=meta["hand"], fingers=fingers, provenance=meta["provenance"])


def summarise(cloud: WorkspaceCloud) -> list[tuple[str, int, int]]:
    """``(finger, number of points, number of contact faces)`` per finger, in priority order."""
    return [(f.name, f.n_points, f.n_faces) for f in cloud.fingers]
