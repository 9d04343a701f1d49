"""Shared fixtures: assets resolve from ../shared/assets (or the env variables), and tests that
need them skip cleanly where they are absent."""

from __future__ import annotations

import dataclasses
import os

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from sim.paths import SHARED_ASSETS, ensure_menagerie_root, ycb_root
from tests.browser import chromium  # noqa: F401  (one session-wide browser for every module)


def _menagerie_available() -> bool:
    root = ensure_menagerie_root()
    return root is not None and (root / "shadow_hand").is_dir()


needs_menagerie = pytest.mark.skipif(not _menagerie_available(),
                                     reason=f"no Menagerie models (MENAGERIE_ROOT or {SHARED_ASSETS})")
needs_ycb = pytest.mark.skipif(ycb_root(required=False) is None,
                               reason=f"no YCB objects (DEXAUG_YCB_ROOT or {SHARED_ASSETS}/ycb)")


@pytest.fixture(scope="session")
def shadow():
    from sim.hand.model import Hand

    if not _menagerie_available():
        pytest.skip("no Menagerie models")
    return Hand.load("shadow_right")


def without_grip_boost(config):
    """``config`` (a ValidateConfig) with the squeeze's grip boost off (``max_grip_safety`` =
    ``grip_safety``): for tests of how the grip is sized before the boost scales it."""
    return dataclasses.replace(config, common=dataclasses.replace(
        config.common, max_grip_safety=config.common.grip_safety))


def without_settled_modes(config):
    """``config`` (a ValidateConfig) with the ``dgb`` pregrasp's free modes left at the
    grasp's split (``[dgb] settle_free_modes`` off): for tests of the benchmark's squeeze
    mechanisms measured before the settling, and of the settling itself."""
    return dataclasses.replace(config, dgb=dataclasses.replace(config.dgb,
                                                               settle_free_modes=False))


def without_rehearsal(config):
    """``config`` (a ValidateConfig) with the ``dgb`` closing not rehearsed (``[dgb]
    rehearse_closing`` off): for tests of the targets' own mechanisms measured before the
    rehearsal chose among them (sim.validate.rehearsal)."""
    return dataclasses.replace(config, dgb=dataclasses.replace(config.dgb, rehearse_closing=False))


def without_drift_correction(config):
    """``config`` (a ValidateConfig) with the rehearsed ``dgb`` squeeze not corrected for its
    closing's drift (``[dgb] rehearsal_drift_corrections = 0``): for tests of mechanisms
    measured before the correction moved the squeeze (sim.validate.rehearsal)."""
    return dataclasses.replace(config, dgb=dataclasses.replace(config.dgb,
                                                               rehearsal_drift_corrections=0))
