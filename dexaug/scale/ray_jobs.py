"""Units of work as Ray tasks; the driver gathers their results and writes every folder.

Per unit, one FSG task (workspace + FSG with ``opts.workers`` processes, reserving that many
CPUs; plus the demo grasp's own check) and then its grasps in validation chunks (``chunk``
grasps per task, one CPU each), gathered back in input order: a demo's validation spreads over
the whole cluster, and the FSG of the next unit runs while this one validates.

Why the driver writes: a task is pure compute and returns plain data (:class:`Computed`, lists
of :class:`~sim.validate.result.ValidationResult`), so Ray may rerun it on another worker when
one dies (``max_retries``) and the rerun gives the same data (FSG is seeded, the validator is
deterministic); the driver writes each unit's folder exactly once, atomically, when its last
chunk is in, so a retried task never duplicates rows, and no remote code ever names a file path.
An input error (:class:`~sim.errors.DexaugError` raised in a task: an unknown object, a hand not
installed) is not retried (``retry_exceptions=False``) and is reported for that unit, like the
local path reports it; the other units go on. A unit finished before (same inputs) is skipped.

The results equal the local path's for the same seed and the same FSG worker count (FSG's output
depends on it: worker k uses seed + k): ``dexaug batch --workers 1`` and ``--ray --workers 1``
write the same datasets.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dexaug.pipeline.options import Progress
from dexaug.pipeline.run import Computed, compute_fsg, validate_demo_grasp
from dexaug.pipeline.summary import DemoSummary
from dexaug.scale.ray_cluster import import_ray
from dexaug.scale.units import Unit
from sim.errors import DexaugError
from sim.grasp import Grasp
from sim.validate.batch import validate_many
from sim.validate.result import ValidationResult

__all__ = ["DEFAULT_CHUNK", "MAX_RETRIES", "Outcome", "fsg_task", "run_on_ray", "validate_chunk"]

log = logging.getLogger(__name__)

#: grasps per validation task: a few seconds of work, small against a task's overhead
DEFAULT_CHUNK = 32
#: times Ray reruns a task whose worker died (system failures only, never an input error)
MAX_RETRIES = 3


def fsg_task(unit: Unit) -> Computed:
    """Ray task (process title ``ray::fsg_task``): the unit's workspace and FSG, and for a demo
    its own grasp's verdict; plain data back, no file written."""
    c, hand, obj, _ = compute_fsg(unit.hand, unit.object, unit.demo, unit.opts,
                                  workers=unit.opts.workers)
    if unit.opts.validate and unit.demo is not None:
        t0 = time.perf_counter()
        c.demo_grasp = validate_demo_grasp(hand.name, obj.name, unit.demo, unit.opts.validate,
                                           unit.opts.squeeze_convention)
        c.timings_s["demo_grasp"] = time.perf_counter() - t0
    return c


def validate_chunk(hand: str, obj: str, grasps: Sequence[Grasp], protocol: str,
                   squeeze_convention: str | None, backend: str = "mujoco") -> list[ValidationResult]:
    """Ray task (``ray::validate_chunk``): ``grasps`` validated in order in this worker (its
    validator is cached across chunks of the same hand and object) on ``backend``."""
    return validate_many(hand, obj, list(grasps), protocol, workers=1,
                         squeeze_convention=squeeze_convention, backend=backend)


@dataclass
class Outcome:
    """What became of one unit: its summary, or ``error`` (one line) when it failed."""

    unit: Unit
    summary: DemoSummary | None = None
    error: str | None = None


@dataclass
class _State:
    unit: Unit
    key: str
    configs: dict[str, str]
    computed: Computed | None = None
    parts: dict[int, list[ValidationResult]] = field(default_factory=dict)
    chunks: int = 0
    t_validate: float = 0.0
    refs: set[Any] = field(default_factory=set)


def _message(exc: BaseException) -> str:
    """One line for a failed task: an input error's own message, else the kind of failure."""
    cause = getattr(exc, "cause", None)
    if isinstance(cause, DexaugError):
        return str(cause)
    if cause is not None:
        return f"{type(cause).__name__}: {cause}"
    head = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {head[0] if head else 'task failed'}"


