"""Two augment runs of one demo into one output folder at once (issue #56): one computes and
writes, the other waits for it (``dexaug.pipeline.result_lock``) and skips the finished demo;
the folder ends with one complete, loadable ``grasps.h5`` and a ``summary.json`` that describes
exactly that file.

Each run is ``augment_demo`` in a process of its own (the real pipeline, 3 grasps, no
validation, no report images: a few seconds each). The overlap is made by events, not by
timing: run A's FSG stage is held at a gate until run B has either entered FSG too (what
happened before the lock: both compute, then interleave their writes) or says it waits for A.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sim.paths import REPO_ROOT
from tests.conftest import HANG_S, SOON_S, needs_menagerie, needs_ycb, wait_for

pytestmark = pytest.mark.slow

DICE = REPO_ROOT / "recordings" / "demo_062_dice.mcap"

#: one run: argv = session, out, tag, gate folder. Marks ``<tag>.computing`` when its FSG stage
#: starts and waits there for ``go``; writes the summary it returned to ``<tag>.json``
CHILD = r"""
import json, logging, sys, time
from pathlib import Path
logging.basicConfig(level=logging.INFO, stream=sys.stderr)
from dexaug.pipeline import run
from dexaug.pipeline.options import AugmentOptions
from teleop.record.demos import extract_demos

session, out, tag, gate = sys.argv[1:5]
gate = Path(gate)
real = run.compute_fsg

def gated(*args, **kwargs):
    (gate / f"{tag}.computing").touch()
    while not (gate / "go").exists():   # the test opens the gate on an event, never a guess
        time.sleep(0.02)
    return real(*args, **kwargs)

run.compute_fsg = gated
(demo,) = extract_demos(session)
opts = AugmentOptions(n=3, workers=1, gallery=0, validate=None, time_budget_s=5.0)
s = run.augment_demo(demo, out, opts)
(gate / f"{tag}.json").write_text(json.dumps({**s.to_json(), "skipped": s.skipped}))
"""


def _start(tmp_path: Path, tag: str, out: Path, gate: Path) -> tuple[subprocess.Popen, Path]:
    log = tmp_path / f"{tag}.log"
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    with log.open("wb") as f:
        proc = subprocess.Popen([sys.executable, "-c", CHILD, str(DICE), str(out), tag, str(gate)],
                                cwd=REPO_ROOT, env=env, stdout=f, stderr=subprocess.STDOUT)
    return proc, log


def _exited(proc: subprocess.Popen, log: Path) -> str | None:
    if proc.poll() is None:
        return None
    return f"run exited with status {proc.returncode}: {log.read_text()[-2000:]}"


@needs_menagerie
@needs_ycb
@pytest.mark.timeout(HANG_S)
def test_two_runs_of_one_demo_leave_one_complete_result(tmp_path: Path) -> None:
    from augment import dataset
    from augment.dataset import grasp_count

    out, gate = tmp_path / "out", tmp_path / "gate"
    gate.mkdir()
    a, a_log = _start(tmp_path, "a", out, gate)
    b = None
    try:
        wait_for(lambda: (gate / "a.computing").exists(), HANG_S, "run A's FSG stage",
                 unless=lambda: _exited(a, a_log))
        b, b_log = _start(tmp_path, "b", out, gate)
        # B either computes too (no lock) or waits for A's lock: either ends this wait
        wait_for(lambda: (gate / "b.computing").exists() or "waiting for it" in b_log.read_text(),
                 HANG_S, "run B computing or waiting for run A",
                 unless=lambda: _exited(b, b_log))
        (gate / "go").touch()
        for proc, log in ((a, a_log), (b, b_log)):
            proc.wait(HANG_S)
            assert proc.returncode == 0, log.read_text()[-3000:]
    finally:
        (gate / "go").touch()
        for proc in (a, b):
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.wait(SOON_S)

    computed = sorted(p.name for p in gate.glob("*.computing"))
    assert computed == ["a.computing"], f"both runs computed the demo at once: {computed}"
    ra, rb = (json.loads((gate / f"{t}.json").read_text()) for t in "ab")
    assert not ra["skipped"] and rb["skipped"], (ra["skipped"], rb["skipped"])
    (folder,) = [p for p in out.iterdir() if p.is_dir()]
    summary = json.loads((folder / "summary.json").read_text())
    data = dataset.load(folder / "grasps.h5")
    (table,) = data.values()
    assert summary["run_key"] == ra["run_key"] == rb["run_key"] == table.attrs["run_key"]
    assert grasp_count(table) == summary["generated"] == ra["generated"] == rb["generated"]
    assert summary["timings_s"] == ra["timings_s"] == rb["timings_s"]   # one run's, not a mix
    assert not list(folder.glob(".*.tmp")), "a temp file was left behind"
    assert not (folder / ".lock").exists(), "the result lock was left behind"


def test_the_lock_reenters_and_leaves_nothing_behind(tmp_path: Path) -> None:
    """A thread holding a folder's lock takes it again without waiting on itself
    (``augment_demo`` around ``write_result``); released, it leaves no lock file, and no folder
    when nothing was written into one it made."""
    from dexaug.pipeline.result_lock import LOCK_NAME, result_lock

    folder = tmp_path / "demo"
    with result_lock(folder, "demo"):
        assert (folder / LOCK_NAME).exists()
        with result_lock(folder, "demo"):
            pass
        assert (folder / LOCK_NAME).exists()   # the inner exit released nothing
    assert not folder.exists()
    with result_lock(folder, "demo"):
        (folder / "summary.json").write_text("{}")
    assert sorted(p.name for p in folder.iterdir()) == ["summary.json"]
