"""The dashboard's augmentation settings the page may change: n, table mode and protocol.

Why a module of its own: what a browser sends is untrusted input, so each field is checked
here, strictly, with a one-line reason naming the field (HTTP 400), before it reaches the
pipeline; everything else of :class:`~dexaug.pipeline.options.AugmentOptions` (workers, seed,
gallery, …) stays as the dashboard was started. The settings are the dashboard's own (one
local user): the listing compares finished results with them (``earlier``), and each job keeps
the settings it was queued with.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from dexaug.pipeline.options import AugmentOptions
from sim.errors import DexaugError
from sim.validate.config import PROTOCOLS

__all__ = ["MAX_N", "PROTOCOL_CHOICES", "TABLE_CHOICES", "SettingsError", "apply_settings",
           "settings_json"]

#: the most grasps one augmentation may ask for from the page (the CLI has no such bound)
MAX_N = 5000
#: "none": keep every FSG grasp unvalidated
PROTOCOL_CHOICES = (*PROTOCOLS, "none")
#: "demo": follow the demonstration (its table when it recorded one)
TABLE_CHOICES = {"demo": None, "on": True, "off": False}


class SettingsError(DexaugError):
    """A settings request the dashboard refuses (the message names the field)."""


def settings_json(opts: AugmentOptions) -> dict[str, Any]:
    """The page's view of the settings and their choices."""
    table = next(k for k, v in TABLE_CHOICES.items() if v is opts.table)
    return {"n": opts.n, "n_max": MAX_N, "validate": opts.validate or "none",
            "protocols": list(PROTOCOL_CHOICES), "table": table, "tables": list(TABLE_CHOICES)}


def apply_settings(body: Any, opts: AugmentOptions) -> AugmentOptions:
    """``opts`` with the fields of a JSON body ``{"n": int, "table": "demo"|"on"|"off",
    "validate": protocol|"none"}`` (each optional) applied; SettingsError on anything else."""
    if not isinstance(body, dict):
        raise SettingsError('expected a JSON object {"n": …, "table": …, "validate": …}')
    unknown = sorted(set(body) - {"n", "table", "validate"})
    if unknown:
        raise SettingsError(f"unknown field(s) {', '.join(unknown)}; expected n, table, validate")
    changes: dict[str, Any] = {}
    if "n" in body:
        n = body["n"]
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_N:
            raise SettingsError(f"field 'n' must be an integer from 1 to {MAX_N}, got {n!r}")
        changes["n"] = n
    if "table" in body:
        if not isinstance(body["table"], str) or body["table"] not in TABLE_CHOICES:
            raise SettingsError(f"field 'table' must be one of {', '.join(TABLE_CHOICES)}, "
                                f"got {body['table']!r}")
        changes["table"] = TABLE_CHOICES[body["table"]]
    if "validate" in body:
        if not isinstance(body["validate"], str) or body["validate"] not in PROTOCOL_CHOICES:
            raise SettingsError(f"field 'validate' must be one of {', '.join(PROTOCOL_CHOICES)}"
                                f", got {body['validate']!r}")
        changes["validate"] = None if body["validate"] == "none" else body["validate"]
    return dataclasses.replace(opts, **changes)
