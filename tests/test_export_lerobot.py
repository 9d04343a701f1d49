"""``dexaug export --format lerobot`` (augment.export.lerobot, issue #55): validated grasp
episodes as a LeRobot v3.0 dataset. Read back with pyarrow alone: frames and actions are the
episodes' arrays bit for bit, the actions replayed in a fresh MuJoCo model from the dataset
alone give the recorded joints (≤ 1e-6 rad; measured: bit for bit), the stats are the data's,
the meta agrees with itself and with the files, failed rollouts are kept apart with their
reasons. Where LeRobot is installed its own ``LeRobotDataset`` reads the folder too (it is
not in the test install: torch-based and heavy; ``benchmarks/bench_export_lerobot.py``
checks it from a side venv)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.episodes.episode import Episode
from sim.episodes.replay import replay
from sim.episodes.rollout import rollout
from sim.hand.model import Hand
from sim.validate.validator import Validator
from sim.world.objects import load_object
from tests.conftest import needs_menagerie, needs_ycb
from tests.test_episodes import DEMOS, shifted_grasps

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]
pytest.importorskip("pyarrow", reason="the LeRobot export's extra: pip install -e '.[lerobot]'")

from augment.export.lerobot import FAILED_FILE, write_lerobot  # noqa: E402
from augment.export.lerobot_read import LeRobotData, read_lerobot, replayable  # noqa: E402
from augment.export.lerobot_stats import STAT_KEYS  # noqa: E402


@pytest.fixture(scope="module")
def rolled(shadow: Hand) -> list[Episode]:
    """The shifted demo grasps of test_episodes (both objects: passes and every failure)."""
    out = []
    for name in DEMOS:
        v = Validator(shadow, load_object(name))
        out += [rollout(v, g, index=i) for i, g in enumerate(shifted_grasps(name))]
    return out


@pytest.fixture(scope="module")
def exported(rolled, tmp_path_factory) -> tuple[Path, LeRobotData]:
    root = tmp_path_factory.mktemp("lerobot") / "grasps"
    write_lerobot(root, rolled)
    return root, read_lerobot(root)


def _kept(rolled: list[Episode]) -> list[Episode]:
    return [e for e in rolled if e.success]


def test_frames_and_actions_are_the_episodes_arrays(rolled, exported) -> None:
    _, data = exported
    kept = _kept(rolled)
    assert len(kept) >= 3 and len(data.episodes) == len(kept)
    for i, ep in enumerate(kept):
        f, n, s = data.episode_frames(i), len(ep), ep.states
        assert len(f["index"]) == n   # one frame per step: the state before it, its action
        assert np.array_equal(f["observation.state"], np.concatenate(
            [s["hand_qpos"][:n], s["hand_qvel"][:n], s["palm_pose"][:n], s["object_pose"][:n]],
            axis=1))
        assert np.array_equal(f["action"], np.concatenate(
            [ep.ctrl, ep.base_target_pos, ep.base_target_quat], axis=1))
        assert np.array_equal(f["observation.fingertip_force"], s["fingertip_force"][:n])
        assert f["observation.state"].dtype == np.float64
        assert np.array_equal(f["timestamp"], (ep.time_s - ep.time_s[0]).astype(np.float32))
        assert f["next.done"].tolist() == [False] * (n - 1) + [True]
        assert f["next.success"].tolist() == [False] * (n - 1) + [True]
        row = data.episodes[i]
        assert (row["dexaug/object"], row["dexaug/grasp_index"]) == (ep.object, ep.grasp_index)
        assert json.loads(row["dexaug/result"]) == json.loads(json.dumps(ep.result))


def test_actions_replayed_from_the_dataset_give_its_joints(shadow: Hand, exported) -> None:
    _, data = exported
    fresh = {}
    for i in range(len(data.episodes)):
        ep = replayable(data, i)
        if ep.object not in fresh:   # a newly compiled model: nothing of the recording reused
            fresh[ep.object] = Validator(shadow, load_object(ep.object)).scene("lift-drop")
        states = replay(ep, fresh[ep.object])
        got = states["hand_qpos"][:len(ep)]
        assert np.abs(got - ep.states["hand_qpos"]).max() <= 1e-6
        assert np.array_equal(got, ep.states["hand_qpos"])   # measured: bit for bit
        assert np.array_equal(states["object_pose"][:len(ep)], ep.states["object_pose"])


def test_a_changed_action_in_the_dataset_shows_in_the_replay(shadow: Hand, exported) -> None:
    """The replay check can fail: one step's controls 0.05 rad off move the joints."""
    _, data = exported
    ep = replayable(data, 0)
    ep.ctrl[10] += 0.05
    states = replay(ep, Validator(shadow, load_object(ep.object)).scene("lift-drop"))
    assert np.abs(states["hand_qpos"][:len(ep)] - ep.states["hand_qpos"]).max() > 1e-4


