"""The sessions committed under ``recordings/`` are what a newcomer tries first: each is
described in its README, each either replays through the bridge or says why not, and the synthetic
session reaches for the object where the bridge puts it.

Why a test: the README promised that any recorded session replays while the four committed
ones could not (scripted robot states, no ``/hands``), and the committed synthetic session kept
an object spot 10 cm past the bridge's long after the operator's default moved.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from teleop.bridge.config import BridgeConfig
from teleop.record.demos import extract_demos
from teleop.record.schemas import TOPIC_HANDS
from teleop.record.session import open_session
from tests.conftest import needs_menagerie, needs_ycb, run_dexaug

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
RECORDINGS = sorted((REPO / "recordings").glob("*.mcap"))
BRIDGE_SAMPLE = REPO / "recordings" / "bridge_043_phillips_screwdriver.mcap"


def test_every_committed_session_is_described_in_the_readme() -> None:
    readme = (REPO / "recordings" / "README.md").read_text()
    assert RECORDINGS
    assert [p.name for p in RECORDINGS if p.name not in readme] == []


@pytest.mark.parametrize("path", RECORDINGS, ids=[p.stem for p in RECORDINGS])
def test_a_committed_session_replays_or_says_it_is_scripted(path: Path) -> None:
    """A session with hand frames is replayable; a scripted one (robot states only) is refused
    by ``replay`` with one line that says so and names a committed session that replays."""
    session = open_session(path)
    if session.counts.get(TOPIC_HANDS):
        assert session.metadata.get("scripted") is not True
        return
    assert session.metadata.get("scripted") is True, f"{path.name}: no {TOPIC_HANDS}, not scripted"
    proc = run_dexaug("replay", str(path), "--connect", "1")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "a scripted demonstration" in lines[0] and BRIDGE_SAMPLE.name in lines[0], lines[0]


@needs_menagerie
@needs_ycb
def test_the_committed_bridge_recording_replays_through_the_bridge(tmp_path: Path) -> None:
    """Its hand frames, run through the bridge again (``rerecord``: the same bridge, in-process,
    deterministic), give a demo with the fingers of the recorded one."""
    (recorded,) = extract_demos(BRIDGE_SAMPLE)
    out = tmp_path / "again.mcap"
    proc = run_dexaug("rerecord", str(BRIDGE_SAMPLE), str(out))
    assert proc.returncode == 0, proc.stderr
    again = extract_demos(out)
    assert [d.fingers for d in again] == [recorded.fingers]
    assert {"thumb"} < set(recorded.fingers)


def test_the_synthetic_session_reaches_for_the_bridges_object_spot() -> None:
    """``recordings/synth_*.mcap`` puts the object where the bridge places it on the table."""
    for path in (REPO / "recordings").glob("synth_*.mcap"):
        spot = np.asarray(open_session(path).metadata["object_pos_m"], float)[:2]
        np.testing.assert_allclose(spot, BridgeConfig().object_pos_m, atol=1e-9,
                                   err_msg=path.name)
