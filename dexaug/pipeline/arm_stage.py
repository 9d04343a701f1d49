"""The arm stage of an augmentation: a result folder's grasps put on an arm at a table
(``dexaug augment --arm``, the dashboard's "Put on arm"), and what a folder's arm files say.

Why a module of its own: the CLI and the dashboard both run the stage and both list its files,
and they must agree on where the file goes and what its numbers are. The work itself is
:func:`dexaug.pipeline.arm_run.run_arm` (``dexaug arm``, carried grasps, placement seed
:data:`ARM_SEED`), writing ``<result folder>/arm_<arm>.h5``. The arm file is an extra output
beside ``grasps.h5``: the augmentation's own files, its ``run_key`` and its resume logic do not
know about it. Its own resume rule is :func:`made_already` (same arm, placements, seed and
input, and newer than the dataset), so a re-run of ``dexaug augment --arm`` skips finished arm
files just as it skips finished augmentations.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from sim.errors import DexaugError

__all__ = ["ARM_FORMAT", "ARM_SEED", "DEFAULT_PLACEMENTS", "MAX_PLACEMENTS", "ArmFile",
           "ArmFileError", "ArmStageOutcome", "arm_path", "check_arm_name", "folder_arm_files",
           "made_already", "read_arm_file", "run_arm_stage", "usable_grasps"]

log = logging.getLogger(__name__)

#: the ``format`` attribute :func:`dexaug.pipeline.arm_run.run_arm` writes
ARM_FORMAT = "dexaug-arm-grasps-1"
#: ``dexaug arm``'s default placement seed, so ``dexaug arm grasps.h5 --arm A --placements N``
#: remakes the stage's file exactly
ARM_SEED = 0
#: placements per object when none are asked for: enough to see the resting poses an object
#: takes, at about a minute for a hundred grasps
DEFAULT_PLACEMENTS = 10
#: the most placements one dashboard request may ask for (each is a whole set of IK and
#: simulations per grasp: a typo of 10000 would hold the job queue for hours)
MAX_PLACEMENTS = 200
#: how grasps reach the arm in this stage (``dexaug arm --grasps``' default, the paper's §5.3)
GRASPS_FROM = "carried"

#: progress(stage, done, total), the pipeline's callback
Progress = Callable[[str, int, int], None]


def arm_path(folder: Path | str, arm: str) -> Path:
    """Where a result folder's grasps on ``arm`` are written: one file per arm, so each arm's
    run replaces only its own."""
    return Path(folder) / f"arm_{arm}.h5"


def check_arm_name(arm: str) -> str:
    """``arm`` when it names an installed arm config, else a one-line error. A name is never a
    path here: the dashboard passes it from a web request."""
    from sim.arm.config import arm_names

    names = arm_names()
    if arm not in names:
        raise DexaugError(f"unknown arm {arm!r}: expected one of {', '.join(names)}")
    return arm


@dataclass(frozen=True)
class ArmFile:
    """What an arm file says, over all its objects: (placement, grasp) ``pairs``, how many
    ``passed`` (held when lifted), ``failures`` by reason, and how it was made. ``stale``: the
    dataset beside it was rewritten after it (a re-augmentation), so it no longer describes
    that dataset's grasps."""

    path: Path
    arm: str
    placements: int
    seed: int
    grasps_from: str
    input: str
    objects: tuple[str, ...]
    pairs: int
    passed: int
    failures: dict[str, int]
    stale: bool = False

    @property
    def pass_share(self) -> float | None:
        """Passed over pairs; None for a file without pairs (never NaN: the page parses JSON)."""
        return self.passed / self.pairs if self.pairs else None

    def failures_text(self) -> str:
        """``"collision 1, table 4"`` (reasons sorted), or ``"none"``."""
        return ", ".join(f"{k} {v}" for k, v in sorted(self.failures.items())) or "none"

    def to_json(self) -> dict[str, Any]:
        return {"file": self.path.name, "arm": self.arm, "placements": self.placements,
                "objects": list(self.objects), "pairs": self.pairs, "passed": self.passed,
                "pass_share": self.pass_share, "failures": dict(self.failures),
                "grasps_from": self.grasps_from, "stale": self.stale}


def _group_attrs(path: Path, groups: list[h5py.Group]) -> dict[str, str]:
    """The attributes every object group shares (arm, placements, seed, ...); an error when a
    group lacks one or the groups disagree, since the file's summary would then be wrong."""
    keys = ("arm", "placements", "seed", "grasps_from", "input")
    seen = []
    for g in groups:
        missing = [k for k in keys if k not in g.attrs]
        if missing:
            raise DexaugError(f"{path}: group {g.name!r} lacks attributes {missing}")
        seen.append(tuple(str(g.attrs[k]) for k in keys))
    if len(set(seen)) > 1:
        raise DexaugError(f"{path}: its object groups were made differently ({sorted(set(seen))})")
    return dict(zip(keys, seen[0], strict=True))


