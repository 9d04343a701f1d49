"""Provenance: ``dexaug --version``, and what every dataset records of what made it — package
versions, code version, the hashes of the hand's and the object's files, the attributes of
appended runs — plus the hygiene of appending (no silent duplicates) and a readable print."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import h5py
import mujoco
import numpy as np
import pytest

from augment import dataset
from augment.fsg.result import FsgGrasp
from augment.grasp_table import grasps_of, with_rejected
from sim.grasp import Grasp
from sim.paths import REPO_ROOT, YCB_ENV
from sim.provenance import asset_hashes, file_sha256
from sim.validate.result import ValidationResult
from sim.versions import code_version, describe_code_version, package_versions
from tests.conftest import needs_menagerie

pytestmark = pytest.mark.slow

JOINTS = tuple(f"j{i}" for i in range(4))
FINGERS = ("thumb", "index")
BLOCK = "999_test_block"
#: a YCB-style object of our own (XML + mesh file), so asset hashing is tested on files the
#: test may change
BLOCK_XML = """<mujoco model="test_block">
  <compiler meshdir="assets"/>
  <asset><mesh name="block" file="block.obj"/></asset>
  <worldbody><geom type="mesh" mesh="block" mass="0.1"/></worldbody>
</mujoco>
"""
CUBE_OBJ = "".join(f"v {x} {y} {z}\n" for x in (-.02, .02) for y in (-.02, .02) for z in (-.02, .02))
CUBE_OBJ += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n"


def _table(n: int, seed: int = 0, rejected: int = 0, **attrs: object) -> dataset.ObjectTable:
    """``n`` random grasps that pass and ``rejected`` that fail, as :func:`dataset.from_fsg`
    builds them from FSG and validation output."""
    rng = np.random.default_rng(seed)
    grasps = []
    for _ in range(n + rejected):
        q = rng.normal(size=4)
        grasps.append(FsgGrasp(grasp=Grasp(rng.normal(size=3), q / np.linalg.norm(q),
                                           rng.normal(size=len(JOINTS))),
                               fingers=FINGERS, contact_points=rng.normal(size=(2, 3)),
                               contact_normals=rng.normal(size=(2, 3)),
                               contact_finger=np.array([0, 1]), ws_index=(0, 1),
                               face_index=(0, 0), epsilon=0.1, volume=0.2))
    verdicts = [ValidationResult("lift-drop", i < n, None if i < n else "slipped", 0.0)
                for i in range(n + rejected)]
    return dataset.from_fsg(grasps, JOINTS, FINGERS, verdicts, demo_id="d", attrs=attrs)


def _drop_attrs(path: Path, group: str, *names: str) -> None:
    """Make ``path`` look written before the attributes ``names`` existed."""
    with h5py.File(path, "a") as f:
        for name in names:
            del f[group].attrs[name]


# ------------------------------------------------------------------------------- versions


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


def test_code_version_is_the_checkout_or_the_installed_package(tmp_path: Path) -> None:
    """A git checkout gives its commit and whether it is dirty; anything else (an installed
    copy, git missing) the installed version — never an error."""
    head = subprocess.run(["git", "-C", str(REPO_ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True, check=False)
    here = code_version()
    if head.returncode == 0:
        assert here == {"source": "git", "commit": head.stdout.strip(),
                        "dirty": here["dirty"]} and isinstance(here["dirty"], bool)
        assert describe_code_version(here).startswith(f"dexaug at {head.stdout[:10]}")
    elsewhere = code_version(tmp_path)   # not a checkout
    assert elsewhere == {"source": "package", "version": metadata.version("dexaug")}
    assert describe_code_version(elsewhere) == f"dexaug {metadata.version('dexaug')}"
    path = tmp_path / "g.h5"
    dataset.save(path, {"obj": _table(2)})
    loaded = dataset.load(path)
    assert json.loads(loaded.attrs["code_version"]) == here
    assert json.loads(loaded["obj"].attrs["code_version"]) == here


# --------------------------------------------------------------------------------- assets


@pytest.fixture
def ycb_copy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A YCB root of one object of our own; the asset root of this test's datasets."""
    folder = tmp_path / "ycb" / BLOCK
    (folder / "assets").mkdir(parents=True)
    (folder / "test_block.xml").write_text(BLOCK_XML)
    (folder / "assets" / "block.obj").write_text(CUBE_OBJ)
    monkeypatch.setenv(YCB_ENV, str(tmp_path / "ycb"))
    return folder


def test_asset_hashes_recorded_and_a_changed_asset_detected(ycb_copy: Path,
                                                            tmp_path: Path) -> None:
    """Each table records the SHA-256 of its object's XML and mesh (named under their asset
    root); ``asset_changes`` is empty while the files are the same, and names the file that
    was edited, then the one that went missing."""
    path = tmp_path / "g.h5"
    dataset.save(path, {BLOCK: _table(3, hand="no_such_hand")})
    recorded = json.loads(dataset.load(path)[BLOCK].attrs["asset_sha256"])
    xml, mesh = f"ycb:{BLOCK}/test_block.xml", f"ycb:{BLOCK}/assets/block.obj"
    assert recorded == {xml: file_sha256(ycb_copy / "test_block.xml"),
                        mesh: file_sha256(ycb_copy / "assets" / "block.obj")}
    assert dataset.asset_changes(path) == []
    with (ycb_copy / "test_block.xml").open("a") as f:
        f.write("<!-- edited -->\n")
    (change,) = dataset.asset_changes(path)
    assert (change.table, change.file, change.reason) == (BLOCK, xml, "changed")
    assert str(change) == f"{BLOCK}: {xml} changed"
    (ycb_copy / "assets" / "block.obj").unlink()
    assert {(c.file, c.reason) for c in dataset.asset_changes(path)} == {(xml, "changed"),
                                                                        (mesh, "missing")}