def test_failed_rollouts_are_kept_apart_with_their_reason(rolled, exported) -> None:
    root, data = exported
    failed = json.loads((root / FAILED_FILE).read_text())["failed"]
    want = [(e.object, e.grasp_index, e.failure) for e in rolled if not e.success]
    assert [(f["object"], f["grasp_index"], f["failure"]) for f in failed] == want
    assert {f["failure"] for f in failed} >= {"slipped", "lost_contact", "penetration"}
    written = {(r["dexaug/object"], r["dexaug/grasp_index"]) for r in data.episodes}
    assert not written & {(o, i) for o, i, _ in want}


def test_stats_are_the_datas(exported) -> None:
    _, data = exported
    numeric = list(data.info["features"])
    for i, row in enumerate(data.episodes):
        f = data.episode_frames(i)
        for k in numeric:
            assert np.allclose(row[f"stats/{k}/q50"], np.median(
                f[k].astype(np.float64).reshape(len(f[k]), -1), axis=0), rtol=1e-12, atol=0), k
            x = f[k].astype(np.float64).reshape(len(f[k]), -1)
            assert np.array_equal(row[f"stats/{k}/min"], x.min(axis=0)), k
            assert np.array_equal(row[f"stats/{k}/max"], x.max(axis=0)), k
            assert np.allclose(row[f"stats/{k}/mean"], x.mean(axis=0), rtol=1e-12, atol=1e-12)
            assert np.allclose(row[f"stats/{k}/std"], x.std(axis=0), rtol=1e-9, atol=1e-12)
            assert row[f"stats/{k}/count"] == [len(x)]
    for k in numeric:   # the dataset's: over every frame (pooled from the episodes')
        x = data.frames[k].astype(np.float64).reshape(len(data.frames[k]), -1)
        got = data.stats[k]
        assert sorted(got) == sorted(STAT_KEYS)
        assert np.array_equal(got["min"], x.min(axis=0)) and np.array_equal(got["max"], x.max(axis=0))
        assert np.allclose(got["mean"], x.mean(axis=0), rtol=1e-12, atol=1e-12)
        assert np.allclose(got["std"], x.std(axis=0), rtol=1e-9, atol=1e-12)
        assert np.all((got["min"] <= got["q50"]) & (got["q50"] <= got["max"]))
        assert got["count"].tolist() == [len(x)]
        counts = np.array([r[f"stats/{k}/count"][0] for r in data.episodes])
        means = np.array([r[f"stats/{k}/mean"] for r in data.episodes])
        assert np.allclose((counts[:, None] * means).sum(0) / counts.sum(), got["mean"],
                           rtol=1e-9, atol=1e-12)


