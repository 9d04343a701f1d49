"""``npz``: every column of every object's table in one NumPy ``.npz``.

Arrays are named ``<object>/<column>`` (contacts flat with their offsets, as in the HDF5), with
``<object>/joint_names`` and ``<object>/finger_names``; ``numpy.load`` reads it with no dexaug
installed. Strings are stored as NumPy unicode arrays (no pickles).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from augment.dataset import ObjectTable
from sim.io import atomic_path

__all__ = ["write_npz"]


def write_npz(path: Path | str, tables: Mapping[str, ObjectTable]) -> int:
    """Write every column of every table to one ``.npz`` (module docstring); the grasp count."""
    arrays: dict[str, np.ndarray] = {}
    for name, table in tables.items():
        for col, values in table.columns.items():
            arrays[f"{name}/{col}"] = np.asarray(values if values.dtype != object
                                                 else values.astype(str))
        arrays[f"{name}/joint_names"] = np.array(table.joint_names)
        arrays[f"{name}/finger_names"] = np.array(table.finger_names)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)  # type: ignore[arg-type]  # numpy stubs type **kwds as allow_pickle's bool
    return sum(len(t) for t in tables.values())
