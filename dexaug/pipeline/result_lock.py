"""One writer per result folder: an exclusive ``fcntl.flock`` on ``<folder>/.lock``.

Why: every file of a result is written atomically, but a result is several files (``grasps.h5``,
the report and its images, ``summary.json`` last), and two runs of one demo into one output
folder at once (two ``dexaug augment`` processes, the dashboard beside the CLI) would each
compute it and interleave their writes: one run's summary beside the other's dataset, each
deleting the other's finished summary (issue #56). With the lock the second run waits for the
first, then finds the demo finished and skips it (or, forced, writes its own whole result).

Why flock: the kernel drops it when its holder dies, so a killed run never leaves a stale lock
(only an empty lock file, which the next run reuses; a run that ends removes it). It is per
open file, so two threads of one process exclude each other too; a thread already holding a
folder's lock re-enters it (``augment_demo`` holds it around ``write_result``, which takes it
for callers that only write).
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["LOCK_NAME", "result_lock"]

log = logging.getLogger(__name__)

#: the lock file in each result folder (hidden: the result lists never show it)
LOCK_NAME = ".lock"

_held: dict[str, int] = {}   # lock path → the thread holding it in this process
_held_guard = threading.Lock()


def _acquire(folder: Path, path: Path, what: str) -> int:
    """An fd of ``path`` holding its flock, waiting for another holder. The file is removed by
    each holder on release, so after waiting the lock may be on a file no longer there: then
    again on the current one (the lock is the file at ``path``, not an unlinked old one)."""
    waited = False
    while True:
        folder.mkdir(parents=True, exist_ok=True)
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except FileNotFoundError:   # the folder was removed by a run that wrote nothing
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if not waited:
                log.info("%s: another run is writing %s; waiting for it to finish", what, folder)
                waited = True
            fcntl.flock(fd, fcntl.LOCK_EX)
        try:
            current = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            current = False
        if current:
            if waited:
                log.info("%s: the other run finished", what)
            return fd
        os.close(fd)


@contextmanager
def result_lock(folder: Path | str, what: str = "") -> Iterator[None]:
    """Hold ``folder``'s result lock (creating the folder), waiting while another run holds it;
    ``what`` names the unit in the waiting message. On release the lock file is removed, and
    the folder too when this call made it and nothing was written into it (a run that failed
    before writing leaves nothing behind)."""
    folder = Path(folder)
    path = folder / LOCK_NAME
    key = str(path.absolute())
    me = threading.get_ident()
    with _held_guard:
        reentered = _held.get(key) == me
    if reentered:
        yield
        return
    made = not folder.exists()
    fd = _acquire(folder, path, what or str(folder))
    try:
        with _held_guard:
            _held[key] = me
        try:
            yield
        finally:
            with _held_guard:
                _held.pop(key, None)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)   # still holding the lock: a waiter sees the file is gone, retries
        if made:
            with contextlib.suppress(OSError):   # not empty: a result (or another run's lock)
                folder.rmdir()
        os.close(fd)   # releases the lock
