"""``dexaug export --format fsg`` (augment.export.fsg): the FSG authors' HDF5, checked against
their reader's logic and their own published numbers.

- layout: one group ``ycb_<object>`` per object holding exactly ``palm_pose`` (N,7),
  ``hand_pose`` (N,22) and ``gws`` (N,1), float32, gzip, resizable — as their
  ``hdf5/srh/grasp_res.h5`` (W567/FSG);
- round trip: the 300 DexGraspBench reference grasps → fsg → :func:`read_fsg` →
  :func:`fsg_to_dexaug` give frame_palm and the 24 joints back to 1e-6 and ε as float32; a bent
  wrist comes back at 0 with rh_palm and the fingers where they were;
- their reader's placement (``set_robot_state``: the URDF root ``rh_palm`` at ``palm_pose``, the
  joints by their names) puts every fingertip where the dataset's grasp has it (1e-6 m), and
  reading ``palm_pose`` as our frame_palm would miss by centimetres;
- the authors' own demonstrations (``../shared/assets/handdata/fsg_keyframes``), stored in our
  frames and exported with ``--object-frame fsg-mesh``, give their ``srh.txt``'s rh_palm poses
  in their object frames and their 22 joint angles in their order;
- refusals: a hand without the Shadow Hand's joints, a table without ``gws``, a format option
  that does not apply — one line each.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.conftest import needs_menagerie
from tests.test_export import REFERENCE, _dataset_of_reference, _export

KEYFRAMES = Path(__file__).resolve().parents[2] / "shared" / "assets" / "handdata" / \
    "fsg_keyframes"
#: their reader's ``robot_joint_names`` for srh (scripts/grasp_gen/reader_grasp.py), typed here
#: rather than imported so that a wrong order in the module fails
THEIR_JOINTS = ["rh_FFJ4", "rh_FFJ3", "rh_FFJ2", "rh_FFJ1", "rh_MFJ4", "rh_MFJ3", "rh_MFJ2",
                "rh_MFJ1", "rh_RFJ4", "rh_RFJ3", "rh_RFJ2", "rh_RFJ1", "rh_LFJ5", "rh_LFJ4",
                "rh_LFJ3", "rh_LFJ2", "rh_LFJ1", "rh_THJ5", "rh_THJ4", "rh_THJ3", "rh_THJ2",
                "rh_THJ1"]

pytestmark = [pytest.mark.slow, needs_menagerie,
              pytest.mark.skipif(not REFERENCE.exists(), reason="no shared DGB reference file")]


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, object]:
    tmp = tmp_path_factory.mktemp("fsg")
    path, hand, _ = _dataset_of_reference(tmp)
    out = tmp / "grasp_res.h5"
    _export(path, out, "fsg")
    return path, out, hand


def _quat_close(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest |a − b| of quaternion rows, up to each row's sign."""
    sign = np.where(np.sum(a * b, axis=-1, keepdims=True) >= 0, 1.0, -1.0)
    return np.abs(sign * a - b).max(axis=-1)


def test_layout_is_theirs(exported) -> None:
    from augment import dataset

    path, out, _ = exported
    tables = dataset.load(path)
    with h5py.File(out, "r") as f:
        assert sorted(f) == sorted(f"ycb_{name}" for name in tables)
        for name, table in tables.items():
            g = f[f"ycb_{name}"]
            assert sorted(g) == ["gws", "hand_pose", "palm_pose"]
            n = len(table)
            for key, shape in (("palm_pose", (n, 7)), ("hand_pose", (n, 22)), ("gws", (n, 1))):
                ds = g[key]
                assert ds.shape == shape and ds.dtype == np.float32, (key, ds.shape, ds.dtype)
                assert ds.compression == "gzip" and ds.maxshape == (None, None)
        assert list(f.attrs["joint_names"]) == THEIR_JOINTS
        assert f.attrs["palm_body"] == "rh_palm"


def test_round_trip_through_their_reader_logic(exported) -> None:
    from augment import dataset
    from augment.export import fsg_to_dexaug, read_fsg

    path, out, hand = exported
    tables = dataset.load(path)
    groups = read_fsg(out)
    for name, table in tables.items():
        palm, q, gws = fsg_to_dexaug(groups[f"ycb_{name}"], hand)
        assert np.abs(palm[:, :3] - table["palm_pose"][:, :3]).max() < 1e-6
        assert _quat_close(palm[:, 3:], table["palm_pose"][:, 3:]).max() < 1e-6
        assert np.abs(q - table["hand_pose"]).max() < 1e-6          # the wrist is 0 in these
        np.testing.assert_array_equal(gws, table["gws"].astype(np.float32))
        # the comparison can fail: palm_pose read as if it were frame_palm is 4.7 cm off
        assert np.linalg.norm(groups[f"ycb_{name}"].palm_pose[:, :3] - table["palm_pose"][:, :3],
                              axis=1).min() > 0.04


