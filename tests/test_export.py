"""``dexaug export`` (augment.export): the DexGraspBench reference layout, measured against the
shared reference file itself, and the flat .npz.

- the 300 lines of ``../shared/reference/dexgraspbench/grasps.jsonl`` read with the reader the
  ``dgb`` agreement uses, put in a dexaug dataset, saved, exported by the CLI: every line's object
  pose, palm body pose (quaternion up to sign) and the three joint dicts come back to 1e-9, with
  the same keys — and a grasp moved by 1 mm would not;
- the export of a dataset reads back, through the same reader, into the dataset's grasps;
- the npz holds every column under ``<object>/<column>``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import needs_menagerie

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference" / "dexgraspbench" / \
    "grasps.jsonl"

pytestmark = [pytest.mark.slow, needs_menagerie,
              pytest.mark.skipif(not REFERENCE.exists(), reason="no shared DGB reference file")]


def _dataset_of_reference(tmp_path: Path) -> tuple[Path, object, list[dict]]:
    """The reference grasps as a dexaug dataset (one table per object, file order kept)."""
    from augment import dataset
    from augment.fsg.result import FsgGrasp
    from sim.validate.dgb_reference import load_reference, reference_hand

    hand = reference_hand(REFERENCE)
    refs = load_reference(REFERENCE, hand)
    lines = [json.loads(x) for x in REFERENCE.read_text().splitlines()]
    tables = {}
    for name in dict.fromkeys(r.object for r in refs):
        mine = [r for r in refs if r.object == name]
        fsg = [FsgGrasp(grasp=r.grasp, fingers=tuple(hand.finger_names),
                        contact_points=np.zeros((0, 3)), contact_normals=np.zeros((0, 3)),
                        contact_finger=np.zeros(0, int), ws_index=(), face_index=(),
                        epsilon=0.0, volume=0.0) for r in mine]
        t = dataset.from_fsg(fsg, hand.joint_names, hand.finger_names, attrs={"hand": hand.name})
        t.columns["pregrasp_pose"] = np.stack([r.grasp.pregrasp for r in mine])
        t.columns["squeeze_pose"] = np.stack([r.grasp.squeeze for r in mine])
        tables[name] = t
    path = tmp_path / "reference.h5"
    dataset.save(path, tables)
    return path, hand, lines


def _export(src: Path, out: Path, fmt: str, *extra: str) -> None:
    proc = subprocess.run([sys.executable, "-m", "dexaug", "export", str(src), "--format", fmt,
                           "--out", str(out), *extra], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr


def _same_row(got: dict, want: dict, body_key: str) -> float:
    """Largest difference of poses and joint angles between two reference-layout rows."""
    worst = float(np.abs(np.subtract(got["object_pose_world"], want["object_pose_world"])).max())
    g, w = np.asarray(got[body_key]), np.asarray(want[body_key])
    sign = 1.0 if g[3:] @ w[3:] >= 0 else -1.0
    worst = max(worst, float(np.abs(g[:3] - w[:3]).max()), float(np.abs(sign * g[3:] - w[3:]).max()))
    for key in ("q_grasp", "q_pregrasp", "q_squeeze"):
        assert set(got[key]) == set(want[key]), key
        worst = max(worst, max(abs(got[key][j] - want[key][j]) for j in want[key]))
    return worst


def test_reference_file_round_trips_through_a_dataset(tmp_path: Path) -> None:
    path, hand, lines = _dataset_of_reference(tmp_path)
    out = tmp_path / "export.jsonl"
    _export(path, out, "dexgraspbench")
    rows = sorted((json.loads(x) for x in out.read_text().splitlines()),
                  key=lambda r: (r["object"], r["index"]))
    lines = sorted(lines, key=lambda r: (r["object"], r["index"]))   # the file's own order kept
    assert len(rows) == len(lines) == 300                           # per object
    body_key = f"{hand.config.palm.body}_pose_world"
    for got, want in zip(rows, lines, strict=True):
        assert got["object"] == want["object"]
        assert set(want) - {"dgb"} <= set(got), set(want) - set(got)   # the reference's keys
        assert _same_row(got, want, body_key) < 1e-9
        assert got["object_mass_kg_real"] == pytest.approx(want["object_mass_kg_real"], rel=0.02)
    moved = dict(rows[0], **{body_key: [rows[0][body_key][0] + 1e-3, *rows[0][body_key][1:]]})
    assert _same_row(moved, lines[0], body_key) > 5e-4         # the comparison can fail


def test_export_reads_back_into_the_same_grasps(tmp_path: Path) -> None:
    from augment import dataset
    from sim.validate.dgb_reference import load_reference

    path, hand, _ = _dataset_of_reference(tmp_path)
    out = tmp_path / "export.jsonl"
    _export(path, out, "dexgraspbench", "--object", "004_sugar_box", "--object-pose",
            "0.1", "-0.2", "0.05", "0.7071068", "0", "0", "0.7071068")
    back = load_reference(out, hand)
    table = dataset.load(path)["004_sugar_box"]
    assert len(back) == len(table) == 100
    for i, r in enumerate(back):
        np.testing.assert_allclose(r.grasp.palm_pos, table["palm_pose"][i, :3], atol=1e-9)
        q = table["palm_pose"][i, 3:]
        assert abs(abs(float(r.grasp.palm_quat_wxyz @ q)) - 1.0) < 1e-9
        np.testing.assert_allclose(r.grasp.joints, table["hand_pose"][i], atol=1e-12)
        np.testing.assert_allclose(r.grasp.squeeze, table["squeeze_pose"][i], atol=1e-12)


def test_npz_holds_every_column(tmp_path: Path) -> None:
    from augment import dataset

    path, hand, _ = _dataset_of_reference(tmp_path)
    out = tmp_path / "grasps.npz"
    _export(path, out, "npz")
    z = np.load(out)
    tables = dataset.load(path)
    for name, t in tables.items():
        for col, values in t.columns.items():
            got = z[f"{name}/{col}"]
            if values.dtype.kind in "fib":
                np.testing.assert_array_equal(got, values)
            else:
                assert got.shape == values.shape
        assert list(z[f"{name}/joint_names"]) == list(hand.joint_names)