def read_arm_file(path: Path | str, dataset: Path | str | None = None) -> ArmFile:
    """Summarise an arm file (``dataset``: the grasps it was made from, for ``stale``). A file
    that is missing, not HDF5, not this format or without objects is a one-line error."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != ARM_FORMAT:
                raise DexaugError(f"{path}: not an arm dataset (format "
                                  f"{f.attrs.get('format')!r}, expected {ARM_FORMAT!r})")
            groups = [g for g in f.values() if isinstance(g, h5py.Group)]
            if not groups:
                raise DexaugError(f"{path}: an arm dataset without objects")
            attrs = _group_attrs(path, groups)
            passed = np.concatenate([np.asarray(g["passed"][()], bool) for g in groups])
            failure = np.concatenate([np.asarray(g["failure"][()]) for g in groups])
            objects = tuple(g.name.lstrip("/") for g in groups)
    except (OSError, KeyError) as exc:   # h5py: unreadable file; KeyError: a missing column
        raise DexaugError(f"{path}: not a readable arm dataset: {exc}") from None
    reasons = Counter(f.decode() if isinstance(f, bytes) else str(f) for f in failure[~passed])
    stale = dataset is not None and _newer(Path(dataset), path)
    return ArmFile(path, str(attrs["arm"]), int(attrs["placements"]), int(attrs["seed"]),
                   str(attrs["grasps_from"]), str(attrs["input"]), objects, len(passed),
                   int(passed.sum()), {k or "unknown": v for k, v in reasons.items()}, stale)


def _newer(a: Path, b: Path) -> bool:
    """Whether ``a`` was modified after ``b`` (False when ``a`` is missing)."""
    try:
        return a.stat().st_mtime_ns > b.stat().st_mtime_ns
    except FileNotFoundError:
        return False


@dataclass(frozen=True)
class ArmFileError:
    """An arm file of a result folder that cannot be read: listed with why, never hidden."""

    path: Path
    error: str

    def to_json(self) -> dict[str, Any]:
        return {"file": self.path.name, "error": self.error}


def folder_arm_files(folder: Path | str) -> list[ArmFile | ArmFileError]:
    """Every ``arm_*.h5`` of a result folder, by name, each summarised (stale against the
    folder's ``grasps.h5``) or with the reason it cannot be read."""
    folder = Path(folder)
    out: list[ArmFile | ArmFileError] = []
    for path in sorted(folder.glob("arm_*.h5")):
        try:
            out.append(read_arm_file(path, folder / "grasps.h5"))
        except DexaugError as exc:
            log.warning("%s", exc)
            out.append(ArmFileError(path, str(exc)))
    return out


def usable_grasps(dataset_path: Path | str) -> int:
    """How many grasps :func:`run_arm` would take from the dataset: its main tables' rows,
    which are the passing grasps of a validated run (the rejected ones sit in side tables) and
    every grasp of one made with ``--validate none``."""
    from augment import dataset

    return sum(len(t) for t in dataset.load(dataset_path).values())


def made_already(out: Path, dataset_path: Path, arm: str, placements: int) -> ArmFile | None:
    """The summary of ``out`` when it is this stage's file for ``dataset_path`` on ``arm``
    with ``placements`` (same seed and grasp source, written after the dataset), else None:
    what a re-run skips."""
    if not out.is_file():
        return None
    try:
        made = read_arm_file(out, dataset_path)
    except DexaugError:
        return None                      # unreadable: made again
    same = (made.arm, made.placements, made.seed, made.grasps_from) == (
        arm, placements, ARM_SEED, GRASPS_FROM)
    return made if same and not made.stale and Path(made.input) == dataset_path else None


@dataclass(frozen=True)
class ArmStageOutcome:
    """What the stage did for one result folder: ``file`` (its arm file's summary; None when
    skipped for want of grasps), ``skipped`` (why it did not run, or None when it ran)."""

    arm: str
    path: Path
    file: ArmFile | None = None
    skipped: str | None = None
    seconds: float = field(default=0.0, compare=False)


def run_arm_stage(dataset_path: Path | str, arm: str, *, placements: int,
                  progress: Progress | None = None, force: bool = False) -> ArmStageOutcome:
    """Put the grasps of ``dataset_path`` (a result folder's ``grasps.h5``) on ``arm`` at
    ``placements`` placements into :func:`arm_path` of its folder, and summarise the file.
    Skipped (one log line, no error) when the dataset holds no grasp to put on the arm, or when
    the file is already made from it (:func:`made_already`) unless ``force``. ``progress``
    gets the stage ``"arm <arm>: <object>"``."""
    from dexaug.pipeline.arm_run import run_arm

    check_arm_name(arm)
    if placements < 1:
        raise DexaugError(f"placements must be >= 1, got {placements}")
    dataset_path = Path(dataset_path).resolve()
    out = arm_path(dataset_path.parent, arm)
    if usable_grasps(dataset_path) == 0:
        why = "no passing grasp to put on the arm"
        log.info("%s: %s; arm stage on %s skipped", dataset_path, why, arm)
        return ArmStageOutcome(arm, out, skipped=why)
    done = None if force else made_already(out, dataset_path, arm, placements)
    if done is not None:
        log.info("%s: already made from this dataset; not redone (--force redoes it)", out)
        return ArmStageOutcome(arm, out, done, skipped="already made")
    t0 = time.perf_counter()
    tick = (lambda name, k, total: progress(f"arm {arm}: {name}", k, total)) if progress else None
    run_arm(dataset_path, arm, out, placements=placements, seed=ARM_SEED, progress=tick)
    return ArmStageOutcome(arm, out, read_arm_file(out, dataset_path),
                           seconds=time.perf_counter() - t0)