def _tips_their_way(hand, palm_pose: np.ndarray, hand_pose: np.ndarray) -> np.ndarray:
    """Fingertips (N,F,3) in the file's object frame as their reader poses the hand: the root
    link rh_palm at ``palm_pose`` (w x y z → scipy x y z w; no extra rotation for srh), the
    joints set by their names, every other joint at 0 (their URDF has none)."""
    from sim.transforms import pose_inv, quat_to_mat

    q = np.zeros((len(hand_pose), hand.nq))
    for k, name in enumerate(THEIR_JOINTS):
        q[:, hand.joint_names.index(name)] = hand_pose[:, k]
    pos, quat = hand.body_poses(q)
    b = hand.model.body("rh_palm").id
    inv_p, inv_q = pose_inv(pos[:, b], quat[:, b])
    tips = hand.fingertip_sites(q, frame="base")
    in_palm = inv_p[:, None] + np.einsum("nij,nfj->nfi", quat_to_mat(inv_q), tips)
    p = np.asarray(palm_pose, float)
    rot = quat_to_mat(p[:, 3:] / np.linalg.norm(p[:, 3:], axis=1, keepdims=True))
    return p[:, None, :3] + np.einsum("nij,nfj->nfi", rot, in_palm)


def _tips_of_dataset(hand, palm_pose: np.ndarray, q: np.ndarray) -> np.ndarray:
    from sim.transforms import quat_to_mat

    tips = hand.fingertip_sites(q, frame="palm")
    return palm_pose[:, None, :3] + np.einsum("nij,nfj->nfi", quat_to_mat(palm_pose[:, 3:]), tips)


def test_their_placement_puts_the_fingertips_where_ours_are(exported) -> None:
    from augment import dataset

    path, out, hand = exported
    table = dataset.load(path)["004_sugar_box"]
    with h5py.File(out, "r") as f:
        g = f["ycb_004_sugar_box"]
        palm_pose, hand_pose = g["palm_pose"][()], g["hand_pose"][()]
    want = _tips_of_dataset(hand, table["palm_pose"], table["hand_pose"])
    got = _tips_their_way(hand, palm_pose, hand_pose)
    assert np.abs(got - want).max() < 1e-6
    # frame_palm written in place of rh_palm would put the fingertips centimetres away
    wrong = _tips_their_way(hand, table["palm_pose"], hand_pose)
    assert np.linalg.norm(wrong - want, axis=-1).min() > 0.01


def test_a_bent_wrist_is_dropped_exactly(tmp_path: Path) -> None:
    from augment import dataset
    from augment.export import fsg_to_dexaug, read_fsg, write_fsg
    from augment.export.fsg import fsg_hand

    path, hand, _ = _dataset_of_reference(tmp_path)
    table = dataset.load(path)["005_tomato_soup_can"]
    table.columns["hand_pose"][:5, :2] = [[0.3, -0.2]] * 5          # rh_WRJ2, rh_WRJ1
    out = tmp_path / "wrist.h5"
    done = write_fsg(out, {"005_tomato_soup_can": table}, hand)
    assert done.dropped_moved == 5
    palm, q, _ = fsg_to_dexaug(read_fsg(out)["ycb_005_tomato_soup_can"], hand)
    assert np.abs(q[:, :2]).max() == 0.0
    np.testing.assert_allclose(q[:, 2:], table["hand_pose"][:, 2:], atol=1e-6)
    np.testing.assert_allclose(palm[:, :3], table["palm_pose"][:, :3], atol=1e-6)
    assert _quat_close(palm[:, 3:], table["palm_pose"][:, 3:]).max() < 1e-6
    foreign = fsg_hand(hand)   # the wrist does move rh_palm against the hand's base
    assert foreign.dropped == ("rh_WRJ2", "rh_WRJ1")
    base_palm = hand.body_poses(table["hand_pose"][:1])[0][0, foreign.body_id]
    base_straight = hand.body_poses(q[:1])[0][0, foreign.body_id]
    assert np.linalg.norm(base_palm - base_straight) > 1e-3


