"""Worker process pools kept for the life of the process.

Why: starting a worker (interpreter, NumPy, SciPy, MuJoCo imports) costs 1–2 s on the 2-core
machines this project runs on — as much as validating a hundred grasps or a whole demo-seeded FSG
run — so a pipeline that calls FSG and the validator once per demo would pay it again and again.
Pools come from a fork server with the given modules preloaded: each worker is a cheap fork of a
clean, thread-free process, which is safe to start from threaded programs (the dashboard, the
bridge), unlike a plain fork of the caller. They are shut down at interpreter exit.

A worker also exits on its own when the process that made its pool is gone: a fork server hands
every worker the pool's queues and its keep-alive pipe, so after a parent killed by a signal
(SIGTERM, SIGKILL: no interpreter exit) neither the workers nor the fork server would ever see
end-of-file, and they would stay forever.
"""

from __future__ import annotations

import atexit
import os
import signal
import threading
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

__all__ = ["persistent_pool", "stop_pools"]

_POOLS: dict[int, ProcessPoolExecutor] = {}
#: seconds between a worker's checks that its owner is alive
_OWNER_POLL_S = 1.0


def _start_worker(owner_pid: int) -> None:
    """Worker initializer. Ctrl-C is the owner's to handle: a terminal sends SIGINT to the whole
    process group, and a worker that took it between tasks (or a second one while its task was
    being stopped) printed a traceback of its queue wait; the owner stops its workers with
    SIGTERM (:func:`stop_pools`). A daemon thread ends this worker once ``owner_pid`` is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while True:
            time.sleep(_OWNER_POLL_S)
            try:
                os.kill(owner_pid, 0)
            except ProcessLookupError:
                os._exit(0)
            except PermissionError:  # pid reused by another user's process: the owner is gone
                os._exit(0)

    threading.Thread(target=watch, name="dexaug-owner-watch", daemon=True).start()


def persistent_pool(workers: int, preload: Sequence[str] = ()) -> ProcessPoolExecutor:
    """The process-wide pool of ``workers`` processes, created on first use; a pool whose
    worker died is replaced. ``preload``: modules the fork server imports before forking
    workers, so each worker starts with them (the caller that creates the pool names what all
    its users need: one pool serves FSG and validation, so the validator scene a worker
    compiles for FSG's exact penetration check, 1–3 s per hand and object, is the one it
    validates with next). Modules not preloaded are imported by a worker on first use."""
    key = workers
    pool = _POOLS.get(key)
    if pool is not None and getattr(pool, "_broken", False):
        pool.shutdown(wait=False, cancel_futures=True)
        pool = None
    if pool is None:
        ctx = get_context("forkserver")
        ctx.set_forkserver_preload(list(preload))
        pool = _POOLS[key] = ProcessPoolExecutor(workers, mp_context=ctx,
                                                 initializer=_start_worker,
                                                 initargs=(os.getpid(),))
        atexit.register(pool.shutdown, cancel_futures=True)
    return pool


def stop_pools() -> int:
    """Terminate every pool's workers now (SIGTERM), without waiting for their running tasks,
    and shut the pools down, waiting for their manager threads (which find the workers gone and
    fail their futures within a second); for the end of an interrupted command. Returns how
    many worker processes were terminated."""
    procs = [p for pool in _POOLS.values() for p in list(getattr(pool, "_processes", {}).values())]
    for proc in procs:
        proc.terminate()
    for pool in list(_POOLS.values()):
        pool.shutdown(wait=True, cancel_futures=True)
    _POOLS.clear()
    return len(procs)
