"""The dashboard's "Put on arm": a listed result's grasps on an arm at a table, as a job.

Why a module of its own: the request comes from a web page, so what it may say is checked here
in one place (an arm among the installed configs, a whole number of placements within
:data:`~dexaug.pipeline.arm_stage.MAX_PLACEMENTS`, a demo key), and the page never names a
file: the server resolves the demo key through the catalog to the result folder the pipeline
wrote (:meth:`dexaug.dashboard.catalog.Catalog.result_dataset`), and the job writes that
folder's ``arm_<arm>.h5`` (:mod:`dexaug.pipeline.arm_stage`, the same stage as
``dexaug augment --arm``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote

from dexaug.pipeline.arm_stage import (
    DEFAULT_PLACEMENTS,
    MAX_PLACEMENTS,
    check_arm_name,
    folder_arm_files,
    run_arm_stage,
)
from sim.errors import DexaugError

__all__ = ["ArmJob", "arm_views", "parse_arm_request", "run_arm_job"]

_EXPECTED = 'expected JSON {"demo": KEY, "arm": ARM, "placements": N}'


@dataclass(frozen=True)
class ArmJob:
    """What an arm job runs: the demo ``key`` (its result folder's name, for the links), the
    ``dataset`` the catalog resolved for it, the arm and the placements."""

    key: str
    dataset: Path
    arm: str
    placements: int


def parse_arm_request(doc: Any) -> tuple[str, str, int]:
    """``(demo key, arm, placements)`` of a ``POST /api/arm`` body, or a one-line
    :class:`DexaugError` saying what is wrong (the server answers 400 with it)."""
    if not isinstance(doc, dict) or not isinstance(doc.get("demo"), str) \
            or not isinstance(doc.get("arm"), str):
        raise DexaugError(_EXPECTED)
    placements = doc.get("placements", DEFAULT_PLACEMENTS)
    # bool is an int in Python; JSON true is no count
    if isinstance(placements, bool) or not isinstance(placements, int) \
            or not 1 <= placements <= MAX_PLACEMENTS:
        raise DexaugError(f"placements must be a whole number from 1 to {MAX_PLACEMENTS}, got "
                          f"{placements!r}")
    return doc["demo"], check_arm_name(doc["arm"]), placements


def arm_views(folder: Path, key: str) -> list[dict[str, Any]]:
    """The page's list of a result folder's arm files: each file's numbers
    (:class:`~dexaug.pipeline.arm_stage.ArmFile`) or why it cannot be read, with its link
    under ``/results/<key>/``."""
    return [{**f.to_json(), "url": f"/results/{quote(key)}/{quote(f.path.name)}"}
            for f in folder_arm_files(folder)]


def run_arm_job(job: ArmJob, progress: Callable[[str, int, int], None]) -> dict[str, Any]:
    """The job: the arm stage on ``job.dataset`` (an arm file already made from it with the
    same arm and placements is kept, and said so); returns the folder's arm files as listed,
    and ``skipped`` (why the stage did not run, or None)."""
    outcome = run_arm_stage(job.dataset, job.arm, placements=job.placements, progress=progress)
    return {"arm": job.arm, "placements": job.placements, "skipped": outcome.skipped,
            "arms": arm_views(job.dataset.parent, job.key)}
