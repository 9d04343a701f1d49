"""The dashboard's job queue: one job (an augmentation, or a result put on an arm) at a time,
on a worker thread of the server.

Why a thread and not a child process per job: the pipeline already runs its heavy parts in
process pools (FSG's fork-server pool, validation's spawn pool), and FSG keeps its pool alive for
the life of the process because starting workers costs about as much as a demo-seeded run; a
job in this process reuses that pool from one click to the next, where a child per job would pay
it every time (and could not exit while the pool's workers lived). What stays on the thread
(AutoWS clouds, the report's renders) is NumPy and MuJoCo code that releases the GIL for its
heavy parts. The web handlers only read job state copied under a lock, so the event loop never
waits on a job; a job's exception of any kind ends that job as "failed" with its message, never
the server.

Why one at a time: every job already uses all the workers it is given; two at once would only
halve each other's speed and make the progress bars lie about the time left.

Why bounded: the list lives as long as the server and every click adds to it. Finished jobs
beyond ``max_finished`` are forgotten oldest first (their results stay on disk, where the session
list finds them); a submission while ``max_queued`` jobs already wait is refused
(:class:`JobQueueFull`) rather than queued for hours.
"""

from __future__ import annotations

import itertools
import logging
import queue
import threading
import time
import traceback
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from sim.errors import DexaugError

__all__ = ["Job", "JobQueue", "JobQueueFull", "JobTarget", "run_augmentation"]

log = logging.getLogger(__name__)

#: What a job runs: ``target(payload, progress) -> result`` (JSON-able);
#: ``progress(stage, done, total)`` is the pipeline's callback.
JobTarget = Callable[[Any, Callable[[str, int, int], None]], dict[str, Any]]

#: Job states, in order; "done" and "failed" are final.
STATES = ("queued", "running", "done", "failed")


class JobQueueFull(DexaugError):
    """A job was submitted while the queue held its maximum of waiting jobs."""


@dataclass
class Job:
    """One queued or finished job: what it is for (``key``, ``label``; ``kind``: "augment" or
    "arm", ``demo``: the listed demo it belongs to), where it is (``state``, the pipeline
    ``stage`` and its ``done``/``total``), and how it ended (``result`` or ``error``; ``detail``
    holds a traceback for errors that are not dexaug's). ``target`` replaces the queue's own
    for this job (a kind of job the queue was not made for)."""

    id: int
    key: str
    label: str
    payload: Any = field(repr=False)
    kind: str = "augment"
    demo: str = ""
    target: JobTarget | None = field(default=None, repr=False)
    state: str = "queued"
    stage: str = ""
    done: int = 0
    total: int = 0
    result: dict[str, Any] | None = None
    error: str | None = None
    detail: str | None = None
    queued_at: float = field(default_factory=time.time)
    started_at: float | None = None
    finished_at: float | None = None

    @property
    def active(self) -> bool:
        return self.state in ("queued", "running")

    def to_json(self) -> dict[str, Any]:
        return {"id": self.id, "key": self.key, "label": self.label, "kind": self.kind,
                "demo": self.demo or self.key, "state": self.state,
                "stage": self.stage, "done": self.done, "total": self.total,
                "result": self.result, "error": self.error, "queued_at": self.queued_at,
                "started_at": self.started_at, "finished_at": self.finished_at}


