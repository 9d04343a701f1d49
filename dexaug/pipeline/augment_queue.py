"""Augmentations of recorded sessions in child processes, queued (``bridge --auto-augment``).

Why child processes: the bridge's loop must never wait on an augmentation, and a crash or a
hang in one ends only that one. Each runs ``python -m dexaug augment SESSION --out OUT
[augment_args]`` with its output in ``OUT/<session>.augment.log``.

Why a queue: one ``dexaug augment`` already uses every core it is given and a few hundred MB;
starting one per stopped recording without a limit made 8 processes (1.15 GB) in 6 s of quick
start/stops. Here at most ``max_running`` run at once (one by default), in the order submitted.

Why a bound, and why the newest is refused: at most ``max_waiting`` sessions wait; a submission
beyond that is refused with a warning that names the command to run later. Refusing the newest
(rather than dropping the oldest waiting one) keeps the queue's word to the sessions it has
accepted, and the one refused is the one whose warning the operator just saw.

Every start, finish (with its exit code and duration) and refusal is logged (``logging``) and
passed to ``notify`` (the bridge's console). :meth:`AugmentQueue.close` lets the queue run out
(up to a timeout), then drops what still waits and terminates what still runs.
"""

from __future__ import annotations

import collections
import logging
import shlex
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from dexaug.pipeline.exit_status import SHORT_SHARE, SHORT_STATUS

__all__ = ["AugmentQueue", "CommandFactory"]

log = logging.getLogger(__name__)

#: ``command(session) -> argv`` of the process that augments ``session``.
CommandFactory = Callable[[Path], Sequence[str]]
#: How long a terminated process has to exit before it is killed, in seconds.
TERMINATE_GRACE_S = 5.0


class AugmentQueue:
    """Augment each submitted session in a child process (module docstring). Callable with the
    closed recording's path, so it serves as the bridge's ``on_recording_closed`` hook.

    ``command`` replaces the ``dexaug augment`` command line (tests run a cheap one);
    ``notify`` receives each one-line message (the console), besides the log.
    """

    def __init__(self, out: Path, augment_args: Sequence[str] = (), *, max_running: int = 1,
                 max_waiting: int = 8, command: CommandFactory | None = None,
                 notify: Callable[[str], None] | None = None) -> None:
        if max_running < 1 or max_waiting < 0:
            raise ValueError(f"max_running must be >= 1 and max_waiting >= 0, got {max_running} "
                             f"and {max_waiting}")
        self.out = Path(out)
        self.augment_args = tuple(augment_args)
        self.max_waiting = max_waiting
        self.command: CommandFactory = command or self._augment_command
        self._notify = notify
        self._cond = threading.Condition()
        self._waiting: collections.deque[Path] = collections.deque()
        self._running: set[subprocess.Popen[bytes]] = set()
        self._closing = False   # no more submissions; the workers drain the queue
        self._stopping = False  # drop what waits, start nothing more
        self._workers = [threading.Thread(target=self._work, name=f"dexaug-augment-{k}",
                                          daemon=True) for k in range(max_running)]
        for w in self._workers:
            w.start()

    def _augment_command(self, session: Path) -> list[str]:
        return [sys.executable, "-m", "dexaug", "augment", str(session), "--out", str(self.out),
                *self.augment_args]

    def __call__(self, session: Path) -> None:
        self.submit(session)

    def submit(self, session: Path) -> bool:
        """Queue ``session``; False (and a warning) when the queue is full or closed."""
        session = Path(session)
        with self._cond:
            refused = ("the queue is closed" if self._closing else
                       f"{len(self._waiting)} sessions already wait"
                       if len(self._waiting) >= self.max_waiting else None)
            if refused is None:
                self._waiting.append(session)
                self._cond.notify()
                waiting = len(self._waiting)
        if refused is not None:
            self._say(logging.WARNING, f"not augmenting {session}: {refused}; run "
                      f"`{shlex.join(self.command(session))}` later")
            return False
        self._say(logging.INFO, f"queued {session} for augmentation ({waiting} waiting)")
        return True

    def close(self, timeout_s: float | None = None) -> None:
        """Take no more sessions and let the queue run out for up to ``timeout_s`` (None: until
        it has); then, or on Ctrl-C meanwhile, drop what still waits and terminate what runs."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        try:
            for w in self._workers:
                w.join(None if deadline is None else max(0.0, deadline - time.monotonic()))
        finally:
            if any(w.is_alive() for w in self._workers):
                self._stop()

    # ---------------------------------------------------------------------------- internals

    def _say(self, level: int, message: str) -> None:
        log.log(level, "%s", message)
        if self._notify is not None:
            self._notify(message)

    def _stop(self) -> None:
        with self._cond:
            self._stopping = True
            dropped, running = list(self._waiting), list(self._running)
            self._waiting.clear()
            self._cond.notify_all()
        for session in dropped:
            self._say(logging.WARNING, f"not augmenting {session}: stopping; run "
                      f"`{shlex.join(self.command(session))}` later")
        for proc in running:
            proc.terminate()
        for proc in running:
            try:
                proc.wait(TERMINATE_GRACE_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for w in self._workers:
            w.join(TERMINATE_GRACE_S)

    def _work(self) -> None:
        while True:
            with self._cond:
                while not (self._waiting or self._closing or self._stopping):
                    self._cond.wait()
                if self._stopping or not self._waiting:
                    return
                session = self._waiting.popleft()
            self._run(session)

    def _run(self, session: Path) -> None:
        log_path = self.out / f"{session.stem}.augment.log"
        argv = list(self.command(session))
        try:
            self.out.mkdir(parents=True, exist_ok=True)
            with open(log_path, "ab") as log_file, self._cond:
                if self._stopping:
                    return
                proc = subprocess.Popen(argv, stdout=log_file, stderr=subprocess.STDOUT,
                                        stdin=subprocess.DEVNULL)
                self._running.add(proc)
        except OSError as exc:
            self._say(logging.ERROR, f"cannot start the augmentation of {session}: {exc}")
            return
        t0 = time.monotonic()
        self._say(logging.INFO, f"augmenting {session} (pid {proc.pid}, log: {log_path})")
        code = proc.wait()
        with self._cond:
            self._running.discard(proc)
        took = f"{time.monotonic() - t0:.1f} s"
        if code == 0:
            self._say(logging.INFO, f"augmented {session} (exit code 0, {took})")
        elif code == SHORT_STATUS:
            self._say(logging.WARNING, f"augmented {session}, short of the grasps asked for "
                      f"(exit code {code}: fewer than {SHORT_SHARE:.0%} of --n; {took}; log: "
                      f"{log_path})")
        else:
            self._say(logging.WARNING, f"augmentation of {session} failed (exit code {code}, "
                      f"{took}; log: {log_path})")
