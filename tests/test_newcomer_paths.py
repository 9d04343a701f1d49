"""Issue #50, errors and conventions: what a newcomer meets on the first runs of ``dexaug``.

Each test pins one item: a listing without ``../shared``, outputs that cannot be written, an
unreachable ``--n``, the two servers' ports, logging options on either side of the subcommand,
"did you mean" for object names, damaged sessions, paths that are not datasets, the asset
listing's texture note, a replay with no bridge, an augmentation that finds no grasp, export
permissions, one ``--n`` default and a second ``dexaug demo``. Commands run in this process
(``dexaug.cli.main``) unless the item is about the process itself (no ``../shared``).
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from dexaug.cli import build_parser, main
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
DICE = REPO / "recordings" / "demo_062_dice.mcap"
SUGAR = REPO / "recordings" / "demo_004_sugar_box.mcap"
SYNTH = REPO / "recordings" / "synth_005_tomato_soup_can.mcap"


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``dexaug ARGV`` in this process: exit status (argparse's refusals included), stdout
    with rich's wrapping undone, stderr."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, " ".join(out.split()), err


def _help(command: str) -> str:
    """``dexaug COMMAND --help``, every whitespace run one space."""
    parser = build_parser(command)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return " ".join(sub.choices[command].format_help().split())


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


# ------------------------------------------------------------ 1. assets without ../shared

def test_assets_without_shared_lists_what_it_can_and_names_the_missing_assets(
        tmp_path: Path) -> None:
    """A checkout with no ``../shared`` beside it (a copy of the packages and configs in a
    temporary folder, no asset variables set): ``dexaug assets`` lists every hand and the
    primitives, marks the hands whose models are missing (Barrett's meshdir points into
    ../shared by a relative path) and says the YCB root is missing; no ValueError."""
    clone = tmp_path / "a" / "b" / "checkout"   # its ../../../../shared does not exist either
    clone.mkdir(parents=True)
    for part in ("dexaug", "sim", "augment", "teleop", "configs"):
        shutil.copytree(REPO / part, clone / part,
                        ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items()
           if k not in ("MENAGERIE_ROOT", "DEXAUG_YCB_ROOT", "PYTHONPATH")}
    env["MUJOCO_GL"] = os.environ.get("MUJOCO_GL", "egl")
    proc = subprocess.run([sys.executable, "-m", "dexaug", "assets"], cwd=clone, env=env,
                          capture_output=True, text=True, timeout=120)
    text = " ".join((proc.stdout + proc.stderr).split())
    assert proc.returncode == 0, text
    assert "ValueError" not in text and "Traceback" not in text, text
    for hand in ("barrett_bh8", "shadow_right", "allegro_right"):
        assert hand in text, text
    assert "missing assets" in text, text
    assert "barrett_hand/meshes" in text, text          # which folder Barrett needs
    for primitive in ("box", "cylinder", "sphere", "bowl"):
        assert primitive in text
    assert "0 of 0 YCB objects" in text or "no YCB objects" in text, text
    assert "DEXAUG_YCB_ROOT" in text


# ------------------------------------------------------------ 2. unwritable outputs

def _unwritable_folder(tmp_path: Path) -> Path:
    """A folder nothing can be created in: read-only for a normal user; as root (who writes
    through permissions) /sys, when this machine refuses root there too."""
    if os.geteuid() != 0:
        folder = tmp_path / "read-only"
        folder.mkdir()
        folder.chmod(0o555)
        return folder
    try:
        probe = Path("/sys") / f".dexaug-probe-{os.getpid()}"
        probe.touch()
        probe.unlink()
    except OSError:
        return Path("/sys")
    pytest.skip("no folder this (root) process cannot write")


UNWRITABLE_CASES = {
    "generate": ["generate", "--object", "cylinder", "--n", "2", "--workers", "1",
                 "--out", "{out}/g.h5"],
    "augment": ["augment", str(DICE), "--n", "2", "--workers", "1", "--out", "{out}/ds"],
    "batch": ["batch", "--objects", "cylinder", "--n", "2", "--workers", "1",
              "--out", "{out}/ds"],
    "synth": ["synth", "--object", "cylinder", "--out", "{out}/s.mcap"],
    "demo": ["demo", "--n", "2", "--out", "{out}/ds"],
}


@needs_menagerie
@pytest.mark.parametrize("where", ["read-only folder", "a file in the path"])
@pytest.mark.parametrize("command", list(UNWRITABLE_CASES))
def test_an_unwritable_output_is_refused_before_any_work(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        command: str, where: str) -> None:
    """The same refusal (status 2, one line naming the option and the path) from every
    command that writes results, before the search (FSG is replaced by a failure here: it
    must not be reached)."""
    import dexaug.pipeline.run as run
    import teleop.synthetic.synthesize as synthesize

    if where == "a file in the path":
        blocker = tmp_path / "notes.txt"
        blocker.write_text("a file, not a folder\n")
        out = blocker
    else:
        out = _unwritable_folder(tmp_path)

    def reached(*args: object, **kwargs: object) -> None:
        raise AssertionError("the expensive step ran before the output was checked")

    monkeypatch.setattr(run, "generate_grasps", reached)
    monkeypatch.setattr(run, "extract_demos", reached)
    monkeypatch.setattr(synthesize, "synthesize", reached)
    argv = [a.format(out=out) for a in UNWRITABLE_CASES[command]]
    code, _, err = _run(argv, capsys)
    line = _one_error_line(err)
    assert code == 2, line
    assert "--out" in line and str(out) in line, line
    assert "cannot write" in line, line


# ------------------------------------------------------------ 3. an unreachable --n

@needs_menagerie
def test_an_unreachable_n_is_warned_before_the_search_and_exits_non_zero(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(["generate", "--object", "cylinder", "--n", "1000000000", "--budget",
                         "1", "--validate", "none", "--workers", "1", "--out",
                         str(tmp_path / "g.h5")], capsys)
    assert code == 3, out
    warned = out.find("cannot be reached")
    assert 0 <= warned < out.find("FSG: "), out           # said before the search's report
    assert "fell short" in out and (tmp_path / "g.h5").is_file(), out   # still written
    text = _help("generate")
    assert "status 3" in text and "half" in text, text


# ------------------------------------------------------------ 4. the two servers' ports

def test_dashboard_and_foxglove_listen_on_different_default_ports() -> None:
    from dexaug.dashboard.server import DashboardConfig
    from teleop.bridge.foxglove_live import DEFAULT_PORT

    ui = build_parser("ui").parse_args(["ui"])
    bridge = build_parser("bridge").parse_args(["bridge"])
    assert bridge.foxglove_port == DEFAULT_PORT == 8765       # Foxglove's conventional port
    assert ui.port == DashboardConfig().port != DEFAULT_PORT
    assert f"default {ui.port}" in _help("ui")


# ------------------------------------------------------------ 5. logging options

@pytest.mark.parametrize(("argv", "level"), [
    (["-v", "assets"], logging.DEBUG),
    (["assets", "-v"], logging.DEBUG),
    (["assets", "--verbose"], logging.DEBUG),
    (["-q", "assets"], logging.WARNING),
    (["assets", "--quiet"], logging.WARNING),
    (["--log-level", "ERROR", "assets"], logging.ERROR),
    (["assets", "--log-level", "debug"], logging.DEBUG),
    (["assets"], logging.INFO),
])
def test_logging_options_work_before_and_after_the_subcommand(argv: list[str],
                                                              level: int) -> None:
    from dexaug.cli import _command_name, log_level

    assert _command_name(argv) == "assets"
    args = build_parser(_command_name(argv)).parse_args(argv)
    assert log_level(args) == level


# ------------------------------------------------------------ 6. did you mean

@needs_ycb
@pytest.mark.parametrize("argv", [
    ["generate", "--object", "005_tomato_soup_cann"],
    ["synth", "--object", "005_tomato_soup_cann", "--out", "{tmp}/x.mcap"],
    ["batch", "--objects", "005_tomato_soup_cann"],
    ["bridge", "--object", "tomato_soup_cann"],
], ids=lambda a: a[0])
def test_a_mistyped_object_name_suggests_the_close_one(
        argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = _run([a.format(tmp=tmp_path) for a in argv], capsys)
    line = _one_error_line(err)
    assert code == 2, line
    assert "did you mean" in line and "005_tomato_soup_can'" in line, line


@needs_menagerie
def test_a_mistyped_table_name_suggests_the_close_one(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.fake_results import empty_dataset

    data = empty_dataset(tmp_path / "grasps.h5")
    code, _, err = _run(["export", str(data), "--format", "npz", "--object", "062_dise",
                         "--out", str(tmp_path / "x.npz")], capsys)
    line = _one_error_line(err)
    assert code == 2 and "did you mean '062_dice'" in line, line


# ------------------------------------------------------------ 7. a damaged session

def _damaged_copy(tmp_path: Path) -> Path:
    from teleop.record.mcap_scan import scan_file

    with open(SUGAR, "rb") as f:
        blocks = scan_file(f, SUGAR.stat().st_size).blocks
    bad = blocks[len(blocks) // 2]
    data = bytearray(SUGAR.read_bytes())
    mid = bad.offset + bad.length // 2
    data[mid:mid + 4] = bytes(b ^ 0xFF for b in data[mid:mid + 4])
    path = tmp_path / "damaged.mcap"
    path.write_bytes(bytes(data))
    return path


def test_a_session_damaged_in_the_middle_suggests_dexaug_repair(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _damaged_copy(tmp_path)
    code, _, err = _run(["replay", str(path), "--connect", "1"], capsys)
    line = _one_error_line(err)
    assert code == 2 and "corrupt MCAP session" in line, line
    assert f"dexaug repair {path}" in line, line
    code, out, _ = _run(["augment", str(path), "--out", str(tmp_path / "ds")], capsys)
    assert code == 1 and f"dexaug repair {path}" in out, out


# ------------------------------------------------------------ 8. not a dataset

@pytest.mark.parametrize("argv", [
    ["export", "{p}", "--format", "npz", "--out", "{tmp}/x.npz"],
    ["view", "{p}"],
    ["diagnose", "{p}"],
    ["arm", "{p}"],
], ids=lambda a: a[0])
@pytest.mark.parametrize("what", ["directory", "junk", "missing"])
def test_a_path_that_is_not_a_dataset_is_one_clean_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
        what: str) -> None:
    p = tmp_path / "grasps.h5"
    if what == "directory":
        p.mkdir()
    elif what == "junk":
        p.write_text("not HDF5\n")
    code, _, err = _run([a.format(p=p, tmp=tmp_path) for a in argv], capsys)
    line = _one_error_line(err)
    assert code == 2, line
    assert "Errno" not in line and "synchronously" not in line and "h5py" not in line, line
    expected = {"directory": f"{p}: is a directory, expected a grasp dataset .h5 file",
                "junk": f"{p}: not an HDF5 file, expected a grasp dataset .h5 file",
                "missing": f"{p}: no such file, expected a grasp dataset .h5 file"}[what]
    assert expected in line, line


# ------------------------------------------------------------ 9. the asset listing

def _status(name: str, source: str, *, ok: bool = True, problem: str | None = None,
            warnings: tuple[str, ...] = ()):
    from sim.world.catalog import ObjectStatus

    return ObjectStatus(name, source, None, ok, problem, 0.1 if ok else None, list(warnings))


TEXTURE = ("texture file(s) missing (assets/texture_map.png): dropped texture(s) ['t'] and "
           "material(s) ['m']; geoms keep a plain colour")


def test_assets_notes_missing_textures_once_and_shows_broken_rows_distinctly(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import sim.hand.config
    import sim.world.catalog

    statuses = [_status(p, "primitive") for p in ("box", "cylinder", "sphere", "bowl")] + [
        _status(f"00{i}_thing", "ycb", warnings=(TEXTURE,)) for i in range(3)] + [
        _status("009_broken", "ycb", ok=False, problem="MuJoCo cannot compile the object")]
    monkeypatch.setattr(sim.world.catalog, "list_objects", lambda: statuses)
    monkeypatch.setattr(sim.hand.config, "hand_names", lambda: [])
    code, out, _ = _run(["assets"], capsys)
    assert code == 0
    assert out.count("texture") == 1, out                 # one note, not one per row
    assert "3 of 4 YCB objects load, 1 broken: 009_broken" in out, out
    assert re.search(r"009_broken\s*│\s*ycb\s*│[^│]*│\s*broken", out), out   # its row


def test_missing_textures_are_logged_once_per_run_not_once_per_worker(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """FSG's and the validator's worker processes load the object too: only the process that
    runs the command warns (a worker logs the same at DEBUG)."""
    import multiprocessing

    import sim.world.objects as objects
    from sim.paths import ycb_root

    root = ycb_root(required=False)
    if root is None or not (root / "002_master_chef_can").is_dir():
        pytest.skip("no YCB 002_master_chef_can (an object with missing textures)")
    xml = objects.find_object_xml(root / "002_master_chef_can")
    monkeypatch.setattr(objects, "_WARNED_TEXTURES", set())
    monkeypatch.setattr(multiprocessing, "parent_process", lambda: object())   # a worker
    caplog.set_level(logging.DEBUG, logger="sim.world.objects")
    asset = objects.load_object_xml(xml)
    assert asset.warnings
    texture = [r for r in caplog.records if "texture" in r.getMessage()]
    assert texture and all(r.levelno == logging.DEBUG for r in texture)


# ------------------------------------------------------------ 10. replay with no bridge

def _free_port() -> int:
    from teleop.keys import free_tcp_port

    return free_tcp_port()


def test_replay_with_no_bridge_listening_exits_non_zero(
        capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = _run(["replay", str(SYNTH), "--connect", str(_free_port()), "--rate", "max",
                         "--wait-bridge-s", "1"], capsys)
    line = _one_error_line(err)
    assert code == 2, line
    assert "no bridge" in line and "dexaug bridge" in line and "--wait-bridge-s" in line, line


def test_replay_publishes_once_a_subscriber_is_there(
        capsys: pytest.CaptureFixture[str]) -> None:
    from teleop import keys as zkeys

    port = _free_port()
    got: list[bytes] = []
    with zkeys.open_session(port, ()) as peer:
        sub = peer.declare_subscriber(zkeys.RigKeys("local").hands,
                                      lambda sample: got.append(bytes(sample.payload)))
        code, out, err = _run(["replay", str(SYNTH), "--connect", str(port), "--rate", "max"],
                              capsys)
        sub.undeclare()
    assert code == 0, err
    assert "replayed" in out and got, out


# ------------------------------------------------------------ 11. FSG finds no grasp

@needs_menagerie
@needs_ycb
def test_augment_with_no_grasp_says_why_writes_the_report_and_exits_non_zero(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A budget far too small for one grasp (forces zero cheaply, on a real demo)."""
    code, out, _ = _run(["augment", str(DICE), "--budget", "0.001", "--workers", "1", "--n",
                         "5", "--gallery", "1", "--out", str(tmp_path)], capsys)
    assert code == 3, out
    assert out.count("FSG found no grasp for this demo: ") == 1, out
    why = out.split("FSG found no grasp for this demo: ", 1)[1]
    assert "time budget" in why[:200], why[:200]
    (report,) = tmp_path.glob("*/report.html")
    assert (report.parent / "summary.json").is_file()
    assert "status 3" in _help("augment")


