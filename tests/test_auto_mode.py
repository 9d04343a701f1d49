"""``generate --mode auto``'s choice (dexaug/commands/auto_mode.py), on scripted pilot outcomes.

The real runs (FSG, power grasps, MuJoCo validation) are in tests/test_power.py; here each
mode's pass share is given, so every branch of the choice is checked, including those that no
shared object reaches reliably at test size.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from dexaug.commands.auto_mode import choose_mode, continuation_seed, run_auto


def _runner(pass_share: dict[str, float], made: dict[str, int] | None = None):
    """A ``run(mode, n, seed)`` whose grasps pass at ``pass_share[mode]`` (the first ones),
    making ``made[mode]`` grasps when given (a shortfall), and the calls it got."""
    calls: list[tuple[str, int, int]] = []

    def run(mode: str, n: int, seed: int):
        calls.append((mode, n, seed))
        k = min(n, (made or {}).get(mode, n))
        passed = round(pass_share[mode] * k)
        results = [SimpleNamespace(passed=i < passed) for i in range(k)]
        return mode, SimpleNamespace(grasps=list(range(k))), results

    return run, calls


def test_power_is_made_only_when_its_pilot_beats_fingertips_by_the_margin() -> None:
    assert choose_mode((10, 3), (10, 9), 0.1) == "power"
    assert choose_mode((10, 7), (10, 8), 0.1) == "fingertip"      # a near-tie: the cheaper mode
    assert choose_mode((0, 0), (10, 1), 0.1) == "power"           # no fingertip grasp at all
    assert choose_mode((10, 2), (0, 0), 0.1) == "fingertip"
    assert choose_mode((10, 2), None, 0.1) == "fingertip"


def test_the_chosen_mode_continues_from_its_pilot_with_a_seed_of_its_own() -> None:
    run, calls = _runner({"fingertip": 0.3, "power": 0.9})
    runs, choice = run_auto(run, 40, 7, 10, 0.1)
    assert calls == [("fingertip", 10, 7), ("power", 10, 7), ("power", 30, continuation_seed(7))]
    assert [r[0] for r in runs] == ["power", "power"]            # the fingertip pilot is dropped
    assert sum(len(r[1].grasps) for r in runs) == 40
    assert choice.mode == "power" and choice.pilots == {"fingertip": (10, 3), "power": (10, 9)}
    assert continuation_seed(7) not in (7, continuation_seed(8))
    assert "fingertip 3/10 pass (30 %)" in choice.summary()


@pytest.mark.parametrize(("shares", "piloted", "mode"), [
    ({"fingertip": 0.9, "power": 1.0}, ["fingertip"], "fingertip"),   # power cannot win: no pilot
    ({"fingertip": 0.7, "power": 0.8}, ["fingertip", "power"], "fingertip"),
])
def test_fingertips_that_hold_keep_the_fingertip_mode(shares: dict[str, float], piloted: list[str],
                                                      mode: str) -> None:
    run, calls = _runner(shares)
    runs, choice = run_auto(run, 25, 0, 10, 0.1)
    assert [c[0] for c in calls[:len(piloted)]] == piloted and choice.mode == mode
    assert [r[0] for r in runs] == [mode, mode] and calls[-1][1] == 15


def test_a_small_n_is_its_pilot_and_a_short_pilot_is_not_continued() -> None:
    run, calls = _runner({"fingertip": 1.0, "power": 1.0})
    runs, _ = run_auto(run, 4, 0, 10, 0.1)
    assert calls == [("fingertip", 4, 0)] and len(runs) == 1
    run, calls = _runner({"fingertip": 0.0, "power": 1.0}, made={"power": 6})
    runs, choice = run_auto(run, 40, 0, 10, 0.1)
    assert choice.mode == "power" and len(runs) == 1 and len(calls) == 2
