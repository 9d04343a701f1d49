"""``fsg``: the HDF5 layout of the FSG authors' implementation (GitHub W567/FSG) for their
Shadow Hand, and a reader that follows their reader's logic.

Layout — their writer ``scripts/grasp_gen/saver_grasp.py`` (``add_obj_key``, ``add_pose``,
``convert_hand_pose``), their reader ``scripts/grasp_gen/reader_grasp.py`` with
``scripts/grasp_gen/utils.py`` (``read_pose``, ``set_robot_state``), their published
``hdf5/srh/grasp_res.h5``::

    /<object>/                 one group per object, named as their assets: ycb_004_sugar_box
        palm_pose (N,7) float32  their robot's root link in the object frame: x y z qw qx qy qz
        hand_pose (N,22) float32 radians: FFJ4..FFJ1 MFJ4..MFJ1 RFJ4..RFJ1 LFJ5..LFJ1 THJ5..THJ1
        gws       (N,1) float32  grasp wrench space score

each gzip-compressed, chunked and resizable (maxshape (None, None)) like theirs: their saver
appends to a file by resizing. The root link of their ``assets/robot/srh/urdf/srh.urdf`` is
``rh_palm`` (their ``config/srh/autows.yaml``: ``palm_name: rh_palm``), whose frame is the
Menagerie ``rh_palm`` body's (same finger joint origins; ``../shared/assets/handdata/
fsg_keyframes/README.md``); their reader puts that link at ``palm_pose`` with no extra rotation
for ``srh`` (scipy ``from_quat([qx, qy, qz, qw])``) and sets the joints by name in the order
above (the hand's declaration: ``[formats.fsg]`` in the Shadow Hand's ``configs/hands/<hand>/hand.toml``;
a hand without one is refused). So ``palm_pose`` is the pose of ``rh_palm`` — not dexaug's
frame_palm, which is ``rh_palm`` turned 180° about z with its origin on the palm face — and it
is computed from frame_palm by forward kinematics of our hand
(:class:`augment.export.foreign.ForeignHand`).
Their hand has no wrist: ``rh_WRJ2`` and ``rh_WRJ1`` are dropped (``foreign``'s docstring: the
palm and fingers stay exact; the count of grasps whose wrist was bent is returned and stored).
``gws`` is their L1 grasp-wrench-space ε (torques over the object's largest radius), the metric
dexaug's ``gws`` column holds.

Their reader reads only those three datasets; attributes it ignores say what the file is:
the root's ``dexaug_layout``, ``palm_body``, ``palm_pose_order``, ``joint_names``,
``dropped_joints``, ``grasps_with_dropped_joints_moved``, ``source``; each group's
``dexaug_object``, ``object_frame`` and ``object_transform``.

Object frame: theirs is the frame of their ``assets/obj/<group>.obj``, for YCB objects a
re-centred copy of the mesh, not the ``textured.obj`` origin dexaug's grasps are in. Without a
transform the poses stay in dexaug's object frame (``object_frame`` says so); with
``object_transforms[object]`` (our object frame in theirs, ``[x, y, z, qw, qx, qy, qz]``) they
are put in theirs. Units: metres, radians.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from augment.dataset import ObjectTable
from augment.export.foreign import ForeignHand, need_columns, same_joints, split_pose
from sim.errors import DexaugError
from sim.hand.model import Hand
from sim.io import atomic_path
from sim.transforms import pose_inv, pose_mul

__all__ = ["FSG_DATASETS", "FSG_LAYOUT", "FsgExport", "FsgGroup", "fsg_group_name", "fsg_hand",
           "fsg_to_dexaug", "read_fsg", "write_fsg"]

FSG_LAYOUT = "dexaug-fsg-srh-1"
#: dataset → its columns (the first axis is the grasp; None: the hand's ``[formats.fsg]`` joints)
FSG_DATASETS: dict[str, int | None] = {"palm_pose": 7, "hand_pose": None, "gws": 1}
_IDENTITY = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
_OURS = "dexaug object frame (the object's mesh origin, YCB textured.obj)"
_THEIRS = "the reference implementation's object mesh frame (our frame placed by object_transform)"


def fsg_hand(hand: Hand) -> ForeignHand:
    """``hand`` as the FSG authors' files know it (its ``[formats.fsg]``); refused (one line)
    when it declares none or cannot be."""
    return ForeignHand(hand, "fsg")


def fsg_group_name(object_name: str) -> str:
    """Their group (and asset) name of an object: ``ycb_`` + the YCB folder name."""
    return f"ycb_{object_name}" if object_name[:3].isdigit() else object_name


@dataclass(frozen=True)
class FsgExport:
    """What :func:`write_fsg` wrote: grasps, and how many had a dropped joint off 0."""

    grasps: int
    dropped_moved: int


def _transform(transforms: Mapping[str, Sequence[float]] | None,
               name: str) -> tuple[np.ndarray, np.ndarray] | None:
    if transforms is None or name not in transforms:
        return None
    t = np.asarray(transforms[name], dtype=float)
    if t.shape != (7,) or not np.isfinite(t).all() or not np.linalg.norm(t[3:]) > 0:
        raise DexaugError(f"object transform of {name}: expected [x, y, z, qw, qx, qy, qz], "
                          f"got {list(t)}")
    return split_pose(t)


def write_fsg(path: Path | str, tables: Mapping[str, ObjectTable], hand: Hand, *,
              object_transforms: Mapping[str, Sequence[float]] | None = None,
              source: str = "dataset") -> FsgExport:
    """Write ``tables`` in the FSG authors' HDF5 layout (module docstring) to ``path``,
    atomically. ``object_transforms``: per object, our object frame in theirs."""
    foreign = fsg_hand(hand)
    groups: dict[str, dict[str, Any]] = {}
    moved = 0
    for name, table in tables.items():
        where = f"{source}: {name}"
        need_columns(table, ("palm_pose", "hand_pose", "gws"), where, "fsg")
        same_joints(table, hand, where)
        q = np.asarray(table["hand_pose"], dtype=float)
        body_p, body_q = (foreign.to_body(table["palm_pose"], q) if len(table)
                          else (np.zeros((0, 3)), np.zeros((0, 4))))
        t = _transform(object_transforms, name)
        if t is not None:
            body_p, body_q = pose_mul(*t, body_p, body_q)
        moved += int(foreign.dropped_moved(q).sum()) if len(table) else 0
        group = fsg_group_name(name)
        if group in groups:
            raise DexaugError(f"{where}: two objects map to the group {group!r}")
        groups[group] = {
            "data": {"palm_pose": np.c_[body_p, body_q], "hand_pose": q[:, foreign.index],
                     "gws": np.asarray(table["gws"], dtype=float).reshape(-1, 1)},
            "attrs": {"dexaug_object": name, "object_frame": _OURS if t is None else _THEIRS,
                      "object_transform": np.asarray(_IDENTITY if t is None or object_transforms is None
                                                     else object_transforms[name], float)}}
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs.update({
            "dexaug_layout": FSG_LAYOUT, "palm_body": foreign.body,
            "palm_pose_order": "x y z qw qx qy qz", "joint_names": list(foreign.joints),
            "dropped_joints": " ".join(foreign.dropped),
            "grasps_with_dropped_joints_moved": moved, "source": source})
        for group, content in groups.items():
            g = f.create_group(group)
            for key, values in content["data"].items():
                values = values.astype(np.float32)
                g.create_dataset(key, data=values, compression="gzip", maxshape=(None, None),
                                 chunks=(max(1, min(len(values), 1024)), values.shape[1]))
            g.attrs.update(content["attrs"])
    return FsgExport(sum(len(t) for t in tables.values()), moved)


@dataclass(frozen=True)
class FsgGroup:
    """One object's grasps as their reader reads them: ``palm_pose`` (N,7) of their palm body
    (``rh_palm``) [x y z qw qx qy qz], ``hand_pose`` (N,J) in the hand's ``[formats.fsg]``
    joint order (J = 22 for theirs), ``gws`` (N,1)."""

    name: str
    palm_pose: np.ndarray
    hand_pose: np.ndarray
    gws: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)


def read_fsg(path: Path | str, hand: Hand | None = None) -> dict[str, FsgGroup]:
    """Read a file of the FSG layout the way their reader does (every top-level group is an
    object; ``palm_pose``/``hand_pose``/``gws`` by name, row i is grasp i), refusing what their
    reader could not use: a missing dataset or a wrong column count (one line naming it).
    ``hand_pose`` has the joints of ``hand``'s ``[formats.fsg]`` (without ``hand``: as many as
    the file's ``joint_names`` attribute lists, else any number)."""
    path = Path(path)
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise DexaugError(f"{path}: cannot read it as HDF5 ({exc})") from None
    out = {}
    with f:
        named = f.attrs.get("joint_names")
        joints = (len(fsg_hand(hand).joints) if hand is not None
                  else None if named is None else len(named))
        for name in f:
            g = f[name]
            if not isinstance(g, h5py.Group):
                raise DexaugError(f"{path}: /{name} is not an object group")
            arrays = {}
            for key, width in FSG_DATASETS.items():
                cols = joints if width is None else width
                if key not in g:
                    raise DexaugError(f"{path}: /{name}/{key} is missing (their reader needs "
                                      f"{', '.join(FSG_DATASETS)})")
                a = np.asarray(g[key][()])
                if a.ndim != 2 or (cols is not None and a.shape[1] != cols):
                    raise DexaugError(f"{path}: /{name}/{key} has shape {a.shape}, expected "
                                      f"(N, {'J' if cols is None else cols})")
                arrays[key] = a
            n = {len(a) for a in arrays.values()}
            if len(n) != 1:
                raise DexaugError(f"{path}: /{name}: the datasets have different lengths {n}")
            out[name] = FsgGroup(name, arrays["palm_pose"], arrays["hand_pose"], arrays["gws"],
                                 {k: v for k, v in g.attrs.items()})
    return out


def fsg_to_dexaug(group: FsgGroup, hand: Hand, *,
                  object_transform: Sequence[float] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Their grasps back in dexaug's terms: frame_palm poses (N,7) in our object frame, our
    joint vectors (N,nq; the wrist at 0) and ε (N,). ``object_transform``: our object frame in
    theirs (default: the group's ``object_transform`` attribute, else none)."""
    foreign = fsg_hand(hand)
    if object_transform is None:
        object_transform = group.attrs.get("object_transform", _IDENTITY)
    body_p, body_q = split_pose(group.palm_pose)
    body_p, body_q = pose_mul(*pose_inv(*split_pose(np.asarray(object_transform, float))),
                              body_p, body_q)
    gws = np.asarray(group.gws, dtype=float).reshape(-1)
    if not len(gws):
        return np.zeros((0, 7)), np.zeros((0, hand.nq)), gws
    palm, q = foreign.from_body(np.c_[body_p, body_q], group.hand_pose)
    return palm, q, gws