# ------------------------------------------------------------ 12. conventions

@needs_menagerie
def test_bodex_export_folder_gets_the_usual_permissions(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from augment import dataset
    from sim.hand.model import Hand

    hand = Hand.load("shadow_right")
    table = dataset.from_fsg([], hand.joint_names, hand.finger_names, [],
                             attrs={"hand": hand.name})
    data = tmp_path / "grasps.h5"
    dataset.save(data, {"062_dice": table})
    umask = os.umask(0o022)
    try:
        code, _, err = _run(["export", str(data), "--format", "bodex", "--out",
                               str(tmp_path / "bodex")], capsys)
    finally:
        os.umask(umask)
    assert code == 0, err
    assert (tmp_path / "bodex").stat().st_mode & 0o777 == 0o755


def test_every_command_asks_for_the_same_number_of_grasps_by_default() -> None:
    from dexaug.commands.options import DEFAULT_GRASPS

    defaults = {
        "generate": build_parser("generate").parse_args(["generate", "--object", "box"]).n,
        "augment": build_parser("augment").parse_args(["augment"]).n,
        "batch": build_parser("batch").parse_args(["batch"]).n,
        "ui": build_parser("ui").parse_args(["ui"]).n,
        "demo": build_parser("demo").parse_args(["demo"]).n,
        "bridge --augment-n": build_parser("bridge").parse_args(["bridge"]).augment_n,
    }
    assert set(defaults.values()) == {DEFAULT_GRASPS}, defaults


def test_a_second_demo_run_does_not_overwrite_the_first(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """`dexaug demo` twice: the second run writes beside the first and says where; with
    --overwrite it replaces it. The bridge replay and the augmentation are replaced by stubs
    that write a result folder as the pipeline does (the decision is the command's)."""
    import json

    import dexaug.pipeline.run as run
    import teleop.bridge.rerecord as rerecord
    import teleop.record.demos as demos
    import teleop.record.session as session_mod
    from dexaug.pipeline.options import demo_dir
    from sim.demo import Demo

    recording = SimpleNamespace(counts={"/hands": 1, "/state": 1, "/contacts": 1},
                                metadata={"object": "cylinder"})
    monkeypatch.setattr(session_mod, "open_session", lambda path: recording)
    monkeypatch.setattr(rerecord, "rerecord", lambda src, out, **kw: out)
    demo = Demo.__new__(Demo)
    object.__setattr__(demo, "id", "demo_cylinder@1.00s")
    monkeypatch.setattr(demos, "extract_demos", lambda path: [demo])
    written: list[Path] = []

    def fake_augment(path, out_root, opts, **kwargs):
        folder = demo_dir(out_root, demo)
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "summary.json").write_text(json.dumps({"run": len(written)}))
        written.append(folder)
        return []

    monkeypatch.setattr(run, "augment_session", fake_augment)
    out = tmp_path / "datasets"
    argv = ["demo", "--session", str(DICE), "--out", str(out)]
    assert _run(argv, capsys)[0] == 0
    first = written[-1]
    code, text, _ = _run(argv, capsys)
    assert code == 0
    second = written[-1]
    assert second != first and json.loads((first / "summary.json").read_text()) == {"run": 0}
    assert str(first) in text and str(second.parent) in text and "--overwrite" in text, text
    assert _run([*argv, "--overwrite"], capsys)[0] == 0
    assert written[-1] == first and json.loads((first / "summary.json").read_text()) == {
        "run": 2}


def test_version_names_every_package_that_shapes_a_result() -> None:
    """``--version`` (and every dataset's provenance) names the packages a grasp or a recording
    depends on, foxglove-sdk, trimesh and highspy included (they were missing)."""
    from dexaug.cli import version_text

    text = version_text()
    for name in ("mujoco", "mink", "highspy", "trimesh", "foxglove-sdk", "mcap", "eclipse-zenoh"):
        assert f"{name} " in text, (name, text)
