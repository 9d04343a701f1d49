"""Provenance: ``dexaug --version`` and the package versions every dataset records, read from
the installed distributions (so they change when an upgrade does)."""

from __future__ import annotations

import json
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import mujoco
import numpy as np

from augment import dataset
from sim.versions import package_versions


def test_version_names_dexaug_and_mujoco() -> None:
    proc = subprocess.run([sys.executable, "-m", "dexaug", "--version"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    (line,) = proc.stdout.splitlines()
    assert line.startswith(f"dexaug {metadata.version('dexaug')} (")
    assert f"mujoco {mujoco.__version__}" in line


def test_a_saved_dataset_records_the_versions(tmp_path: Path) -> None:
    table = dataset.ObjectTable(
        columns={k: np.zeros((0, 7) if k == "palm_pose" else 0, dtype=t) if k != "contact_offsets"
                 else np.zeros(1, np.int64) for k, t in dataset.COLUMNS.items()},
        joint_names=("j",), finger_names=("f",))
    path = tmp_path / "g.h5"
    dataset.save(path, {"obj": table})
    (loaded,) = dataset.load(path).values()
    versions = json.loads(loaded.attrs["versions"])
    assert versions == package_versions() and versions["mujoco"] == mujoco.__version__
    # a table made elsewhere keeps the versions it was made with
    old = {"mujoco": "3.3.2"}
    dataset.save(path, {"obj": dataset.ObjectTable(table.columns, table.joint_names,
                                                    table.finger_names, {"versions": old})})
    (loaded,) = dataset.load(path).values()
    assert json.loads(loaded.attrs["versions"]) == old
