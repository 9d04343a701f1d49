"""Units of augmentation work and their local run: a demo, or an object without one.

Why units: ``dexaug batch`` takes sessions, demo files and bare objects alike, and the local pool
and the Ray driver must agree on what each one is, where its folder is (the driver decides every
path; a task never names one), which key says it is finished, and how its results are written.
A demo unit is exactly what ``dexaug augment`` does with that demo (:func:`augment_demo`); an
object unit is ``dexaug generate`` on the hand's manual workspace (paper Table 1, no demo, finger
iteration on unless turned off), validated and written like a demo's folder, without a report
(the report is about a demonstration).
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from dexaug.pipeline.options import (
    AugmentOptions,
    Progress,
    demo_dir,
    result_configs,
    result_options,
    run_key,
)
from dexaug.pipeline.run import Computed, augment_demo, compute_fsg, validate_computed, write_result
from dexaug.pipeline.summary import DemoSummary, finished, stored
from sim.demo import Demo, DemoError, load_demo
from sim.errors import DexaugError
from teleop.record.demos import extract_demos

__all__ = ["Unit", "demo_unit", "gather_units", "object_unit", "run_local"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Unit:
    """One unit of work: ``demo`` (None for an object on the manual workspace), the hand and
    object, the options it runs with, and ``id`` (the demo's id, or ``<object>@manual``)."""

    id: str
    hand: str
    object: str
    opts: AugmentOptions
    demo: Demo | None = None

    @property
    def source(self) -> str:
        return str(self.demo.source) if self.demo is not None else "manual workspace"

    def folder(self, out_root: Path | str) -> Path:
        """The unit's result folder, always directly inside ``out_root`` (:func:`demo_dir`'s
        rules for a demo; an object's name made path-safe the same way)."""
        if self.demo is not None:
            return demo_dir(out_root, self.demo)
        name = re.sub(r"[^A-Za-z0-9_.@-]+", "_", self.id)
        return Path(out_root) / ("_" + name if name.startswith(".") else name)

    def configs(self) -> dict[str, str]:
        """The configuration texts the results depend on, read now (:func:`result_configs`)."""
        return result_configs(self.demo if self.demo is not None else self.hand)

    def key(self, configs: dict[str, str]) -> str:
        """:func:`run_key` of a demo; for an object the same hash over the object and hand."""
        if self.demo is not None:
            return run_key(self.demo, self.opts, configs)
        doc = {"options": result_options(self.opts), "object": self.object, "hand": self.hand,
               "configs": configs}
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]

    def finished(self, out_root: Path | str) -> DemoSummary | None:
        """The folder's summary when this unit is finished under today's inputs (what a re-run
        skips, as ``augment`` does), else None."""
        folder = self.folder(out_root)
        if self.demo is not None:
            return finished(folder, self.demo, self.opts)
        summary = stored(folder, self.id)
        return summary if summary is not None and summary.run_key == self.key(self.configs()) else None

    def write(self, out_root: Path | str, computed: Computed, key: str, configs: dict[str, str],
              progress: Progress | None = None) -> DemoSummary:
        """Write ``computed`` into this unit's folder (:func:`write_result`, atomic files)."""
        return write_result(self.folder(out_root), computed, self.opts, key=key, configs=configs,
                            demo=self.demo, unit_id=self.id, source=self.source, progress=progress)


def demo_unit(demo: Demo, opts: AugmentOptions) -> Unit:
    return Unit(demo.id, demo.hand, demo.object, opts, demo)


def object_unit(obj: str, hand: str, opts: AugmentOptions, finger_iteration: bool | None = None) -> Unit:
    """An object on ``hand``'s manual workspace; ``finger_iteration`` None means on (as
    ``generate`` without a demo)."""
    fi = True if finger_iteration is None else finger_iteration
    return Unit(f"{obj}@manual", hand, obj, replace(opts, finger_iteration=fi))


def gather_units(inputs: Sequence[Path], opts: AugmentOptions, objects: Sequence[str] = (),
                 hand: str = "", finger_iteration: bool | None = None) -> tuple[list[Unit], list[str]]:
    """The units of ``inputs`` (demo files ``.json``, sessions ``.mcap``: every demo in them) and
    of ``objects`` (on ``hand``'s manual workspace), and one message per input that gave none
    (unreadable, no usable grasp)."""
    units: list[Unit] = []
    errors: list[str] = []
    for path in inputs:
        try:
            demos = [load_demo(path)] if path.suffix == ".json" else extract_demos(path)
        except (DemoError, DexaugError) as exc:
            errors.append(str(exc) if str(path) in str(exc) else f"{path}: {exc}")
            continue
        units.extend(demo_unit(d, opts) for d in demos)
    units.extend(object_unit(o, hand, opts, finger_iteration) for o in objects)
    return units, errors


def run_local(unit: Unit, out_root: Path | str, *, progress: Progress | None = None,
              force: bool = False) -> DemoSummary:
    """Run ``unit`` in this process with the local pool (``unit.opts.workers`` processes): a demo
    exactly as ``dexaug augment`` does, an object as the module docstring says."""
    if unit.demo is not None:
        return augment_demo(unit.demo, out_root, unit.opts, progress=progress, force=force)
    if not force and (done := unit.finished(out_root)) is not None:
        log.info("%s: already done (%s), skipping", unit.id, unit.folder(out_root))
        return done
    tick = progress or (lambda stage, done, total: None)
    opts = unit.opts
    configs = unit.configs()
    key = unit.key(configs)
    c, _, _, _ = compute_fsg(unit.hand, unit.object, None, opts, workers=opts.workers, progress=tick)
    validate_computed(c, opts, progress=tick)
    return unit.write(out_root, c, key, configs, progress=tick)
