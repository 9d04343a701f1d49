"""The process-wide worker pools (sim/pools.py): Ctrl-C belongs to their owner."""

from __future__ import annotations

import os
import signal

from sim.pools import persistent_pool, stop_pools
from tests.conftest import wait_for


def _sigint_ignored(pid: int) -> bool:
    """Whether process ``pid`` ignores SIGINT, read from the kernel (``SigIgn`` in
    /proc/PID/status is a hex mask, bit ``signum - 1``)."""
    with open(f"/proc/{pid}/status") as f:
        mask = next(int(line.split()[1], 16) for line in f if line.startswith("SigIgn:"))
    return bool(mask >> (signal.SIGINT - 1) & 1)


def test_a_worker_ignores_ctrl_c_and_its_owner_stops_it() -> None:
    """A terminal's Ctrl-C reaches every process of the group; a worker that took it between
    tasks printed a traceback of its queue wait (a CI run: ``ForkServerProcess-2: Traceback``).
    A worker ignores SIGINT, still runs tasks after one, and ends when its owner stops the pools."""
    pool = persistent_pool(1)
    try:
        pid = pool.submit(os.getpid).result(timeout=120)
        assert _sigint_ignored(pid)
        os.kill(pid, signal.SIGINT)
        assert pool.submit(os.getpid).result(timeout=120) == pid
    finally:
        assert stop_pools() >= 1   # other tests of this process may have left pools too
    wait_for(lambda: not _alive(pid), 60, lambda: f"worker {pid} to end", every_s=0.1)


def _alive(pid: int) -> bool:
    """Whether ``pid`` is a running process (a zombie awaiting its parent's wait counts as ended)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return "zombie" not in f.read()
    except FileNotFoundError:
        return False