def test_a_table_without_hashes_is_reported_and_primitives_have_none(tmp_path: Path) -> None:
    path = tmp_path / "g.h5"
    dataset.save(path, {"cylinder": _table(2), "obj": _table(2, seed=1)})
    assert dataset.asset_changes(path) == []   # code-made object, unknown object: no files
    _drop_attrs(path, "obj", "asset_sha256")   # a file from before asset hashes
    (change,) = dataset.asset_changes(path)
    assert (change.table, change.reason) == ("obj", "not recorded")


@needs_menagerie
def test_the_hands_model_files_are_hashed() -> None:
    from sim.hand.model import Hand

    hashes = asset_hashes("shadow_right", None)
    model = Hand.load("shadow_right").model_path
    key = f"menagerie:{model.parent.name}/{model.name}"
    assert hashes[key] == file_sha256(model)
    assert sum(k.endswith(".obj") for k in hashes) >= 10   # its meshes
    assert asset_hashes("shadow_right", None) == hashes     # cached, same answer


# ------------------------------------------------------------------------- append hygiene


def test_append_refuses_duplicates_unless_allowed(tmp_path: Path) -> None:
    path = tmp_path / "grasps.h5"
    assert dataset.existing_rows(path) == 0
    dataset.append(path, {"obj": _table(4, rejected=2)})
    assert dataset.existing_rows(path) == 6
    before = path.read_bytes()
    again = {"obj": _table(4, rejected=2), "other": _table(3, seed=5)}
    with pytest.raises(dataset.DuplicateGraspsError,
                       match=r"^\S*grasps\.h5: 6 of the 9 grasps to append are exact duplicates "
                             r"of grasps already in the file \(obj: 6;") as err:
        dataset.append(path, again)
    assert "\n" not in str(err.value)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["grasps.h5"]
    dataset.append(path, again, allow_duplicates=True)
    assert dataset.existing_rows(path) == 15
    dataset.append(path, {"obj": _table(2, seed=7)})   # new grasps append as before
    assert len(dataset.load(path)["obj"]) == 10
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    with pytest.raises(dataset.DatasetError, match=r"junk\.h5: not a readable grasp dataset"):
        dataset.existing_rows(tmp_path / "junk.h5")


def test_appended_tables_keep_what_they_were_made_with(tmp_path: Path) -> None:
    """Rows already in a file keep their provenance — a table from before an attribute existed
    is marked unrecorded, never given the writer's — and appended rows made otherwise are
    recorded in ``appended``."""
    path = tmp_path / "g.h5"
    dataset.save(path, {"obj": _table(2, seed=1, versions={"mujoco": "3.3.2"}),
                        "old": _table(1, seed=2)})
    _drop_attrs(path, "old", "code_version", "asset_sha256")
    dataset.append(path, {"obj": _table(3, seed=3, rejected=1)})
    tables = dataset.load(path)
    obj, old = tables["obj"].attrs, tables["old"].attrs
    assert json.loads(obj["versions"]) == {"mujoco": "3.3.2"}
    (run,) = json.loads(obj["appended"])
    assert run["grasps"] == 4 and run["attrs"] == {"versions": package_versions()}
    assert old["code_version"] == old["asset_sha256"] == "unrecorded"
    assert "appended" not in old


# ------------------------------------------------------------------------------ printing


def test_a_printed_dataset_is_short_and_says_what_it_holds(tmp_path: Path) -> None:
    path = tmp_path / "big.h5"
    dataset.save(path, {"big": _table(3000, rejected=1500, hand="shadow_right"),
                        **{f"o{i:02d}": _table(5, seed=i) for i in range(30)}})
    loaded = dataset.load(path)
    text = str(loaded)
    assert len(text) < 2000, text
    first, second = text.splitlines()[:2]
    assert first.startswith(f"Dataset({path}: 31 objects, {4500 + 30 * 5} grasps; written by "
                            f"{describe_code_version(code_version())})")
    assert second == "  big: 3000 grasps (3000 passed), 1500 rejected, hand shadow_right"
    assert text.endswith("… and 19 more objects")
    table = repr(loaded["big"])
    assert len(table) < 1000 and "\n" not in table and table.startswith("ObjectTable(3000 grasps")


def test_grasps_of_a_saved_table_are_the_grasps_written(tmp_path: Path) -> None:
    made = _table(3, rejected=2)
    dataset.save(tmp_path / "d.h5", {"obj": made})
    table = with_rejected(dataset.load(tmp_path / "d.h5")["obj"])
    grasps = grasps_of(table)
    assert len(grasps) == 5 and len(grasps_of(table, 2)) == 2 and grasps_of(None) == []
    for i, g in enumerate(grasps):
        np.testing.assert_allclose(np.r_[g.palm_pos, g.palm_quat_wxyz], table["palm_pose"][i], atol=1e-12)
        np.testing.assert_array_equal(g.joints, table["hand_pose"][i])


def test_copied_asset_root_is_hashed_in_place(ycb_copy: Path, tmp_path: Path) -> None:
    """A dataset made against one asset root checks against the root in use: the same files
    copied elsewhere (another machine's layout) still match."""
    path = tmp_path / "g.h5"
    dataset.save(path, {BLOCK: _table(1)})
    moved = tmp_path / "elsewhere"
    shutil.copytree(ycb_copy.parent, moved)
    shutil.rmtree(ycb_copy.parent)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(YCB_ENV, str(moved))
        assert dataset.asset_changes(path) == []
