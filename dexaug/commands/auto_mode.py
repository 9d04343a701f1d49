"""``dexaug generate --mode auto``: the grasp mode chosen per object from a pilot of each.

Why pilots. Fingertip (FSG) grasps hold where fingertips can hold the object and cost 5–10×
less per validated grasp; power grasps hold the heavy, large and long objects that fingertips
cannot. No threshold on the fingertip pass share alone tells the two cases apart. On the ten
objects not used in development (docs/decisions/2026-12-07-power-grasps.md, n = 40 per mode):

- the mustard bottle passes 32 % with fingertips and 90 % with power grasps;
- the flat screwdriver passes 72 % and 52 %;
- adding power grasps below 30 % fingertip averaged 64.8 % lift-drop, while the better mode of
  each object averaged 85.2 %.

So auto measures both modes on the object at hand:

1. It makes and validates a pilot of ``[power] auto_pilot`` grasps per mode.
2. Power wins only when its pilot passes more than ``auto_margin`` more often than the
   fingertip pilot. Near-ties go to the cheaper mode, and the power pilot is skipped where it
   cannot win (fingertips already pass at least 1 − margin).
3. The chosen mode continues to ``--n`` grasps with a seed of its own.
4. The other pilot's grasps are not written. The report gives their numbers, and so do the
   table's attributes.

Asked for fingertips (``--demo``, ``--fingers``, ``--table``), auto makes fingertip grasps
only, without pilots.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from augment.fsg.result import FsgResult
    from sim.validate.result import ValidationResult

__all__ = ["AutoChoice", "ModeRun", "choose_mode", "run_auto"]

#: one mode's grasps and their validation (None: not validated)
ModeRun = tuple[str, "FsgResult", "list[ValidationResult] | None"]
#: makes ``n`` grasps of a mode with a seed, validated: (mode, n, seed) -> its run
RunMode = Callable[[str, int, int], ModeRun]


@dataclass(frozen=True)
class AutoChoice:
    """What auto measured and chose: per mode piloted, (grasps made, grasps passed)."""

    mode: str
    pilots: dict[str, tuple[int, int]]

    def rate(self, mode: str) -> float:
        return _rate(self.pilots.get(mode, (0, 0)))

    def summary(self) -> str:
        """One line for the console: each pilot's pass share and the choice."""
        parts = [f"{m} {p}/{n} pass ({100 * self.rate(m):.0f} %)"
                 for m, (n, p) in self.pilots.items()]
        return f"auto pilots: {'; '.join(parts)}: {self.mode}"

    def attrs(self) -> str:
        """The pilots as JSON, for the dataset table's ``auto_pilots`` attribute."""
        return json.dumps({m: {"grasps": n, "passed": p} for m, (n, p) in self.pilots.items()},
                          sort_keys=True)


def _rate(pilot: tuple[int, int]) -> float:
    """A pilot's (grasps, passed) as a pass share; 0 for an empty pilot."""
    return pilot[1] / pilot[0] if pilot[0] else 0.0


def _tally(run: ModeRun) -> tuple[int, int]:
    results = run[2] or []
    return len(run[1].grasps), sum(bool(r.passed) for r in results)


def choose_mode(fingertip: tuple[int, int], power: tuple[int, int] | None,
                margin: float) -> str:
    """``"power"`` when the power pilot's pass share beats the fingertip pilot's by more than
    ``margin``, else ``"fingertip"`` (pilots as (grasps, passed)); power too when FSG made no
    fingertip grasp and the power pilot made any."""
    if not fingertip[0]:    # FSG made no grasp at all: fingertips cannot deliver any
        return "power" if power is not None and power[0] else "fingertip"
    # a share difference of exactly the margin is a tie (1e-9: 0.8 − 0.7 is 0.1000…01 in floats)
    return ("power" if power is not None and _rate(power) - _rate(fingertip) > margin + 1e-9
            else "fingertip")


def continuation_seed(seed: int) -> int:
    """The chosen mode's seed for the grasps after its pilot: its own stream, so they do not
    repeat the pilot's."""
    import numpy as np

    return int(np.random.SeedSequence([seed, 1]).generate_state(1)[0])


def run_auto(run: RunMode, n: int, seed: int, pilot: int,
             margin: float) -> tuple[list[ModeRun], AutoChoice]:
    """The runs to write (the chosen mode's pilot, then its continuation to ``n`` grasps) and
    what auto chose (module docstring). ``run(mode, n, seed)`` makes and validates."""
    k = min(pilot, n)
    tip = run("fingertip", k, seed)
    pilots = {"fingertip": _tally(tip)}
    pw = None
    if pilots["fingertip"][0] and _rate(pilots["fingertip"]) + margin >= 1.0 - 1e-9:
        mode = "fingertip"     # power cannot beat it by the margin: no power pilot
    else:
        pw = run("power", k, seed)
        pilots["power"] = _tally(pw)
        mode = choose_mode(pilots["fingertip"], pilots["power"], margin)
    kept = pw if mode == "power" and pw is not None else tip
    runs = [kept]
    rest = n - len(kept[1].grasps)
    if rest > 0 and len(kept[1].grasps) == k:   # a pilot that fell short would again
        runs.append(run(mode, rest, continuation_seed(seed)))
    return runs, AutoChoice(mode, pilots)
