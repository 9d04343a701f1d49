"""``dexaug augment --arm``: each result's grasps put on an arm at a table, beside the dataset.

The end-to-end test is a real augmentation of the dice demo (6 grasps, one worker) with the
arm stage at one placement: the arm file holds a row per (placement, passing grasp), the
printed line and table state the file's own numbers, a re-run finds both the augmentation
and the arm file finished (so ``--arm`` changed neither the run key nor the dataset), and a
rewritten dataset makes the arm file stale and redone. The others check the stage without a
pipeline: a dataset without a passing grasp is skipped with one log line, files that are not
arm datasets are one-line errors (and listed, not hidden), and the options are checked before
any work.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import h5py
import numpy as np
import pytest

from augment import dataset
from dexaug.cli import build_parser, main
from dexaug.pipeline.arm_stage import (
    ArmFileError,
    arm_path,
    folder_arm_files,
    read_arm_file,
    run_arm_stage,
)
from sim.errors import DexaugError
from sim.paths import REPO_ROOT
from tests.conftest import needs_menagerie, needs_ycb
from tests.fake_results import arm_file_numbers, empty_dataset

pytestmark = pytest.mark.slow

DICE = REPO_ROOT / "recordings" / "demos" / "062_dice.json"


def _flat(text: str) -> str:
    """Console output with rich's line wrapping undone (every whitespace run one space)."""
    return " ".join(text.split())


@needs_menagerie
@needs_ycb
@pytest.mark.timeout(180)
def test_augment_with_arm_writes_the_arm_file_and_prints_its_numbers(tmp_path: Path,
                                                                     capsys) -> None:
    args = ["augment", str(DICE), "--n", "6", "--workers", "1", "--gallery", "0",
            "--out", str(tmp_path)]
    arm = ["--arm", "ur5e", "--arm-placements", "1"]
    assert main([*args, *arm]) == 0
    out = _flat(capsys.readouterr().out)
    (data,) = tmp_path.glob("*/grasps.h5")
    table = dataset.load(data)["062_dice"]
    path = arm_path(data.parent, "ur5e")
    pairs, passed, failures = arm_file_numbers(path)
    assert pairs == 1 * len(table) > 0          # one placement × every passing grasp
    with h5py.File(path, "r") as f:
        g = f["062_dice"]
        assert (g.attrs["arm"], g.attrs["placements"]) == ("ur5e", 1)
        assert sorted(set(g["grasp"][()])) == list(range(len(table)))
    failure_text = ", ".join(f"{k} {v}" for k, v in sorted(failures.items())) or "none"
    assert (f"on ur5e, {passed} of {pairs} (placement, grasp) pairs held "
            f"({100 * passed / pairs:.1f} %); failures {failure_text}; wrote") in out, out
    assert "grasps on an arm" in out and "demo_062_dice@0.38s" in out

    # a re-run without --arm skips the augmentation: --arm is not part of its run key
    mtime = path.stat().st_mtime_ns
    assert main(args) == 0
    assert "skipped (done)" in _flat(capsys.readouterr().out)
    # with --arm again: the arm file is already made from this dataset, kept as it is
    assert main([*args, *arm]) == 0
    out = _flat(capsys.readouterr().out)
    assert f"{passed} of {pairs} (placement, grasp) pairs held" in out and "already made" in out
    assert path.stat().st_mtime_ns == mtime

    # a dataset rewritten after it (a re-augmentation) makes it stale: listed so, made again
    earlier = data.stat().st_mtime_ns - 10**9
    os.utime(path, ns=(earlier, earlier))
    assert read_arm_file(path, data).stale
    outcome = run_arm_stage(data, "ur5e", placements=1)
    assert outcome.skipped is None and path.stat().st_mtime_ns > data.stat().st_mtime_ns
    assert not outcome.file.stale and arm_file_numbers(path) == (pairs, passed, failures)


def test_no_passing_grasp_skips_the_arm_stage_with_one_log_line(tmp_path: Path,
                                                                caplog) -> None:
    data = empty_dataset(tmp_path / "demo" / "grasps.h5")
    caplog.set_level(logging.INFO, logger="dexaug.pipeline.arm_stage")
    outcome = run_arm_stage(data, "ur5e", placements=3)
    assert outcome.file is None and outcome.skipped == "no passing grasp to put on the arm"
    assert not arm_path(data.parent, "ur5e").exists()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and "skipped" in lines[0] and "\n" not in lines[0], lines
    assert all(r.levelno == logging.INFO for r in caplog.records)


def test_files_that_are_not_arm_datasets_are_one_line_errors(tmp_path: Path) -> None:
    grasps = empty_dataset(tmp_path / "grasps.h5")
    junk = tmp_path / "arm_junk.h5"
    junk.write_bytes(b"not hdf5" * 10)
    with pytest.raises(DexaugError, match="not a readable arm dataset") as err:
        read_arm_file(junk)
    assert "\n" not in str(err.value)
    with pytest.raises(DexaugError, match=r"not an arm dataset \(format 'dexaug-grasps-1'"):
        read_arm_file(grasps)
    with h5py.File(tmp_path / "arm_ur5e.h5", "w") as f:    # the format, but no objects
        f.attrs["format"] = "dexaug-arm-grasps-1"
    listed = folder_arm_files(tmp_path)
    assert [type(x) for x in listed] == [ArmFileError, ArmFileError]   # listed, not hidden
    assert [x.path.name for x in listed] == ["arm_junk.h5", "arm_ur5e.h5"]
    assert "without objects" in listed[1].error


def test_a_hand_written_arm_file_is_summarised(tmp_path: Path) -> None:
    """The summary counts what the file holds: passes, failures by reason, no NaN share."""
    path = tmp_path / "arm_ur5e.h5"
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "dexaug-arm-grasps-1"
        for name, passed, failure in (("a", [True, False, False], [b"", b"table", b"slipped"]),
                                      ("b", [False], [b"table"])):
            g = f.create_group(name)
            g["passed"], g["failure"] = np.array(passed), np.array(failure, dtype="S16")
            g.attrs.update({"arm": "ur5e", "placements": 2, "seed": 0, "grasps_from": "carried",
                            "input": "x.h5"})
    s = read_arm_file(path)
    assert (s.pairs, s.passed, s.failures, s.objects) == (4, 1, {"table": 2, "slipped": 1},
                                                          ("a", "b"))
    assert s.pass_share == 0.25 and s.failures_text() == "slipped 1, table 2"
    assert s.to_json()["pass_share"] == 0.25 and not s.stale


def test_arm_options_are_checked_before_any_work(capsys) -> None:
    assert main(["augment", str(DICE), "--arm-placements", "3"]) == 2
    assert "--arm-placements needs --arm ARM" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main(["augment", str(DICE), "--arm", "no_such_arm"])
    assert exit_.value.code == 2 and "invalid choice: 'no_such_arm'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        build_parser("augment").parse_args(["augment", "--help"])
    text = _flat(capsys.readouterr().out)
    assert "--arm-placements N --arm: random resting placements" in text and "default 10" in text
    assert "Default: no arm stage" in text
