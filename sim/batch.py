"""Validate many grasps on all cores.

Each worker process builds its own hand, object and scenes once (initializer) and then validates
grasps by index; results come back in input order, so the output does not depend on the number of
workers (the simulation itself has no randomness).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

from sim.grasp import Grasp
from sim.hand import Hand
from sim.objects import load_object
from sim.validate import ValidateConfig, ValidationResult, Validator

_worker: Validator | None = None


def _init(hand: str, obj: str, config_path: str | None) -> None:
    global _worker
    config = ValidateConfig.load(config_path) if config_path else ValidateConfig.load()
    _worker = Validator(Hand.load(hand), load_object(obj), config)


def _validate_one(args: tuple[Grasp, str]) -> ValidationResult:
    assert _worker is not None, "worker not initialised"
    grasp, protocol = args
    return _worker.validate(grasp, protocol)


def default_workers() -> int:
    return max(len(os.sched_getaffinity(0)), 1)


def validate_many(hand: str, obj: str, grasps: Sequence[Grasp], protocol: str = "lift-drop", *,
                  workers: int | None = None, config_path: Path | None = None,
                  progress: Callable[[int], None] | None = None) -> list[ValidationResult]:
    """Validate ``grasps`` of hand config ``hand`` on object ``obj`` with ``workers`` processes
    (default: all cores). ``progress(n_done)`` is called as results arrive."""
    workers = workers or default_workers()
    cfg = str(config_path) if config_path else None
    if workers == 1 or len(grasps) <= 1:
        _init(hand, obj, cfg)
        out = []
        for g in grasps:
            out.append(_validate_one((g, protocol)))
            if progress:
                progress(len(out))
        return out
    ctx = get_context("spawn")  # MuJoCo and fork do not mix safely; spawn is deterministic
    results: list[ValidationResult] = []
    with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init,
                             initargs=(hand, obj, cfg)) as pool:
        chunk = max(1, len(grasps) // (workers * 8))
        for res in pool.map(_validate_one, [(g, protocol) for g in grasps], chunksize=chunk):
            results.append(res)
            if progress:
                progress(len(results))
    return results
