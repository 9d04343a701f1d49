"""Ending the worker processes of an interrupted command at once.

Why: FSG and the validator run in ``sim.pools``' persistent process pools, and at interpreter
exit a pool's shutdown waits for the tasks its workers are running. A Ctrl-C that reaches only
the main process (``kill -INT``, a service manager, a parent process) or a SIGTERM left each
FSG worker sampling until its time budget ended, up to ``--budget`` seconds after the user asked
to stop. :func:`stop_workers` terminates the workers, then shuts each pool down and waits for
its manager thread, which finds its workers gone, fails their futures and ends within a second.
Waiting here matters: left to the interpreter's exit, the manager thread closing its wake-up
pipe races ``concurrent.futures``' exit hook writing to it (an "Exception ignored … Bad file
descriptor" traceback on Python 3.11).
"""

from __future__ import annotations

import logging
import multiprocessing

__all__ = ["stop_workers"]

log = logging.getLogger(__name__)


def stop_workers() -> None:
    """Terminate every worker process this process started (SIGTERM), without waiting for
    their running tasks, and shut their pools down; for the end of an interrupted command."""
    from sim.pools import stop_pools

    stopped = stop_pools()
    others = multiprocessing.active_children()   # the fork server, any worker outside sim.pools
    for child in others:
        child.terminate()
    if stopped or others:
        log.debug("terminated %d pool workers and %d other processes", stopped, len(others))
