"""What a ``POST /api/augment`` may ask of one job: the demo, and sizes that can finish.

Why a module of its own: a request body is untrusted, and every size in it scales the work a
job does (grasps generated and validated, FSG's wall time, processes started, images
rendered), so each is checked here against a documented ceiling, before anything is queued
(issue #56). A refusal is one line naming the field, the value and the allowed range (the
server answers HTTP 400 with it). Fields left out keep the dashboard's settings
(:mod:`dexaug.dashboard.settings`); an unknown field is refused by name, never ignored.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

from dexaug.dashboard.settings import MAX_N
from dexaug.pipeline.options import AugmentOptions
from sim.errors import DexaugError

__all__ = ["AUGMENT_FIELDS", "MAX_GALLERY", "MAX_TIME_BUDGET_S", "MAX_WORKERS", "AugmentRequestError",
           "parse_augment_request"]

#: FSG's wall-time budget per job, at most an hour: the dashboard runs one job at a time, so a
#: longer one would hold every later click behind it; a larger dataset is the CLI's business
MAX_TIME_BUDGET_S = 3600.0
#: the most worker processes a job may start: each is a MuJoCo process of a few hundred MB;
#: beyond the cores they only share them, and thousands would exhaust memory and process slots
MAX_WORKERS = 64
#: the most grasp images one report renders (each is an offscreen render of about a second)
MAX_GALLERY = 50

#: field → (kind, least, most): the sizes a request may set, "int" fields whole numbers
AUGMENT_FIELDS: dict[str, tuple[str, float, float]] = {
    "n": ("int", 1, MAX_N),                              # grasps generated and validated
    "time_budget_s": ("float", 1.0, MAX_TIME_BUDGET_S),
    "workers": ("int", 1, MAX_WORKERS),
    "gallery": ("int", 0, MAX_GALLERY),
}


class AugmentRequestError(DexaugError):
    """A ``POST /api/augment`` body the dashboard refuses (the message names the field)."""


def _bounded(field: str, value: Any) -> int | float:
    kind, lo, hi = AUGMENT_FIELDS[field]
    number = not isinstance(value, bool) and isinstance(value, int | float)
    whole = number and (kind == "float" or isinstance(value, int))
    if not whole or not math.isfinite(value) or not lo <= value <= hi:
        what = "a whole number" if kind == "int" else "a number of seconds"
        raise AugmentRequestError(f"field {field!r} = {json.dumps(value)[:40]} is refused: "
                                  f"expected {what} from {lo:g} to {hi:g}")
    return int(value) if kind == "int" else float(value)


def parse_augment_request(body: Any, opts: AugmentOptions) -> tuple[str, AugmentOptions]:
    """The demo key of a ``POST /api/augment`` body ``{"demo": KEY, "n"?, "time_budget_s"?,
    "workers"?, "gallery"?}`` and ``opts`` with its sizes applied; AugmentRequestError (one
    line) on anything else."""
    if not isinstance(body, dict) or not isinstance(body.get("demo"), str | int):
        raise AugmentRequestError('expected JSON {"demo": KEY} (optionally "n", "time_budget_s", '
                                  '"workers", "gallery")')
    unknown = sorted(set(body) - {"demo", *AUGMENT_FIELDS})
    if unknown:
        names = ", ".join(repr(u)[:40] for u in unknown[:5])
        raise AugmentRequestError(f"unknown field(s) {names}; expected demo, "
                                  f"{', '.join(AUGMENT_FIELDS)}")
    changes: dict[str, Any] = {f: _bounded(f, body[f]) for f in AUGMENT_FIELDS if f in body}
    return str(body["demo"]), dataclasses.replace(opts, **changes)
