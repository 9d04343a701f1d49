"""Grasp datasets in layouts other tools read (``dexaug export``).

Why: a dataset is only useful in the field if the tools people already run can read it.

- ``dexgraspbench`` (:mod:`.dexgraspbench`): DexGraspBench's reference JSONL, one grasp per line
  (the layout of ``../shared/reference/dexgraspbench/grasps.jsonl``), palm *body* and object
  poses in the world, joints by name, pregrasp/squeeze, dexaug's verdict.
- ``npz`` (:mod:`.npz`): every column of every table, for ``numpy.load``.
- ``fsg`` (:mod:`.fsg`): the FSG authors' HDF5 (GitHub W567/FSG): per object ``palm_pose``
  (N,7) of their palm body ``rh_palm``, ``hand_pose`` (N,22) in their joint order, ``gws``
  (N,1), all float32; with :func:`read_fsg`, which follows their reader.
- ``bodex`` (:mod:`.bodex`): DexGraspBench's per-grasp ``.npy`` files, the form BODex's grasps
  take for its evaluation: ``pregrasp_qpos`` / ``grasp_qpos`` / ``squeeze_qpos`` (floating
  root + 22 joints), ``obj_pose``, ``obj_scale``, ``obj_path``; with :func:`read_bodex`.

The Shadow-Hand layouts convert frames and joints exactly, by forward kinematics of our hand
(:mod:`.foreign`: which joints are dropped and why). Which body places their hand and which
joints they list in which order is the hand's own declaration, ``[formats.fsg]`` /
``[formats.bodex]`` in ``configs/hands/<hand>/hand.toml`` (:class:`sim.hand.config.HandFormat`):
nothing here names a hand's joints, and a hand that declares no such table is refused in one
line. Files are written atomically (:func:`sim.io.atomic_path`; the ``bodex`` folder as a
whole). Units: metres, radians.

What to import: the writers, readers and converters below, from the package
(``from augment.export import write_fsg, read_fsg, fsg_to_dexaug``); :data:`FORMATS` lists the
layouts ``dexaug export`` offers.
"""

from __future__ import annotations

from augment.export.bodex import (
    IDENTITY_POSE,
    BodexExport,
    bodex_to_dexaug,
    read_bodex,
    table_stages,
    write_bodex,
)
from augment.export.dexgraspbench import (
    REFERENCE_OBJECT_POSE,
    dexgraspbench_rows,
    write_dexgraspbench,
)
from augment.export.fsg import FsgExport, FsgGroup, fsg_group_name, fsg_to_dexaug, read_fsg, write_fsg
from augment.export.npz import write_npz

__all__ = ["FORMATS", "IDENTITY_POSE", "REFERENCE_OBJECT_POSE", "BodexExport", "FsgExport",
           "FsgGroup", "bodex_to_dexaug", "dexgraspbench_rows", "fsg_group_name", "fsg_to_dexaug",
           "read_bodex", "read_fsg", "table_stages", "write_bodex", "write_dexgraspbench",
           "write_fsg", "write_npz"]

FORMATS: tuple[str, ...] = ("dexgraspbench", "npz", "fsg", "bodex")
