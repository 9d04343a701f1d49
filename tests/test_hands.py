"""Every hand folder (``configs/hands/<hand>/``), each on its own: it loads, follows the palm-frame
convention, has a workspace, yields FSG grasps that the validator takes, and has a model card.
No hand's name appears in the code outside its folder; the default hand comes from one file."""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pytest

from sim.errors import ConfigError
from sim.hand import config as hand_config
from sim.hand.config import default_hand_name, hand_dir, hand_names, load_hand_config
from sim.hand.conventions import closed_posture, palm_frame_problems
from sim.hand.model import Hand
from sim.paths import REPO_ROOT
from tests.conftest import needs_menagerie

pytestmark = pytest.mark.slow

HANDS = hand_names()
OBJECT = "cylinder"   # procedural: no YCB needed, and quick to validate


@pytest.fixture(scope="module")
def hands() -> dict[str, Hand]:
    return {name: Hand.load(name) for name in HANDS}


def test_there_are_hands_and_a_default() -> None:
    assert len(HANDS) >= 2
    assert default_hand_name() in HANDS


def test_a_bad_default_hand_names_the_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "default.toml"
    monkeypatch.setattr(hand_config, "DEFAULT_HAND_FILE", path)
    with pytest.raises(ConfigError, match=r"default\.toml: config file not found"):
        default_hand_name()
    path.write_text('hand = "no_such_hand"\n')
    with pytest.raises(ConfigError, match=r"default\.toml: hand: no hand folder .*no_such_hand"):
        default_hand_name()


@pytest.mark.parametrize("name", HANDS)
def test_folder_has_config_and_model_card(name: str) -> None:
    folder = hand_dir(name)
    assert (folder / "hand.toml").is_file()
    card = (folder / "README.md").read_text()
    cfg = load_hand_config(name)
    assert cfg.name == name
    for finger in cfg.fingers:      # the card describes every finger
        assert finger.name in card


@needs_menagerie
@pytest.mark.parametrize("name", HANDS)
def test_hand_loads_with_its_reference_grasps(name: str, hands: dict[str, Hand]) -> None:
    from sim.hand.reference_grasps import load_reference_grasps

    hand = hands[name]
    assert hand.name == name and hand.finger_names
    assert np.isfinite(hand.fingertip_sites(hand.open_pose)).all()
    if (hand_dir(name) / "grasps.toml").is_file():
        refs = load_reference_grasps(hand)
        assert refs and all(r.grasp.joints.shape == (hand.nq,) for r in refs)


@needs_menagerie
@pytest.mark.parametrize("name", HANDS)
def test_palm_frame_follows_the_convention(name: str, hands: dict[str, Hand]) -> None:
    assert palm_frame_problems(hands[name]) == []


@needs_menagerie
def test_convention_check_flags_a_turned_palm_frame(hands: dict[str, Hand]) -> None:
    """The same hand with frame_palm turned 180° about its z axis (+y into the hand) fails."""
    from sim.transforms import quat_mul

    for hand in hands.values():
        palm = hand.config.palm
        turned = dataclasses.replace(palm, quat_wxyz=quat_mul(palm.quat_wxyz, np.array([0.0, 0, 0, 1])))
        wrong = dataclasses.replace(hand.config, palm=turned)
        with pytest.raises(ConfigError, match=rf"{re.escape(str(hand.config.file))}: palm.*"
                                              "pulps lie behind the palm face"):
            Hand(wrong)   # refused on load, naming the file and the reason
        flipped = Hand(wrong, check_conventions=False)
        problems = palm_frame_problems(flipped)
        assert any("pulps lie behind the palm face" in p for p in problems), (hand.name, problems)
        assert any("face away from the palm face" in p for p in problems), (hand.name, problems)
        assert closed_posture(flipped).shape == (hand.nq,)


@needs_menagerie
@pytest.mark.parametrize("name", HANDS)
def test_workspace_fsg_and_validation(name: str, hands: dict[str, Hand]) -> None:
    from augment.autows.build import build_workspace
    from augment.object_cloud import object_cloud
    from dexaug.pipeline.run import generate_grasps
    from sim.validate.batch import validate_many
    from sim.validate.config import PROTOCOLS
    from sim.world.objects import load_object

    hand = hands[name]
    ws = build_workspace(hand, cache=False)
    assert ws.finger_names == hand.finger_names
    assert all(f.n_points > 0 and f.n_faces > 0 for f in ws.fingers)
    obj = load_object(OBJECT)
    res = generate_grasps(hand, object_cloud(obj), ws, n=2, seed=0, time_budget_s=10.0, workers=1)
    assert res.grasps, res.stats
    for g in res.grasps:
        assert np.all(g.grasp.joints >= hand.lower - 1e-9) and np.all(g.grasp.joints <= hand.upper + 1e-9)
    for protocol in PROTOCOLS:   # placement → simulation → verdict, every protocol
        results = validate_many(hand.name, obj.name, [g.grasp for g in res.grasps], protocol,
                                workers=1)
        assert len(results) == len(res.grasps)
        assert all(r.protocol == protocol and (r.passed == (r.failure is None)) for r in results)
        assert all(r.pregrasp is not None and r.pregrasp.shape == (hand.nq,) for r in results
                   if r.failure != "penetration")


# ------------------------------------------------------------------- no hand names in the code

def hand_name_mentions(paths: Iterable[Path], names: Iterable[str], root: Path) -> list[str]:
    """``path:line: name`` for every line of ``paths`` that holds one of the hand ``names``."""
    names = list(names)
    found = []
    for path in paths:
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            found += [f"{path.relative_to(root)}:{number}: {n}" for n in names if n in line]
    return found


#: the reference paper's configs name the hand its tables are of (its §5: the Shadow Hand), a
#: fact about the paper, stated once there (issue #51), not hand knowledge spread in code
PAPER_CONFIGS = "configs/paper/"


def _code_files() -> list[Path]:
    """Tracked and new (not ignored) ``*.py`` / ``*.toml`` files outside ``configs/hands/``,
    :data:`PAPER_CONFIGS` and ``tests/``."""
    if shutil.which("git") is None or not (REPO_ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z",
                          "--", "*.py", "*.toml"], cwd=REPO_ROOT, capture_output=True, check=True)
    rel = sorted({p for p in out.stdout.decode().split("\0") if p})
    return [REPO_ROOT / p for p in rel
            if not p.startswith(("configs/hands/", "tests/", PAPER_CONFIGS))
            and (REPO_ROOT / p).is_file()]


def test_mention_scan_finds_a_hand_name(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text(f'x = 1\nHAND = "{HANDS[0]}"\n')
    (tmp_path / "b.toml").write_text('hand = "someone_else"\n')
    paths = [tmp_path / "a.py", tmp_path / "b.toml"]
    assert hand_name_mentions(paths, HANDS, tmp_path) == [f"a.py:2: {HANDS[0]}"]


def test_no_hand_name_outside_its_folder() -> None:
    files = _code_files()
    assert any(p.name == "cli.py" for p in files)   # the scan sees the code
    mentions = hand_name_mentions(files, HANDS, REPO_ROOT)
    assert not mentions, ("hand names belong in configs/hands/<hand>/ (use "
                          "sim.hand.config.default_hand_name() or hand_names()):\n"
                          + "\n".join(mentions))
