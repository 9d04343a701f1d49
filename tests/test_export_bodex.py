"""``dexaug export --format bodex`` (augment.export.bodex): DexGraspBench's per-grasp files,
read as DexGraspBench reads them and measured against the shared DGB reference.

- the 300 reference grasps exported with the reference's object pose: one ``.npy`` dict per
  grasp with DGB's keys; read like DGB (``np.load(…).item()``) and placed as its Shadow asset
  places the hand (``rh_palm`` at ``pos="0 0 0.034"`` under the floating root, the joints in its
  MJCF order, typed here), every line's ``rh_palm_pose_world``, ``q_grasp``, ``q_pregrasp`` and
  ``q_squeeze`` come back (1e-9); a root put at rh_palm itself would miss by 34 mm;
- :func:`read_bodex` + :func:`bodex_to_dexaug` give the dataset's palm poses and joint
  vectors back (1e-9);
- grasps without stages get them as the validator makes them (``bodex``: squeeze =
  2·grasp − pregrasp), labelled ``derived:bodex`` in the files and the manifest;
- a folder that is not an earlier export is not replaced; a hand without the Shadow joints is
  refused in one line.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import needs_menagerie, needs_ycb
from tests.test_export import REFERENCE, _dataset_of_reference, _export

#: DexGraspBench's Shadow qpos after the root (assets/hand/shadow/right_hand.xml), typed here
DGB_JOINTS = ["rh_FFJ4", "rh_FFJ3", "rh_FFJ2", "rh_FFJ1", "rh_MFJ4", "rh_MFJ3", "rh_MFJ2",
              "rh_MFJ1", "rh_RFJ4", "rh_RFJ3", "rh_RFJ2", "rh_RFJ1", "rh_LFJ5", "rh_LFJ4",
              "rh_LFJ3", "rh_LFJ2", "rh_LFJ1", "rh_THJ5", "rh_THJ4", "rh_THJ3", "rh_THJ2",
              "rh_THJ1"]
#: where DGB's Shadow asset puts rh_palm under its floating root: <body name="rh_palm" pos=…>
DGB_PALM_IN_ROOT = np.array([0.0, 0.0, 0.034])

pytestmark = [pytest.mark.slow, needs_menagerie,
              pytest.mark.skipif(not REFERENCE.exists(), reason="no shared DGB reference file")]


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory):
    tmp = tmp_path_factory.mktemp("bodex")
    path, hand, lines = _dataset_of_reference(tmp)
    out = tmp / "graspdata"
    _export(path, out, "bodex", "--object-pose", "0", "0", "0.3", "1", "0", "0", "0")
    return path, out, hand, lines


def _dgb_read(path: Path) -> dict:
    return np.load(path, allow_pickle=True).item()


def _rh_palm(qpos: np.ndarray, offset: np.ndarray = DGB_PALM_IN_ROOT) -> tuple[np.ndarray, np.ndarray]:
    """rh_palm in the world as DGB's scene puts it: the root's free joint, then the body offset."""
    from sim.transforms import rotate

    q = qpos[3:7] / np.linalg.norm(qpos[3:7])
    return qpos[:3] + rotate(q, offset), q


def test_files_place_the_hand_as_the_reference_does(exported) -> None:
    _, out, _, lines = exported
    files = sorted(out.glob("**/*.npy"))
    assert len(files) == 300 and (out / "dexaug_export.json").is_file()
    by_key = {(r["object"], r["index"]): r for r in lines}
    for f in files:
        d = _dgb_read(f)
        assert {"obj_path", "obj_scale", "obj_pose", "pregrasp_qpos", "grasp_qpos",
                "squeeze_qpos"} <= set(d)
        ref = by_key[(f.parent.name, int(f.stem))]
        np.testing.assert_allclose(d["obj_pose"], ref["object_pose_world"], atol=1e-12)
        assert d["obj_scale"] == 1.0 and d["obj_path"].endswith(f"/{ref['object']}")
        for key, want in (("grasp_qpos", "q_grasp"), ("pregrasp_qpos", "q_pregrasp"),
                          ("squeeze_qpos", "q_squeeze")):
            qpos = np.asarray(d[key])
            assert qpos.shape == (29,)
            pos, quat = _rh_palm(qpos)
            body = np.asarray(ref["rh_palm_pose_world"])
            assert np.abs(pos - body[:3]).max() < 1e-9
            assert abs(abs(float(quat @ body[3:])) - 1.0) < 1e-9
            np.testing.assert_allclose(qpos[7:], [ref[want][j] for j in DGB_JOINTS], atol=1e-12)
        assert d["stages_made_by"].startswith("dataset:")
    # the check can fail: a root at rh_palm itself (no offset) is 34 mm off
    d = _dgb_read(files[0])
    ref = by_key[(files[0].parent.name, int(files[0].stem))]
    pos, _ = _rh_palm(np.asarray(d["grasp_qpos"]), np.zeros(3))
    assert np.linalg.norm(pos - np.asarray(ref["rh_palm_pose_world"][:3])) > 0.03


def test_read_back_gives_the_dataset(exported) -> None:
    from augment import dataset
    from augment.export import bodex_to_dexaug, read_bodex

    path, out, hand, _ = exported
    tables = dataset.load(path)
    records = read_bodex(out)
    assert len(records) == 300
    back = bodex_to_dexaug(records, hand)
    want = {col: np.array([tables[r["dexaug_object"]][col][r["dexaug_index"]] for r in records])
            for col in ("palm_pose", "hand_pose", "pregrasp_pose", "squeeze_pose")}
    assert np.abs(back["palm_pose"][:, :3] - want["palm_pose"][:, :3]).max() < 1e-9
    dots = np.abs(np.sum(back["palm_pose"][:, 3:] * want["palm_pose"][:, 3:], axis=1))
    assert np.abs(dots - 1.0).max() < 1e-9
    for col in ("hand_pose", "pregrasp_pose", "squeeze_pose"):
        np.testing.assert_allclose(back[col], want[col], atol=1e-12)


def test_root_offset_is_dgbs() -> None:
    from augment.export.bodex import bodex_hand
    from sim.hand.model import Hand
    from sim.transforms import pose_inv

    p, q = pose_inv(*bodex_hand(Hand.load("shadow_right")).parent_in_body())
    np.testing.assert_allclose(p, DGB_PALM_IN_ROOT, atol=1e-12)
    np.testing.assert_allclose(np.abs(q), [1, 0, 0, 0], atol=1e-12)


@needs_ycb
def test_missing_stages_are_derived_as_the_validator_does(tmp_path: Path) -> None:
    from augment import dataset
    from augment.export import read_bodex
    from sim.grasp import Grasp
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    path, hand, _ = _dataset_of_reference(tmp_path)
    name = "004_sugar_box"
    table = dataset.load(path)[name]
    table.columns["pregrasp_pose"][:] = np.nan          # never simulated: no stages stored
    table.columns["squeeze_pose"][:] = np.nan
    bare = tmp_path / "bare.h5"
    dataset.save(bare, {name: table})
    out = tmp_path / "derived"
    _export(bare, out, "bodex", "--squeeze-convention", "bodex")
    manifest = json.loads((out / "dexaug_export.json").read_text())
    assert manifest["stages_made_by"] == {"derived:bodex": len(table)}
    v = Validator(hand, load_object(name))
    idx = [hand.joint_names.index(j) for j in DGB_JOINTS]
    for r in read_bodex(out):
        i = r["dexaug_index"]
        assert r["stages_made_by"] == "derived:bodex"
        np.testing.assert_allclose(r["squeeze_qpos"][7:],
                                   2 * r["grasp_qpos"][7:] - r["pregrasp_qpos"][7:], atol=1e-12)
        if i < 5:
            palm = table["palm_pose"][i]
            want = v.stages(Grasp.from_arrays(palm[:3], palm[3:], table["hand_pose"][i]), "bodex",
                            sized_for="dgb")   # the export's stages are the benchmark's
            np.testing.assert_allclose(r["pregrasp_qpos"][7:], want.pregrasp[idx], atol=1e-12)
            assert np.abs(r["pregrasp_qpos"][7:] - r["grasp_qpos"][7:]).max() > 1e-3


def test_refusals(tmp_path: Path) -> None:
    from augment.export import write_bodex
    from sim.errors import DexaugError
    from sim.hand.model import Hand

    keep = tmp_path / "mine"
    keep.mkdir()
    (keep / "notes.txt").write_text("not an export")
    path, _, _ = _dataset_of_reference(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "dexaug", "export", str(path), "--format", "bodex",
                           "--out", str(keep)], capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0 and "is not an earlier bodex export" in proc.stderr
    assert "Traceback" not in proc.stderr and (keep / "notes.txt").is_file()
    with pytest.raises(DexaugError, match="hand 'leap_right' cannot be written in the bodex"):
        write_bodex(tmp_path / "x", {}, Hand.load("leap_right"))
    assert not (tmp_path / "x").exists()


@needs_ycb
def test_the_grasp_stage_is_the_one_dgb_closes_through(tmp_path: Path) -> None:
    """``grasp_qpos`` is the dataset's ``touch_pose`` where ``dgb`` recorded one, ``hand_pose``
    where not, and, derived under ``dexaug``, the validator's touching grasp stage."""
    from augment import dataset
    from augment.export import read_bodex
    from augment.grasp_table import select_rows
    from sim.grasp import Grasp
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    path, hand, _ = _dataset_of_reference(tmp_path)
    name = "005_tomato_soup_can"
    table = dataset.load(path)[name]
    touch = np.full_like(table.columns["hand_pose"], np.nan)
    touch[0] = table.columns["hand_pose"][0] + 0.01
    table.columns["touch_pose"] = touch
    stored = tmp_path / "stored.h5"
    dataset.save(stored, {name: table})
    _export(stored, tmp_path / "stored", "bodex")
    idx = [hand.joint_names.index(j) for j in DGB_JOINTS]
    got = {r["dexaug_index"]: r["grasp_qpos"][7:] for r in read_bodex(tmp_path / "stored")}
    np.testing.assert_allclose(got[0], touch[0][idx], atol=1e-12)
    np.testing.assert_allclose(got[1], table["hand_pose"][1][idx], atol=1e-12)

    for col in ("pregrasp_pose", "squeeze_pose", "touch_pose"):   # never simulated
        table.columns[col][:] = np.nan
    bare = tmp_path / "bare.h5"
    dataset.save(bare, {name: select_rows(table, np.arange(len(table)) < 3)})   # each is rehearsed
    _export(bare, tmp_path / "derived", "bodex", "--squeeze-convention", "dexaug")
    v = Validator(hand, load_object(name))
    derived = read_bodex(tmp_path / "derived")
    assert sorted(r["dexaug_index"] for r in derived) == [0, 1, 2]
    for r in derived:
        i = r["dexaug_index"]
        palm = table["palm_pose"][i]
        want = v.stages(Grasp.from_arrays(palm[:3], palm[3:], table["hand_pose"][i]),
                        "dexaug", sized_for="dgb")
        np.testing.assert_allclose(r["grasp_qpos"][7:], want.grasp[idx], atol=1e-12)
        assert np.abs(want.grasp - table["hand_pose"][i]).max() > 1e-4   # it moved
