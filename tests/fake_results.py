"""Result folders and arm files as tests need them, without running the pipeline.

Why not a fixture: the dashboard, its security tests and the arm-stage tests each need them
with their own output folders and demos.
"""

from __future__ import annotations

import json
from pathlib import Path

import h5py

from augment import dataset
from dexaug.pipeline.options import demo_dir
from dexaug.pipeline.summary import DemoSummary
from sim.demo import Demo

__all__ = ["arm_file_numbers", "empty_dataset", "fake_result"]


def empty_dataset(path: Path, obj: str = "062_dice") -> Path:
    """A ``grasps.h5`` as augment writes it when no grasp passed: an empty main table."""
    table = dataset.from_fsg([], ("j0", "j1"), ("thumb", "first"), [],
                             attrs={"hand": "shadow_right"})
    path.parent.mkdir(parents=True, exist_ok=True)
    dataset.save(path, {obj: table})
    return path


def fake_result(out_root: Path, demo: Demo) -> Path:
    """A finished result of ``demo`` under ``out_root`` (the folder the pipeline would write:
    an empty dataset and a ``summary.json`` naming it) the catalog lists; returns the
    dataset's path."""
    folder = demo_dir(out_root, demo)
    data = empty_dataset(folder / "grasps.h5", demo.object)
    summary = DemoSummary(demo_id=demo.id, hand=demo.hand, object=demo.object,
                          source=str(demo.source), run_key="fake", requested=1, generated=0,
                          passed=0, failures={}, fsg_stopped="n", timings_s={}, metrics={},
                          dataset=str(data), report=None)
    (folder / "summary.json").write_text(json.dumps(summary.to_json()))
    return data


def arm_file_numbers(path: Path) -> tuple[int, int, dict[str, int]]:
    """(pairs, passed, failures by reason) of a one-object arm file, read with h5py alone (not
    through the code under test)."""
    with h5py.File(path, "r") as f:
        (g,) = f.values()
        passed = g["passed"][()]
        reasons = [x.decode() for x in g["failure"][()][~passed]]
    return len(passed), int(passed.sum()), {r: reasons.count(r) for r in set(reasons)}
