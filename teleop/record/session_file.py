"""A recording's file on disk: created without clobbering, cut back to its last complete chunk
when a write fails.

Why apart from the recorder (:mod:`teleop.record.recorder`): what reaches the disk and what is
left after a write error — a full disk (ENOSPC), EFBIG past ``RLIMIT_FSIZE``, any OSError — is
one concern, the session's channels and payloads another. MCAP is append-only, so a file that
ends at a record boundary is a valid prefix, which :func:`teleop.record.session.open_session`
reads as truncated; a partial record at its end would read as damage instead. So the file
remembers its size each time it ends at a complete chunk (:meth:`SessionFile.mark_good`), and
on a write error (in :meth:`SessionFile.guard`) it is closed and cut back to that size; the
error, :class:`RecordingFailed`, names the file, what failed and how many bytes were kept.

The ``foxglove-sdk``'s MCAP writer writes through this object (``write``/``seek``/``flush``, the
file-like protocol it takes): the SDK turns an OSError of ours into its own RuntimeError ("a
write method failed") or, inside a ``log`` call, only a log line, so :meth:`write` keeps the
OS's error and :meth:`guard` raises it — the OS's words, never the SDK's paraphrase — after
any SDK call, whether or not the SDK raised. Passing our stream (not a path) also keeps the
no-clobber open (``xb``) and lets :meth:`teleop.record.recorder.SessionRecorder.close` fsync.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from teleop.record.session import SessionError

__all__ = ["RecordingFailed", "SessionFile"]


class RecordingFailed(SessionError):
    """Writing a recording failed; the file is readable up to its last complete chunk."""


class SessionFile:
    """``path`` opened for writing: a new file, or (``overwrite``) replacing one.

    Raises :class:`SessionError` naming the file when it exists (without ``overwrite``) or
    cannot be created. ``stream`` is the binary file the MCAP writer writes to.
    """

    def __init__(self, path: Path, *, overwrite: bool) -> None:
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self.stream = open(path, "wb" if overwrite else "xb")  # noqa: SIM115
        except FileExistsError:
            raise SessionError(f"{path}: a recording already exists there (pass "
                               "overwrite=True to replace it)") from None
        except OSError as exc:
            raise SessionError(f"{path}: cannot create the recording: {exc.strerror}") from None
        #: why writing stopped (the OS's words), and the whole story; None while writes succeed
        self.reason: str | None = None
        self.failure: str | None = None
        self.good_bytes = 0
        #: the first OSError a write met (kept for :meth:`guard`: the SDK swallows it)
        self.write_error: OSError | None = None

    # --- the file-like protocol of the SDK's MCAP writer --------------------------------------

    def write(self, data: bytes | bytearray) -> int:
        if self.write_error is not None:   # after a failure (or a close) nothing more lands
            raise self.write_error
        try:
            return self.stream.write(data)
        except OSError as exc:
            self.write_error = exc
            raise
        except ValueError as exc:   # closed: the SDK's writer finishing after a failure
            raise OSError(f"{self.path} is closed") from exc

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        try:
            return self.stream.seek(offset, whence)
        except OSError as exc:   # a seek flushes Python's buffer: a write error shows here
            self.write_error = self.write_error or exc
            raise

    def flush(self) -> None:
        try:
            self.stream.flush()
        except OSError as exc:
            self.write_error = self.write_error or exc
            raise

    def mark_good(self) -> int:
        """The file ends at a complete record now (its bytes handed to the OS): remember and
        return its size in bytes."""
        self.good_bytes = self.stream.tell()
        return self.good_bytes

    @contextlib.contextmanager
    def guard(self) -> Iterator[None]:
        """Around a write (ours or the SDK writer's): an OSError in it — raised, or met by
        :meth:`write` and reported by the SDK as a RuntimeError or not at all — becomes
        :meth:`fail`'s error."""
        try:
            yield
        except (OSError, RuntimeError) as exc:
            error = self.write_error or (exc if isinstance(exc, OSError) else None)
            if error is None:
                raise
            raise self.fail(error) from None
        if self.write_error is not None:
            raise self.fail(self.write_error) from None

    def fail(self, exc: OSError) -> RecordingFailed:
        """After a write error: close the file, cut it back to the last good size; the error
        to raise (its message also in :attr:`failure`; the caller says it where it matters)."""
        self.write_error = self.write_error or exc
        with contextlib.suppress(OSError):   # the buffered rest fails again; the fd is closed
            self.stream.close()
        with contextlib.suppress(OSError):
            os.truncate(self.path, self.good_bytes)
        self.reason = exc.strerror or str(exc)
        self.failure = (f"{self.path}: writing the recording failed ({self.reason}); "
                        f"kept {self.good_bytes} bytes, up to its last complete chunk")
        return RecordingFailed(self.failure)

    def discard(self) -> None:
        """Close and remove the file (a recording that could not even start holds nothing)."""
        with contextlib.suppress(OSError):
            self.stream.close()
        self.path.unlink(missing_ok=True)
