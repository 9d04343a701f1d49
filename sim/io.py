"""Atomic file writes: outputs appear whole or not at all (temp file in the same folder, then
rename), so an interrupted run never leaves a half-written dataset, image or report.

Temp files are named ``.<target name>.<writer pid>.<random>.tmp``. A writer killed mid-write
(SIGKILL, power loss) cannot remove its own, so every write sweeps the stale temp files *of the
same target* first: those whose writer process no longer exists, and any older than
:data:`STALE_TEMP_S` (a live writer keeps touching its file; an old one with a live pid is a
reused pid, and temp names from before the pid was in them have no pid to check).
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from sim.errors import DexaugError

__all__ = ["STALE_TEMP_S", "atomic_path", "replace_folder", "sweep_stale_temps",
           "write_bytes_atomic"]

log = logging.getLogger(__name__)

#: Seconds after its last change when a target's temp file counts as abandoned, whoever wrote it.
STALE_TEMP_S = 300.0
# the random part tempfile.mkstemp adds: 8 characters of [a-z0-9_]
_RANDOM = r"[a-z0-9_]{8}"


def _pid_running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:   # another user's live process
        return True
    return True


def sweep_stale_temps(path: Path | str, *, stale_after_s: float = STALE_TEMP_S) -> list[Path]:
    """Remove the abandoned temp files of ``path`` (module docstring) and return them. Only names
    this module makes for exactly this target match; files of other targets are never touched."""
    path = Path(path)
    pattern = re.compile(re.escape(f".{path.name}.") + rf"(?:(\d+)\.)?{_RANDOM}\.tmp")
    removed: list[Path] = []
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match is None or not entry.is_file(follow_symlinks=False):
            continue
        try:
            age_s = now - entry.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue   # gone meanwhile
        pid = match.group(1)
        if age_s < stale_after_s and (pid is None or _pid_running(int(pid))):
            continue
        try:
            os.unlink(entry.path)
        except FileNotFoundError:
            continue
        except OSError as exc:
            log.warning("%s: cannot remove the stale temp file: %s", entry.path, exc.strerror)
            continue
        log.info("removed %s: temp file of an interrupted write (writer pid %s, %.0f s old)",
                 entry.path, pid or "unknown", age_s)
        removed.append(Path(entry.path))
    return removed


@contextmanager
def atomic_path(path: str | os.PathLike[str], *, mode: int | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path``.

    ``mode``: permission bits of the result (e.g. ``0o600`` for keys and tokens: the temp file is
    created with them, so the content is never readable by others, not even briefly); None gives
    the usual ``0666 & ~umask``. Stale temp files of ``path`` are swept first
    (:func:`sweep_stale_temps`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    sweep_stale_temps(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp",
                               dir=path.parent)   # mkstemp creates it 0600
    try:
        if mode is None:
            umask = os.umask(0)
            os.umask(umask)
            os.fchmod(fd, 0o666 & ~umask)   # outputs get the usual permissions
        elif mode & 0o777 != 0o600:
            os.fchmod(fd, mode & 0o777)
    finally:
        os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_bytes_atomic(path: str | os.PathLike[str], payload: bytes, *, mode: int | None = None) -> None:
    """Write ``payload`` to ``path`` atomically (:func:`atomic_path`, ``mode`` as there)."""
    with atomic_path(path, mode=mode) as tmp:
        tmp.write_bytes(payload)


def replace_folder(out: Path, fill: Callable[[Path], None], *, marker: str, what: str) -> None:
    """Run ``fill`` on a fresh folder beside ``out``, then put it in ``out``'s place: a reader
    never sees half an export, and a failed one leaves ``out`` as it was. Replaces only an
    empty folder or an earlier export of the same kind (one holding the file ``marker``, a
    path relative to it); anything else is refused, naming ``what`` the folder should be. The
    new folder gets the mode ``mkdir`` would give it (``mkdtemp``'s 0700 would make it
    private)."""
    if out.exists() and not (out.is_dir() and ((out / marker).is_file()
                                               or not any(out.iterdir()))):
        raise DexaugError(f"{out}: exists and is not an earlier {what} (no {marker}); "
                          "not replaced")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.{os.getpid()}.", suffix=".tmp",
                                dir=out.parent))
    try:
        umask = os.umask(0)
        os.umask(umask)
        tmp.chmod(0o777 & ~umask)
        fill(tmp)
        old = None
        if out.exists():
            old = out.with_name(f".{out.name}.{os.getpid()}.old")
            out.rename(old)
        tmp.rename(out)
        if old is not None:
            shutil.rmtree(old)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