def _srh(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Their srh.txt: object → (object pose, qpos[:7] rh_palm pose, qpos[7:29] joints)."""
    blocks = [b.splitlines() for b in path.read_text().strip().split("\n\n")]
    out = {}
    for b in blocks:
        obj = np.r_[np.fromstring(b[1], sep=" "), np.fromstring(b[2], sep=" ")]
        qpos = np.fromstring(b[3], sep=" ")
        out[b[0].strip().removeprefix("ycb_")] = (obj, qpos[:7], qpos[7:29])
    return out


@pytest.mark.skipif(not (KEYFRAMES / "srh.txt").is_file(), reason="no fsg_keyframes in ../shared")
def test_the_authors_demonstrations_come_out_as_their_srh_numbers(tmp_path: Path) -> None:
    import json

    from augment import dataset
    from augment.export import fsg_to_dexaug, read_fsg, write_fsg
    from augment.fsg.result import FsgGrasp
    from dexaug.commands.export import fsg_mesh_transforms
    from sim.grasp import Grasp
    from sim.hand.model import Hand
    from sim.transforms import pose_inv, pose_mul
    from tests.test_demo_import import SRH_TRANSFORMS

    hand = Hand.load("shadow_right")
    cfg = hand.config.palm
    doc = json.loads((KEYFRAMES / "keyframes_shared_frames.json").read_text())["objects"]
    tables = {}
    for name, kf in doc.items():         # our frames: frame_palm in our object frame
        body = pose_mul(*pose_inv(kf["object_pos_m"], kf["object_quat_wxyz"]),
                        kf["rh_palm_pos_m"], kf["rh_palm_quat_wxyz"])
        palm = pose_mul(*body, cfg.pos, cfg.quat_wxyz)
        q = np.array([kf["joints_rad"].get(j, 0.0) for j in hand.joint_names])
        g = FsgGrasp(grasp=Grasp.from_arrays(palm[0], palm[1], q), fingers=hand.finger_names,
                     contact_points=np.zeros((0, 3)), contact_normals=np.zeros((0, 3)),
                     contact_finger=np.zeros(0, int), ws_index=(), face_index=(), epsilon=0.05,
                     volume=0.0)
        tables[name] = dataset.from_fsg([g], hand.joint_names, hand.finger_names,
                                        attrs={"hand": hand.name})
    path = tmp_path / "demos.h5"
    dataset.save(path, tables)
    out = tmp_path / "srh.h5"
    _export(path, out, "fsg", "--object-frame", "fsg-mesh")
    groups = read_fsg(out)
    srh = _srh(KEYFRAMES / "srh.txt")
    assert sorted(srh) == sorted(tables)
    for name, (obj, palm_world, joints) in srh.items():
        p, q = pose_mul(*pose_inv(obj[:3], obj[3:] / np.linalg.norm(obj[3:])), palm_world[:3],
                        palm_world[3:] / np.linalg.norm(palm_world[3:]))
        got = groups[f"ycb_{name}"]
        assert np.abs(got.palm_pose[0, :3] - p).max() < 1e-6, name
        assert _quat_close(got.palm_pose[:1, 3:], q[None])[0] < 1e-6, name
        assert np.abs(got.hand_pose[0] - joints).max() < 1e-6, name       # their joint order
        # the transform derived from the two files agrees with the one derived for demo import
        derived = fsg_mesh_transforms([name])[name]
        assert np.abs(np.subtract(derived[:3], SRH_TRANSFORMS[name][:3])).max() < 1e-5
        assert _quat_close(np.array(derived[3:]), np.array(SRH_TRANSFORMS[name][3:])) < 1e-5
        # ... and --object-transform with it round-trips to our frames
        one = tmp_path / f"{name}.h5"
        write_fsg(one, {name: tables[name]}, hand, object_transforms={name: SRH_TRANSFORMS[name]})
        back, _, _ = fsg_to_dexaug(read_fsg(one)[f"ycb_{name}"], hand)
        assert np.abs(back[0, :3] - tables[name]["palm_pose"][0, :3]).max() < 1e-6


def test_refusals_are_one_line(tmp_path: Path) -> None:
    from augment import dataset
    from augment.export import write_fsg
    from sim.errors import DexaugError
    from sim.hand.model import Hand

    path, hand, _ = _dataset_of_reference(tmp_path)
    table = dataset.load(path)["005_tomato_soup_can"]
    del table.columns["gws"]
    with pytest.raises(DexaugError, match=r"my.h5: 005_tomato_soup_can: no column gws"):
        write_fsg(tmp_path / "x.h5", {"005_tomato_soup_can": table}, hand, source="my.h5")
    with pytest.raises(DexaugError, match=r"hand 'allegro_right' cannot be written in the fsg "
                                          r"layout.*lacks rh_FFJ4"):
        write_fsg(tmp_path / "x.h5", {}, Hand.load("allegro_right"))
    assert not (tmp_path / "x.h5").exists()
    proc = subprocess.run([sys.executable, "-m", "dexaug", "export", str(path), "--format", "fsg",
                           "--out", str(tmp_path / "y.h5"), "--object-pose", "0", "0", "0", "1", "0", "0",
                           "0"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0 and "--object-pose does not apply to --format fsg" in proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "y.h5").exists()
