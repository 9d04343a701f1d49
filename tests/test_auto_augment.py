"""A session recorded live by the bridge from a replayed operator gives a demo, and
``--auto-augment`` turns it into a dataset — the product's loop, end to end.

The operator is the synthetic one of ``tests/test_demo_extraction.py`` (its sugar-box grasp,
replayed onto zenoh loopback into a real bridge); the bridge's recording-closed hook is the one
``dexaug bridge --auto-augment`` installs, which starts ``dexaug augment`` in its own process."""

from __future__ import annotations

from pathlib import Path

import pytest
from rich.console import Console

from augment import dataset
from dexaug.commands.teleop import _auto_augment
from teleop.record.demos import extract_demos
from tests.conftest import HANG_S, needs_menagerie, needs_ycb, wait_for
from tests.test_demo_extraction import OBJECT, _record

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb]


def test_a_live_recording_is_augmented_into_a_dataset(tmp_path: Path) -> None:
    out = tmp_path / "datasets"
    hook = _auto_augment(out, Console(quiet=True), ("--n", "8", "--budget", "40", "--gallery", "0"))
    session = _record(tmp_path / "live.mcap", mark=False, on_recording_closed=hook)
    (demo,) = extract_demos(session)
    assert "thumb" in demo.fingers and len(demo.fingers) >= 2
    summaries = wait_for(lambda: list(out.glob("*/summary.json")), HANG_S,
                         lambda: "a summary; augment log:\n"
                         + (out / f"{session.stem}.augment.log").read_text(), every_s=0.5)
    tables = dataset.load(summaries[0].parent / "grasps.h5")
    table = tables[OBJECT]
    assert len(table) + (len(table.rejected) if table.rejected is not None else 0) > 0
    assert set(table["demo_id"]) <= {demo.id}
