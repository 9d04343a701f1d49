"""Session → demo → AutoWS → FSG → validation → dataset + report (teleop.record.demos, dexaug.pipeline.run).

The end-to-end check runs the committed scripted demonstration of the tomato soup can through
the whole pipeline and checks the dataset against its own claims and the report against the
dataset; the bad-input checks build small sessions with the real recorder.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from augment import dataset
from sim.demo import DemoError, load_demo, save_demo
from sim.errors import DexaugError
from sim.paths import REPO_ROOT
from teleop.record.demos import extract_demos
from teleop.record.recorder import SessionRecorder
from tests.conftest import HANG_S, needs_menagerie, needs_ycb, wait_for

pytestmark = pytest.mark.slow

CAN_SESSION = REPO_ROOT / "recordings" / "demo_005_tomato_soup_can.mcap"
RAW_SESSION = REPO_ROOT / "recordings" / "synth_005_tomato_soup_can.mcap"


def _state_only_session(path: Path, meta: dict, contacts: bool) -> Path:
    """A session with states (hand at rest, object still) and, when ``contacts``, one
    forefinger-only contact per state: never a grasp."""
    joints = [f"j{i}" for i in range(3)]
    with SessionRecorder(path, metadata={"joint_names": joints, **meta}) as rec:
        for k in range(50):
            t = k * 10_000_000
            rec.write_state(np.zeros(3), [0, 0, 0.2], [1, 0, 0, 0], [0, 0, 0], [1, 0, 0, 0],
                            t_s=k * 0.01, log_time_ns=t)
            rec.write_contacts([], t_s=k * 0.01, log_time_ns=t)
    return path


def test_session_without_object_or_contacts(tmp_path: Path) -> None:
    fingers = {"hand": "shadow_right", "fingers": ["thumb", "forefinger"]}
    with pytest.raises(DemoError, match="no object"):
        extract_demos(_state_only_session(tmp_path / "a.mcap", fingers, False))
    p = _state_only_session(tmp_path / "b.mcap", {**fingers, "object": "box"}, False)
    with pytest.raises(DemoError, match="no fingertip ever touched"):
        extract_demos(p)


@needs_menagerie
@needs_ycb
def test_raw_session_and_damaged_file(tmp_path: Path) -> None:
    with pytest.raises(DemoError, match=r"raw input only.*rerecord"):
        extract_demos(RAW_SESSION)
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all" * 10)
    with pytest.raises(DemoError, match=r"junk\.mcap"):
        extract_demos(junk)
    # a recording cut in half (recorder killed): what is readable still gives the grasp or a
    # clear reason, never a crash
    cut = tmp_path / "cut.mcap"
    data = CAN_SESSION.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    try:
        demos = extract_demos(cut)
        assert all(np.isfinite(d.joints).all() for d in demos)
    except DemoError as exc:
        assert "cut.mcap" in str(exc)


@needs_menagerie
@needs_ycb
def test_demo_of_the_committed_session_and_file_round_trip(tmp_path: Path) -> None:
    demos = extract_demos(CAN_SESSION)
    assert len(demos) == 1
    d = demos[0]
    assert d.object == "005_tomato_soup_can" and d.hand == "shadow_right"
    assert "thumb" in d.fingers and len(d.fingers) >= 2 and d.duration_s >= 0.3
    # contacts lie on the can: within a few mm of its surface in the object frame
    from sim.world.objects import load_object
    from teleop.synthetic.surface import surface_distance_m

    mesh = load_object(d.object).surface_mesh()
    for pts in d.contact_points_obj.values():
        assert np.abs(surface_distance_m(mesh, pts)).max() < 0.004
    save_demo(tmp_path / "d.json", d)
    back = load_demo(tmp_path / "d.json")
    np.testing.assert_allclose(back.joints, d.joints)
    np.testing.assert_allclose(back.palm_quat_wxyz, d.palm_quat_wxyz)
    assert back.tip_contacts.keys() == d.tip_contacts.keys()
    (tmp_path / "bad.json").write_text(json.dumps({"format": "dexaug-demo-1", "id": "x"}))
    with pytest.raises(DemoError, match=r"bad\.json.*field"):
        load_demo(tmp_path / "bad.json")


@needs_menagerie
@needs_ycb
def test_hand_not_installed(tmp_path: Path) -> None:
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_demo

    d = extract_demos(CAN_SESSION)[0]
    ghost = type(d)(**{**d.__dict__, "hand": "no_such_hand"})
    with pytest.raises(DexaugError, match="no_such_hand"):
        augment_demo(ghost, tmp_path, AugmentOptions(n=5, workers=1, gallery=0))
    assert not any(tmp_path.iterdir())   # nothing half-written


@needs_menagerie
@needs_ycb
def test_session_to_validated_dataset_and_report(shadow, tmp_path: Path) -> None:
    """A recorded session in, a dataset out: ≥ 20 grasps that pass lift-drop, joint angles
    within the demo-centred ranges, the report stating the dataset's numbers and the demo
    grasp's own verdict (the validator's); re-running skips the finished demo, and a summary
    written before the demo check still loads."""
    from augment.autows.params import load_autows_params
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_session
    from dexaug.pipeline.summary import demo_grasp_text, finished
    from sim.validate.batch import cached_validator

    # 40 grasps asked, ≥ 20 must pass: half of them (80 asked, ≥ 20 was a quarter); 39 pass
    opts = AugmentOptions(n=40, workers=2, time_budget_s=90.0, gallery=2)
    (s,) = augment_session(CAN_SESSION, tmp_path, opts)
    assert s.passed >= 20, s
    tables = dataset.load(s.dataset)
    t = tables["005_tomato_soup_can"]
    assert len(t) == s.passed and t["passed"].all()
    assert t.rejected is not None and len(t.rejected) == s.generated - s.passed
    assert all(r != "" for r in t.rejected["failure"])
    demo = extract_demos(CAN_SESSION)[0]
    ws = load_autows_params()
    span = math.radians(ws.demo_steps * ws.demo_step_deg) + 1e-6
    q = t["hand_pose"]
    for k, finger in enumerate(t.finger_names):
        idx = list(shadow.finger_qadr[finger])
        used = t["fingers_used"][:, k]
        assert (np.abs(q[used][:, idx] - demo.joints[idx]) <= span).all(), finger
        assert (q[~used][:, idx] == 0).all(), finger
    html = Path(s.report).read_text()
    shown = {m[0]: m[1] for m in re.findall(r"<td id='m-([a-z0-9-]+)'>([^<]*)</td>", html)}
    assert int(shown["grasps-passed-validation"]) == len(t)
    assert int(shown["grasps-generated-fsg"]) == len(t) + len(t.rejected)
    assert (Path(s.report).parent / "palm_cloud.png").stat().st_size > 1000
    # the demonstration's own grasp, validated beside the augmented ones (DESIGN §5): the
    # summary holds what the validator says of it, and the report states that verdict
    folder = Path(s.dataset).parent
    direct = cached_validator(demo.hand, demo.object).validate(demo.grasp, "lift-drop")
    verdict = json.loads((folder / "summary.json").read_text())["demo_grasp"]
    assert verdict["protocol"] == "lift-drop" and verdict["passed"] is direct.passed
    assert verdict["failure"] == (None if direct.failure is None else str(direct.failure))
    if direct.passed:
        assert verdict["displacement_m"] == pytest.approx(direct.displacement_m, rel=1e-6)
        assert verdict["rotation_deg"] == pytest.approx(math.degrees(direct.rotation_rad), rel=1e-6)
    assert shown["demonstration-grasp"] == demo_grasp_text(verdict)
    assert shown["demonstration-grasp"].startswith("passed —" if direct.passed else "failed (")
    assert f"Demonstration grasp: {demo_grasp_text(verdict)}" in html
    from sim.validate.config import VALIDATE_TOML
    assert t.attrs["config:validate.toml"] == VALIDATE_TOML.read_text()   # provenance
    again = augment_session(CAN_SESSION, tmp_path, opts)
    assert again[0].skipped and again[0].passed == s.passed
    assert again[0].demo_grasp == verdict
    # a summary.json from before the demo check (no field) is still a finished run
    old = json.loads((folder / "summary.json").read_text())
    del old["demo_grasp"]
    (folder / "summary.json").write_text(json.dumps(old))
    loaded = finished(folder, demo, opts)
    assert loaded is not None and loaded.demo_grasp is None and loaded.passed == s.passed
    assert demo_grasp_text(loaded.demo_grasp).startswith("not validated")
    # an interrupted run (no summary yet) is redone, never trusted
    (Path(s.dataset).parent / "summary.json").unlink()
    shutil.copy(s.dataset, tmp_path / "keep.h5")
    same = dataclasses.replace(opts, gallery=0)   # the same run key: only the summary is gone
    redo = augment_session(CAN_SESSION, tmp_path, same)
    assert not redo[0].skipped and redo[0].run_key == s.run_key
    assert redo[0].passed == s.passed and (Path(s.dataset).parent / "summary.json").is_file()


@needs_menagerie
@needs_ycb
def test_a_demo_grasp_that_cannot_be_validated_is_reported_not_raised() -> None:
    """The demo check is a diagnostic beside the augmentation: a demo grasp that penetrates,
    or that the validator cannot take at all, comes back failed with the reason, as plain
    JSON (no NaN, which the dashboard's browser cannot parse)."""
    from dexaug.pipeline.run import validate_demo_grasp

    demo = load_demo(REPO_ROOT / "recordings" / "demos" / "005_tomato_soup_can.json")
    inside = dataclasses.replace(demo, palm_pos_m=np.zeros(3))   # the palm in the can's centre
    assert validate_demo_grasp(demo.hand, demo.object, inside, "lift-drop") == {
        "protocol": "lift-drop", "passed": False, "failure": "penetration",
        "displacement_m": None, "rotation_deg": None}
    short = dataclasses.replace(demo, joints=demo.joints[:3])   # another hand's joint vector
    verdict = validate_demo_grasp(demo.hand, demo.object, short, "lift-drop")
    assert not verdict["passed"] and verdict["displacement_m"] is None
    assert re.match(r"not validated: .*expected \d+ joint values", verdict["failure"]), verdict
    json.dumps(verdict, allow_nan=False)


def test_run_key_follows_every_input(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A finished demo is skipped only when options, demo and configs are all unchanged."""

    from dexaug.pipeline import options as pipeline
    from dexaug.pipeline.options import AugmentOptions, run_key

    demo = load_demo(REPO_ROOT / "recordings" / "demos" / "005_tomato_soup_can.json")
    configs = []
    for path in pipeline.RESULT_CONFIGS:
        shutil.copy(path, tmp_path / path.name)
        configs.append(tmp_path / path.name)
    monkeypatch.setattr(pipeline, "RESULT_CONFIGS", tuple(configs))
    opts = AugmentOptions(n=50, workers=1, gallery=0)
    key = run_key(demo, opts)
    assert run_key(demo, dataclasses.replace(opts, workers=2, gallery=3)) == key
    assert run_key(demo, dataclasses.replace(opts, n=51)) != key
    moved = dataclasses.replace(demo, joints=demo.joints + 1e-3)
    assert run_key(moved, opts) != key
    configs[1].write_text(configs[1].read_text().replace("servo_kp_scale = 5.0",
                                                         "servo_kp_scale = 1.0"))
    assert run_key(demo, opts) != key


@needs_menagerie
@needs_ycb
def test_watch_mode_augments_finished_sessions_only(tmp_path: Path) -> None:
    """`dexaug augment --watch DIR`: a session still being written (it reads as truncated) is
    left alone; once complete it is augmented, and its summary appears."""
    import os
    import subprocess
    import sys
    import time

    watch, out = tmp_path / "incoming", tmp_path / "out"
    watch.mkdir()
    src = (REPO_ROOT / "recordings" / "demo_062_dice.mcap").read_bytes()
    target = watch / "dice.mcap"
    target.write_bytes(src[: len(src) // 2])          # a recorder mid-session
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    proc = subprocess.Popen([sys.executable, "-m", "dexaug", "augment", "--watch", str(watch),
                             "--poll", "0.5", "--n", "8", "--gallery", "0", "--workers", "2",
                             "--out", str(out)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    try:
        time.sleep(3.0)   # a negative check needs a window: six polls of the half file
        assert not list(out.glob("*/summary.json"))
        target.write_bytes(src)                       # the recorder closed it
        wait_for(lambda: list(out.glob("*/summary.json")), HANG_S, "the watched session's summary",
                 every_s=0.5, unless=lambda: None if proc.poll() is None
                 else f"augment --watch exited: {proc.stdout.read().decode()}")
        (summary,) = out.glob("*/summary.json")
        doc = json.loads(summary.read_text())
        assert doc["object"] == "062_dice" and doc["generated"] > 0
    finally:
        proc.terminate()
        proc.wait(10)


@needs_menagerie
@needs_ycb
def test_rerecord_gives_a_raw_session_state_contacts_and_its_marks(tmp_path: Path) -> None:
    """`dexaug rerecord`: every /hands frame of a raw-input session goes through the bridge
    (one state and one contact record each, deterministic mode) and its grasp_mark comes back."""
    from teleop.bridge.rerecord import rerecord
    from teleop.record.session import open_session

    src = open_session(RAW_SESSION)
    out = open_session(rerecord(RAW_SESSION, tmp_path / "full.mcap"))
    n = src.counts["/hands"]
    assert out.counts["/hands"] == n and out.counts["/state"] == n
    assert out.counts["/contacts"] == n and not out.truncated
    assert out.metadata["object"] == src.metadata["object"]
    marks = [e for _, e in out.events() if e["type"] == "grasp_mark"]
    assert len(marks) == sum(e["type"] == "grasp_mark" for _, e in src.events()) == 1
    assert not list(tmp_path.glob(".*.tmp"))   # written through a temporary name
