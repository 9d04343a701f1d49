"""The `dexaug` command: subcommands run end to end on real assets and report what they did."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from dexaug.cli import build_parser, main
from sim.world.render import gl_available
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow


def test_help_lists_every_subcommand(capsys) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    out = capsys.readouterr().out
    for name in ("assets", "validate", "workspace", "retarget", "synth", "demo", "generate",
                 "augment", "bench", "rerecord"):
        assert name in out


@needs_menagerie
@needs_ycb
def test_assets_reports_broken_objects(capsys) -> None:
    assert main(["assets", "--broken"]) == 0
    out = capsys.readouterr().out
    assert "073_a_lego_duplo" in out and "broken" in out
    assert "shadow_right" in out


@needs_menagerie
@needs_ycb
def test_validate_writes_json_matching_the_table(tmp_path: Path, capsys) -> None:
    out_json = tmp_path / "results.json"
    code = main(["validate", "--object", "005_tomato_soup_can", "--protocol", "lift-drop",
                 "--json", str(out_json)])
    assert code == 0
    rows = json.loads(out_json.read_text())
    assert [(r["grasp"], r["protocol"], r["passed"]) for r in rows] == [
        ("can_side_wrap", "lift-drop", True)]
    assert "1/1 validations passed" in capsys.readouterr().out


@needs_menagerie
def test_retarget_reports_errors_of_the_quest_capture(tmp_path: Path, capsys) -> None:
    from sim.paths import SHARED_ASSETS

    capture = SHARED_ASSETS / "handdata" / "quest3_webxr" / "cap.min.js"
    if not capture.is_file():
        pytest.skip("no Quest capture in ../shared/assets")
    out = tmp_path / "trace.npz"
    assert main(["retarget", str(capture), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "757 frames" in text and "forefinger" in text
    import numpy as np

    trace = np.load(out)
    assert trace["q"].shape == (757, 24)


@needs_menagerie
@needs_ycb
def test_synth_session_retargets(tmp_path: Path, capsys) -> None:
    session = tmp_path / "synth.mcap"
    assert main(["synth", "--object", "005_tomato_soup_can", "--out", str(session)]) == 0
    assert main(["retarget", str(session)]) == 0
    out = capsys.readouterr().out
    assert "533 frames over 7.4 s" in out and "imitating can_side_wrap" in out   # settle 0.8 s
    assert "533 frames," in out  # the retargeter read every recorded frame back


def test_hand_default_comes_from_the_default_file(capsys) -> None:
    from sim.hand.config import default_hand_name

    for command in ("validate", "workspace", "generate", "retarget", "synth", "bridge"):
        with pytest.raises(SystemExit):
            build_parser().parse_args([command, "--help"])
        out = " ".join(capsys.readouterr().out.split())
        assert f"default {default_hand_name()}" in out, command
    args = build_parser().parse_args(["validate"])
    assert args.hand == default_hand_name()


def test_unknown_hand_is_one_line_error(capsys) -> None:
    assert main(["validate", "--hand", "no_such_hand"]) == 2
    err = capsys.readouterr().err
    assert "unknown hand 'no_such_hand'" in err and "Traceback" not in err


@needs_menagerie
@needs_ycb
@pytest.mark.skipif(gl_available() is None, reason="no OpenGL backend (egl/osmesa)")
def test_validate_render_writes_png(tmp_path: Path) -> None:
    # a fresh process: MuJoCo must be imported after MUJOCO_GL is chosen
    proc = subprocess.run([sys.executable, "-m", "dexaug", "validate", "--object",
                           "004_sugar_box", "--protocol", "lift-drop", "--render", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    import numpy as np
    from PIL import Image

    image = np.asarray(Image.open(tmp_path / "box_edge_wrap.png").convert("RGB"))
    assert image.shape == (480, 640, 3)
    assert image.std() > 10  # not a blank frame


@needs_menagerie
@needs_ycb
def test_generate_writes_and_appends_a_dataset(tmp_path: Path, capsys) -> None:
    """`dexaug generate` with a demo: grasps validated and split into kept/rejected; a second
    run appends; an unreachable --n ends at the time budget with the shortfall reported."""
    from augment import dataset
    from sim.paths import REPO_ROOT

    out = tmp_path / "g.h5"
    demo = REPO_ROOT / "recordings" / "demos" / "062_dice.json"
    args = ["generate", "--object", "062_dice", "--demo", str(demo), "--workers", "1",
            "--out", str(out)]
    assert main([*args, "--n", "6"]) == 0
    t = dataset.load(out)["062_dice"]
    first = len(t) + len(t.rejected)
    assert first == 6 and t["passed"].all()
    assert set(t["demo_id"]) == {"demo_062_dice@0.38s"}
    options = json.loads(t.attrs["options"])          # every option is kept, and the demo
    assert options["n"] == 6 and options["workers"] == 1 and options["demo"] == str(demo)
    assert json.loads(t.attrs["demo"])["id"] == "demo_062_dice@0.38s"
    # an existing dataset is never appended to by surprise: refused before any work
    capsys.readouterr()
    assert main([*args, "--n", "6"]) == 2
    err = capsys.readouterr().err
    assert "already holds 6 grasps" in err and "--append" in err and len(err.strip().splitlines()) == 1
    assert main([*args, "--append", "--seed", "1", "--n", "100000", "--budget", "2",
                 "--validate", "none"]) == 3   # written, but fewer than half of --n
    text = capsys.readouterr().out
    assert "shortfall" in text and "time budget" in text
    t2 = dataset.load(out)["062_dice"]
    assert len(t2) > len(t)   # appended, unvalidated grasps land in the main table
    # the same run again (same seed, same grasps) is refused: no exact duplicates, file intact
    before = out.read_bytes()
    assert main([*args, "--append", "--n", "6"]) == 2
    assert "duplicate" in capsys.readouterr().err and out.read_bytes() == before
    t3 = dataset.load(out)["062_dice"]
    assert (len(t3), len(t3.rejected)) == (len(t2), len(t2.rejected))
    assert len(repr(t3)) < 1000 and f"{len(t3)} grasps" in repr(t3)
    code = main(["generate", "--object", "062_dice", "--demo", "no_such_grasp", "--n", "1"])
    assert code == 2