def test_the_meta_agrees_with_itself_and_the_files(rolled, exported) -> None:
    import pyarrow.parquet as pq

    root, data = exported
    info, kept = data.info, _kept(rolled)
    assert info["codebase_version"] == "v3.0" and info["video_path"] is None
    assert info["fps"] == 250 and abs(1 / info["fps"] - kept[0].timestep_s) < 1e-15
    assert info["total_episodes"] == len(data.episodes) == len(kept)
    assert info["total_frames"] == len(data.frames["index"]) == sum(len(e) for e in kept)
    assert info["total_tasks"] == len(data.tasks) == len(DEMOS)
    assert info["splits"] == {"train": f"0:{len(kept)}"}
    assert data.tasks[0] == "grasp and lift the dice with the shadow right"
    for k, ft in info["features"].items():
        names = ft["names"]
        assert names is None or len(names) == ft["shape"][0], k
        assert data.frames[k].shape[1:] == (() if ft["shape"] == [1] else tuple(ft["shape"])), k
        assert data.frames[k].dtype == np.dtype(ft["dtype"]), k
    assert np.array_equal(data.frames["index"], np.arange(info["total_frames"]))
    at = 0
    for i, row in enumerate(data.episodes):
        assert row["episode_index"] == i and row["dataset_from_index"] == at
        at = row["dataset_to_index"]
        assert row["length"] == at - row["dataset_from_index"]
        f = data.episode_frames(i)
        assert set(f["episode_index"].tolist()) == {i}
        assert np.array_equal(f["frame_index"], np.arange(row["length"]))
        assert row["tasks"] == [data.tasks[int(f["task_index"][0])]]
        assert row["tasks"] == [f"grasp and lift the {row['dexaug/object'][4:].replace('_', ' ')} "
                                "with the shadow right"]
        path = root / info["data_path"].format(chunk_index=row["data/chunk_index"],
                                               file_index=row["data/file_index"])
        assert i in set(pq.read_table(path, columns=["episode_index"])["episode_index"].to_pylist())
    assert at == info["total_frames"]


def test_small_files_roll_over_into_new_files_and_chunks(rolled, exported, tmp_path) -> None:
    """A 1 MB file limit and 2 files a chunk: one episode a file, a new chunk every two; the
    frames read the same."""
    _, whole = exported
    done = write_lerobot(tmp_path / "small", rolled, data_file_mb=1.0, chunks_size=2)
    assert len(done.data_files) == done.episodes
    assert done.data_files[2] == "data/chunk-001/file-000.parquet"
    data = read_lerobot(tmp_path / "small")
    assert [(r["data/chunk_index"], r["data/file_index"]) for r in data.episodes][:3] == \
        [(0, 0), (0, 1), (1, 0)]
    assert all(np.array_equal(data.frames[k], whole.frames[k]) for k in whole.frames)


def test_a_folder_that_is_no_export_is_not_replaced(rolled, tmp_path) -> None:
    from sim.errors import DexaugError

    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    with pytest.raises(DexaugError, match="not an earlier LeRobot export"):
        write_lerobot(tmp_path / "mine", rolled)
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep me"
    assert [p.name for p in tmp_path.iterdir()] == ["mine"]   # no temp folder left
    with pytest.raises(DexaugError, match="no successful episode"):
        write_lerobot(tmp_path / "none", [e for e in rolled if not e.success])
    assert not (tmp_path / "none").exists()


def test_without_pyarrow_the_error_names_the_extra(monkeypatch) -> None:
    from augment.export.lerobot import pyarrow_modules
    from sim.errors import DexaugError

    monkeypatch.setitem(sys.modules, "pyarrow", None)   # what a missing package looks like
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    with pytest.raises(DexaugError, match=r"pip install 'dexaug\[lerobot\]'"):
        pyarrow_modules()


