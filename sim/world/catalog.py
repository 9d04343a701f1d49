"""The object catalogue: which objects exist and whether each one loads (``dexaug assets``).

:func:`list_objects` tries every primitive and every YCB folder under the YCB root and returns
one :class:`ObjectStatus` per object, never raising, so a listing shows every broken object and
its problem at once instead of stopping at the first. Units: kilograms, seconds.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from sim.world.objects import (
    ObjectAsset,
    find_object_xml,
    load_object_xml,
    load_primitive,
    one_line,
    ycb_folders,
)
from sim.world.primitives import PRIMITIVES
from sim.world.ycb_xml import ObjectLoadError

__all__ = ["ObjectStatus", "list_objects"]

logger = logging.getLogger(__name__)


@dataclass
class ObjectStatus:
    """One row of ``list_objects``: whether an object loads, and if not, why."""

    name: str
    source: str                     # "ycb" or "primitive"
    path: Path | None
    ok: bool
    problem: str | None = None
    mass_kg: float | None = None
    warnings: list[str] = field(default_factory=list)


def _status(name: str, source: str, load: Callable[[], ObjectAsset], path: Path | None) -> ObjectStatus:
    try:
        asset = load()
    except ObjectLoadError as exc:
        return ObjectStatus(name, source, exc.path if path is None else path, False, exc.problem)
    except Exception as exc:   # a listing reports every broken object instead of stopping
        return ObjectStatus(name, source, path, False, one_line(str(exc)))
    return ObjectStatus(name, source, asset.path, True, None, asset.mass_kg, list(asset.warnings))


def _ycb_status(folder: Path) -> ObjectStatus:
    xmls = sorted(folder.glob("*.xml"))

    def load() -> ObjectAsset:
        return load_object_xml(find_object_xml(folder), folder.name, log_warnings=False)
    return _status(folder.name, "ycb", load, xmls[0] if len(xmls) == 1 else folder)


def list_objects(max_workers: int | None = None) -> list[ObjectStatus]:
    """Try to load every primitive and every YCB object under the YCB root; never raises.

    Compiling (mesh files, convex hulls) is nearly all of the cost, about 4 s for the 63 YCB
    objects on two cores; MuJoCo compiles outside the GIL, so objects are compiled on
    ``max_workers`` threads (default ``min(8, CPUs)``), which helps on machines with more cores.
    Warnings (missing textures) are returned in the statuses rather than logged.
    """
    start = time.perf_counter()
    statuses = [_status(name, "primitive", partial(load_primitive, name), None) for name in PRIMITIVES]
    folders = ycb_folders()
    workers = max_workers or min(8, os.cpu_count() or 1)
    if folders:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            statuses.extend(pool.map(_ycb_status, folders))
    logger.debug("list_objects: %d objects in %.1f s", len(statuses), time.perf_counter() - start)
    return statuses