def run_on_ray(units: Sequence[Unit], out_root: Path | str, *, chunk: int = DEFAULT_CHUNK,
               force: bool = False, progress: Progress | None = None) -> list[Outcome]:
    """Run ``units`` on the initialised Ray cluster (module docstring) and write their folders
    under ``out_root``; outcomes in the order of ``units``. ``progress(stage, done, total)``
    ticks "fsg" (units), "validate" (grasps; the total grows as FSG finishes) and "written"."""
    ray = import_ray()
    tick = progress or (lambda stage, done, total: None)
    opts_remote = {"max_retries": MAX_RETRIES, "retry_exceptions": False}
    fsg_remote = ray.remote(**opts_remote)(fsg_task)
    val_remote = ray.remote(num_cpus=1, **opts_remote)(validate_chunk)
    outcomes = [Outcome(u) for u in units]
    states: dict[int, _State] = {}
    pending: dict[Any, tuple[int, int]] = {}   # ref → (unit index, chunk index; -1: FSG)
    for i, unit in enumerate(units):
        if not force and (done := unit.finished(out_root)) is not None:
            log.info("%s: already done (%s), skipping", unit.id, unit.folder(out_root))
            outcomes[i].summary = done
            continue
        configs = unit.configs()   # the inputs as they are now, before any task reads them
        states[i] = _State(unit, unit.key(configs), configs)
        ref = fsg_remote.options(num_cpus=unit.opts.workers).remote(unit)
        pending[ref] = (i, -1)
        states[i].refs.add(ref)
    n_run = len(states)
    counts = {"fsg": 0, "validate": 0, "validate_total": 0, "written": len(units) - n_run}
    tick("fsg", 0, n_run)
    tick("validate", 0, 0)
    tick("written", counts["written"], len(units))

    def fail(i: int, message: str) -> None:
        outcomes[i].error = message
        for ref in states[i].refs:
            if pending.pop(ref, None) is not None:
                ray.cancel(ref)
        counts["written"] += 1
        tick("written", counts["written"], len(units))
        log.warning("%s: %s", states[i].unit.id, message)

    def write(i: int) -> None:
        st = states[i]
        c = st.computed
        assert c is not None, "a unit is written only after its computation returned"
        if st.chunks:
            c.validation = [r for k in range(st.chunks) for r in st.parts[k]]
        c.timings_s["validate"] = time.perf_counter() - st.t_validate if st.chunks else 0.0
        outcomes[i].summary = st.unit.write(out_root, c, st.key, st.configs)
        counts["written"] += 1
        tick("written", counts["written"], len(units))

    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            ref = ready[0]
            i, k = pending.pop(ref)
            st = states[i]
            st.refs.discard(ref)
            try:
                value = ray.get(ref)
            except ray.exceptions.RayError as exc:
                fail(i, _message(exc))
                continue
            if k < 0:
                st.computed = value
                counts["fsg"] += 1
                tick("fsg", counts["fsg"], n_run)
                opts = st.unit.opts
                grasps = [g.grasp for g in value.fsg.grasps] if opts.validate else []
                st.t_validate = time.perf_counter()
                for j, start in enumerate(range(0, len(grasps), chunk)):
                    # a Warp chunk runs where Ray has a GPU to give it
                    task = val_remote.options(num_gpus=1 if opts.backend == "warp" else 0)
                    r = task.remote(value.hand, value.object, grasps[start:start + chunk],
                                    opts.validate, opts.squeeze_convention, opts.backend)
                    pending[r] = (i, j)
                    st.refs.add(r)
                    st.chunks += 1
                counts["validate_total"] += len(grasps)
                tick("validate", counts["validate"], counts["validate_total"])
                if not st.chunks:
                    write(i)
            else:
                st.parts[k] = value
                counts["validate"] += len(value)
                tick("validate", counts["validate"], counts["validate_total"])
                if len(st.parts) == st.chunks:
                    write(i)
    except BaseException:
        for ref in pending:
            ray.cancel(ref)
        raise
    return outcomes