def test_the_command_rolls_out_a_dataset_and_writes_it(shadow: Hand, rolled, tmp_path) -> None:
    """`dexaug export --format lerobot` on a grasps.h5 of the dice's shifted grasps: the same
    episodes as rolling them out here, the failures apart, episodes/s printed."""
    from augment import dataset
    from augment.fsg.result import FsgGrasp

    grasps = shifted_grasps("062_dice")
    fsg = [FsgGrasp(grasp=g, fingers=tuple(shadow.finger_names), contact_points=np.zeros((0, 3)),
                    contact_normals=np.zeros((0, 3)), contact_finger=np.zeros(0, int),
                    ws_index=(), face_index=(), epsilon=0.0, volume=0.0) for g in grasps]
    table = dataset.from_fsg(fsg, shadow.joint_names, shadow.finger_names,
                             attrs={"hand": shadow.name})
    src = tmp_path / "grasps.h5"
    dataset.save(src, {"062_dice": table})
    out = tmp_path / "lerobot"
    proc = subprocess.run([sys.executable, "-m", "dexaug", "export", str(src), "--format",
                           "lerobot", "--out", str(out)], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "episodes/s" in proc.stdout and f"to {out}" in proc.stdout
    here = [e for e in rolled if e.object == "062_dice"]
    data = read_lerobot(out)
    assert len(data.episodes) == sum(e.success for e in here)
    for i, ep in enumerate(e for e in here if e.success):
        assert np.array_equal(data.episode_frames(i)["action"][:, :len(ep.actuator_names)], ep.ctrl)
    failed = json.loads((out / FAILED_FILE).read_text())["failed"]
    assert [f["failure"] for f in failed] == [e.failure for e in here if not e.success]
    bad = subprocess.run([sys.executable, "-m", "dexaug", "export", str(src), "--format",
                          "lerobot", "--out", str(tmp_path / "x"), "--object-pose",
                          *["0", "0", "0", "1", "0", "0", "0"]], capture_output=True, text=True, timeout=120)
    assert bad.returncode != 0 and "--object-pose does not apply to --format lerobot" in bad.stderr


def test_lerobots_own_reader_gives_the_episodes(rolled, exported) -> None:
    """LeRobot's ``LeRobotDataset`` on the folder: its frames are the episodes' (float64 in
    its table; its items are torch tensors, float32 as torch makes them of Python floats)."""
    pytest.importorskip("lerobot", reason="LeRobot is not in the test install (torch-based, "
                        "heavy); benchmarks/bench_export_lerobot.py --lerobot-python checks it")
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root, data = exported
    ds = LeRobotDataset("dexaug/test", root=root)
    kept = _kept(rolled)
    assert ds.num_episodes == len(kept) and len(ds) == sum(len(e) for e in kept)
    table = ds.hf_dataset.with_format("arrow")[:]   # the frames LeRobot loaded, as stored
    for k in ("observation.state", "action"):
        col = table[k].combine_chunks()
        assert np.array_equal(col.flatten().to_numpy().reshape(len(col), -1), data.frames[k])
    item = ds[len(kept[0])]   # the second episode's first frame
    assert int(item["episode_index"]) == 1 and item["task"] == data.tasks[0]
    assert np.array_equal(item["action"].numpy(), data.frames["action"][len(kept[0])]
                          .astype(np.float32))


def test_camera_frames_are_an_image_feature_of_every_frame(shadow: Hand, tmp_path) -> None:
    """``--camera``: a rollout rendered on every state row (32x32: about 16 ms a frame with
    software EGL, so this test takes about 10 s), the hand and the die covering at least a
    tenth of every frame (the scene's far overview camera left them 5.7 %), gives
    ``observation.images.overview`` as LeRobot's ``image`` dtype: PNGs in the parquet that
    decode to the rendered pixels exactly, with per-channel stats in [0, 1]; a rollout
    rendered on every 400th row only is refused (a camera needs every frame's image)."""
    from sim.world.render import gl_available

    if gl_available() is None:
        pytest.skip("no offscreen rendering (EGL/OSMesa)")
    v = Validator(shadow, load_object("062_dice"))
    grasp = shifted_grasps("062_dice")[0]
    ep = rollout(v, grasp, camera=(32, 32))
    assert ep.success
    write_lerobot(tmp_path / "cam", [ep])
    data = read_lerobot(tmp_path / "cam")
    ft = data.info["features"]["observation.images.overview"]
    assert ft == {"dtype": "image", "shape": [32, 32, 3], "names": ["height", "width", "channels"]}
    images = data.frames["observation.images.overview"]
    assert images.shape == (len(ep), 32, 32, 3) and images.dtype == np.uint8
    covered = (images.max(axis=-1) > 0).mean(axis=(1, 2))   # share of drawn pixels per frame
    assert covered.min() >= 0.1, covered.min()
    assert np.array_equal(images, ep.frames[:len(ep)])           # lossless: PNG
    stats = data.stats["observation.images.overview"]
    x = images.reshape(-1, 3) / 255.0
    assert np.array_equal(stats["mean"].shape, (3, 1, 1))
    assert np.allclose(stats["mean"].ravel(), x.mean(axis=0), rtol=1e-12)
    assert np.array_equal(stats["max"].ravel(), x.max(axis=0))
    assert stats["count"].tolist() == [len(ep)]
    sparse = rollout(v, grasp, camera=(8, 8), camera_every=400)
    with pytest.raises(ValueError, match="a LeRobot camera needs every frame's"):
        write_lerobot(tmp_path / "sparse", [sparse])
