"""Asset roots: a missing root is one clear error naming the variable and the path."""

from __future__ import annotations

from pathlib import Path

import pytest

from sim.errors import AssetError
from sim.hand.model import Hand
from sim.paths import MENAGERIE_ENV, YCB_ENV, ensure_menagerie_root, ycb_root
from sim.world.objects import load_object


def test_missing_ycb_root_names_variable_and_path(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    missing = tmp_path / "nowhere"
    monkeypatch.setenv(YCB_ENV, str(missing))
    assert ycb_root(required=False) is None
    with pytest.raises(AssetError, match=rf"{YCB_ENV}={missing}.* is not a directory"):
        load_object("004_sugar_box")
    # primitives need no asset root
    assert load_object("cylinder").mass_kg > 0


def test_missing_menagerie_root_names_variable_and_path(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    missing = tmp_path / "no_menagerie"
    monkeypatch.setenv(MENAGERIE_ENV, str(missing))
    with pytest.raises(AssetError, match=rf"{MENAGERIE_ENV}={missing} is not a directory"):
        ensure_menagerie_root()
    with pytest.raises(AssetError, match=MENAGERIE_ENV):
        Hand.load("shadow_right")


def test_menagerie_root_without_the_robot_is_a_clear_error(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(MENAGERIE_ENV, str(tmp_path))
    with pytest.raises(AssetError, match=r"shadow_right/hand\.toml: cannot resolve Menagerie model "
                                         r"'shadow_hand'.*not found under MENAGERIE_ROOT"):
        Hand.load("shadow_right")