class JobQueue:
    """Jobs run one after another on a worker thread (module docstring).

    ``target`` is run for every job (tests give a fake one). :meth:`submit` returns at once;
    :meth:`snapshot` gives every job's state as JSON for the page. At most ``max_queued`` jobs
    wait and ``max_finished`` finished ones are kept (module docstring).
    """

    def __init__(self, target: JobTarget, *, max_queued: int = 20, max_finished: int = 100) -> None:
        if max_queued < 1 or max_finished < 0:
            raise ValueError(f"max_queued must be >= 1 and max_finished >= 0, got {max_queued} "
                             f"and {max_finished}")
        self._target = target
        self.max_queued, self.max_finished = max_queued, max_finished
        self._lock = threading.Lock()
        self._jobs: dict[int, Job] = {}
        self._pending: queue.Queue[Job | None] = queue.Queue()
        self._ids = itertools.count(1)
        self._closing = threading.Event()
        self._worker = threading.Thread(target=self._run, name="dexaug-jobs", daemon=True)
        self._worker.start()

    def submit(self, key: str, label: str, payload: Any, *, kind: str = "augment",
               demo: str = "", target: JobTarget | None = None) -> Job:
        """Queue a job for ``key`` (a demo, or a demo on an arm); while one for that key is
        queued or running, that one is returned instead (a double click starts nothing twice).
        ``kind``, ``demo`` and ``target``: see :class:`Job`. Raises :class:`JobQueueFull`
        while ``max_queued`` jobs wait."""
        with self._lock:
            for job in self._jobs.values():
                if job.key == key and job.active:
                    return job
            waiting = [j.kind for j in self._jobs.values() if j.state == "queued"]
            if len(waiting) >= self.max_queued:
                raise JobQueueFull(f"{_count_kinds(waiting)} already waiting (the most the "
                                   "dashboard queues); try again when one has started")
            job = Job(next(self._ids), key, label, payload, kind, demo, target)
            self._jobs[job.id] = job
        log.info("job %d queued: %s", job.id, label)
        self._pending.put(job)
        return job

    def snapshot(self) -> list[dict[str, Any]]:
        """Every job (oldest first) as JSON-able dicts, copied under the lock."""
        with self._lock:
            return [j.to_json() for j in self._jobs.values()]

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop taking jobs; queued ones are dropped. A running job cannot be interrupted (the
        pipeline has no cancel): the worker is a daemon thread and is waited for only
        ``timeout_s``, and an unfinished demo is redone next time (no summary is written)."""
        self._closing.set()
        self._pending.put(None)
        self._worker.join(timeout_s)
        if self._worker.is_alive():
            log.warning("a job is still running; leaving it to end with the process")

    # ---------------------------------------------------------------------------- internals

    def _update(self, job: Job, **fields: Any) -> None:
        with self._lock:
            for k, v in fields.items():
                setattr(job, k, v)
            if not job.active:
                self._forget_oldest_finished()

    def _forget_oldest_finished(self) -> None:
        """Drop finished jobs beyond ``max_finished``, oldest first (the lock is held)."""
        finished = [i for i, j in self._jobs.items() if not j.active]   # ids ascend: oldest first
        for i in finished[: max(0, len(finished) - self.max_finished)]:
            del self._jobs[i]

    def _run(self) -> None:
        while not self._closing.is_set():
            job = self._pending.get()
            if job is None:
                break
            self._run_one(job)

    def _run_one(self, job: Job) -> None:
        if self._closing.is_set():
            self._update(job, state="failed", error="stopped: the dashboard is shutting down",
                         finished_at=time.time())
            return
        self._update(job, state="running", started_at=time.time())
        log.info("job %d started: %s", job.id, job.label)

        def progress(stage: str, done: int, total: int) -> None:
            self._update(job, stage=str(stage), done=int(done), total=int(total))

        try:
            result = (job.target or self._target)(job.payload, progress)
        except DexaugError as exc:
            self._failed(job, str(exc), None)
            return
        except Exception as exc:  # any failure ends this job, never the queue or the server
            self._failed(job, f"{type(exc).__name__}: {exc}", traceback.format_exc())
            return
        self._update(job, state="done", result=result, finished_at=time.time())
        log.info("job %d done: %s", job.id, job.label)

    def _failed(self, job: Job, error: str, detail: str | None) -> None:
        self._update(job, state="failed", error=error, detail=detail, finished_at=time.time())
        log.error("job %d failed: %s: %s%s", job.id, job.label, error,
                  f"\n{detail}" if detail else "")


def run_augmentation(payload: tuple[Any, str, Any], progress: Callable[[str, int, int], None]
                     ) -> dict[str, Any]:
    """The dashboard's job: ``augment_demo(demo, out_root, opts)``; returns the
    summary as written to ``summary.json`` plus ``skipped``."""
    from dexaug.pipeline.run import augment_demo

    demo, out_root, opts = payload
    summary = augment_demo(demo, out_root, opts, progress=progress)
    return {**summary.to_json(), "skipped": summary.skipped}


#: what a job of each kind is called in messages (singular, plural)
_KIND_NAMES = {"augment": ("augmentation", "augmentations"), "arm": ("arm run", "arm runs")}


def _count_kinds(kinds: list[str]) -> str:
    """The waiting jobs by kind for the queue-full message, the verb agreeing:
    ``["augment", "arm", "augment"]`` → "1 arm run and 2 augmentations are"."""
    counts = Counter(kinds)
    parts = [f"{n} {_KIND_NAMES.get(k, (k + ' job', k + ' jobs'))[n != 1]}"
             for k, n in sorted(counts.items())]
    verb = "is" if len(kinds) == 1 else "are"
    return f"{' and '.join(parts)} {verb}"
