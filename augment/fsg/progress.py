"""FSG's progress while it runs: the workers' accepted-grasp counts in shared memory
(:class:`ProgressBoard`), so a caller shows a count that moves instead of "0 / n" until the
stage ends.

Why shared memory: the workers live in a persistent process pool started long before this call
(:mod:`sim.pools`), so nothing can be inherited; a named block of ``workers`` int64 slots is
the cheapest channel (one store per batch, no process, no socket). Each worker writes only its
own slot; the parent sums and unlinks the block. The pool's workers share the parent's
resource tracker (fork server), so a worker's attachment is the parent's own registration: the
worker only closes its mapping (unregistering it there made the tracker fail on the parent's
unlink).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from concurrent.futures import wait
from multiprocessing import shared_memory
from typing import Any

import numpy as np

from sim.pools import persistent_pool

__all__ = ["ProgressBoard", "run_workers", "worker_slot"]


class ProgressBoard:
    """``workers`` counters in a named shared-memory block, created by the caller of FSG."""

    def __init__(self, workers: int) -> None:
        self._shm = shared_memory.SharedMemory(create=True, size=8 * max(workers, 1))
        self._counts = np.ndarray((max(workers, 1),), np.int64, buffer=self._shm.buf)
        self._counts[:] = 0

    @property
    def name(self) -> str:
        """The block's name, for :func:`worker_slot` in a worker."""
        return self._shm.name

    def total(self) -> int:
        """Grasps accepted so far, over all workers (before the merge's deduplication)."""
        return int(self._counts.sum())

    def close(self) -> None:
        """Free and remove the block (after every worker has finished)."""
        del self._counts
        self._shm.close()
        with contextlib.suppress(FileNotFoundError):   # already gone: a worker's own tracker
            self._shm.unlink()


def worker_slot(name: str, worker: int) -> tuple[Callable[[int], None], Callable[[], None]]:
    """In a worker: a setter of its slot of the board ``name`` and a closer of the attachment."""
    shm = shared_memory.SharedMemory(name=name)
    counts = np.ndarray((shm.size // 8,), np.int64, buffer=shm.buf)

    def set_count(k: int) -> None:
        counts[worker] = k

    def close() -> None:
        nonlocal counts
        del counts
        shm.close()

    return set_count, close


def run_workers(fn: Callable[..., Any], worker_args: Sequence[tuple[Any, ...]], n: int,
                progress: Callable[[int], None] | None, preload: Sequence[str]) -> list[Any]:
    """``fn(*args, board)`` for each ``args`` of ``worker_args`` on the persistent pool (one
    process per entry), their results in that order. ``board`` is the name of a
    :class:`ProgressBoard` whose slot the worker sets with :func:`worker_slot` (None without
    ``progress``); ``progress`` gets the summed count, at most ``n``, about every 0.2 s."""
    pool = persistent_pool(len(worker_args), preload=preload)
    board = ProgressBoard(len(worker_args)) if progress is not None else None
    try:
        futs = [pool.submit(fn, *args, None if board is None else board.name)
                for args in worker_args]
        while board is not None and progress is not None:
            _, pending = wait(futs, timeout=0.2)
            progress(min(n, board.total()))
            if not pending:
                break
        return [f.result() for f in futs]
    finally:
        if board is not None:
            board.close()
