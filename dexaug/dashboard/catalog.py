"""What the dashboard lists: the sessions of a folder, their demos, thumbnails and results.

Every ``*.mcap`` is listed. A session that gives no demo (raw input only, no grasp, no object,
truncated beyond use, not MCAP) is listed with the reason :func:`teleop.record.demos.extract_demos`
gives, and a demo whose hand or object cannot be loaded here carries that error and cannot be
augmented: the user sees why, instead of wondering where a recording went. Extraction is
cached per file by size and modification time, so a rescan only reads new or changed files.

Thumbnails: each demo grasp is rendered once (``Validator.render``, 320×240) into
``<out>/.thumbnails/``, named by the demo's key and a hash of its grasp (a re-recorded session
under the same name never shows a stale picture). Without offscreen OpenGL, or when a render
fails, the page gets a placeholder and the reason is logged once; nothing is retried per
request. Renders run on one dedicated thread: a MuJoCo GL context belongs to the thread that
made it.
"""

from __future__ import annotations

import hashlib
import logging
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

from dexaug.dashboard.arm_jobs import arm_views
from dexaug.pipeline.options import AugmentOptions, demo_dir, run_key
from dexaug.pipeline.summary import demo_grasp_text, stored
from sim.demo import Demo
from sim.errors import DexaugError
from teleop.record.demos import extract_demos

__all__ = ["Catalog", "DemoEntry", "SessionEntry", "result_view"]

log = logging.getLogger(__name__)

THUMB_SIZE = (320, 240)


@dataclass
class DemoEntry:
    """A demo as listed: ``key`` (its output folder's name, unique and URL-safe), the demo,
    and ``error`` when it cannot be augmented here (hand or object not installed)."""

    key: str
    demo: Demo
    error: str | None = None


@dataclass
class SessionEntry:
    """A session file as listed: its demos, or the reason it has none."""

    path: Path
    size: int
    mtime_ns: int
    demos: list[DemoEntry] = field(default_factory=list)
    error: str | None = None
    warning: str | None = None


def result_view(summary: dict[str, Any], out_root: Path) -> dict[str, Any]:
    """The numbers the page shows of a ``summary.json`` (or a job's result): generated,
    passed, pass rate, failures, the demo grasp's own verdict (``demo_grasp``, None when not
    validated, and the report's wording of it), and the dashboard URL of the report (None
    without one)."""
    generated, passed = int(summary.get("generated", 0)), int(summary.get("passed", 0))
    report = summary.get("report")
    url = None
    if report:
        try:
            rel = Path(report).resolve().relative_to(out_root.resolve())
            url = "/results/" + "/".join(quote(p) for p in rel.parts)
        except ValueError:
            log.warning("report %s lies outside the output folder %s; not linked", report,
                        out_root)
    return {"generated": generated, "passed": passed,
            "pass_rate": passed / generated if generated else None,
            "requested": summary.get("requested"), "failures": summary.get("failures", {}),
            "demo_grasp": summary.get("demo_grasp"),
            "demo_grasp_text": demo_grasp_text(summary.get("demo_grasp")),
            "fsg_stopped": summary.get("fsg_stopped"), "report_url": url,
            "dataset": summary.get("dataset"), "skipped": bool(summary.get("skipped"))}


class Catalog:
    """The sessions of ``sessions_dir`` and the results in ``out_root`` under ``opts``.
    Thread-safe: the server scans from worker threads."""

    def __init__(self, sessions_dir: Path, out_root: Path, opts: AugmentOptions) -> None:
        self.sessions_dir = Path(sessions_dir)
        self.out_root = Path(out_root)
        self.opts = opts
        self.thumb_dir = self.out_root / ".thumbnails"
        self._lock = threading.Lock()
        self._sessions: dict[Path, SessionEntry] = {}
        self._loadable: dict[tuple[str, str], str | None] = {}
        self._thumb_failed: dict[str, str] = {}
        self._gl: str | None = None
        self._gl_probed = False

    # ------------------------------------------------------------------------------ sessions

    def scan(self) -> list[SessionEntry]:
        """Every ``*.mcap`` of the folder, re-reading only new or changed files."""
        if not self.sessions_dir.is_dir():
            raise DexaugError(f"sessions folder {self.sessions_dir} does not exist")
        paths = sorted(self.sessions_dir.glob("*.mcap"))
        entries = []
        for path in paths:
            try:
                st = path.stat()
            except OSError:
                continue                              # removed while scanning
            with self._lock:
                old = self._sessions.get(path)
            if old is not None and (old.size, old.mtime_ns) == (st.st_size, st.st_mtime_ns):
                entries.append(old)
                continue
            entry = self._read(path, st.st_size, st.st_mtime_ns)
            with self._lock:
                self._sessions[path] = entry
            entries.append(entry)
        with self._lock:
            for gone in set(self._sessions) - set(paths):
                del self._sessions[gone]
        return entries

    def _read(self, path: Path, size: int, mtime_ns: int) -> SessionEntry:
        entry = SessionEntry(path, size, mtime_ns)
        try:
            demos = extract_demos(path)
        except DexaugError as exc:
            entry.error = str(exc)
            log.info("%s: listed without demos: %s", path.name, exc)
            return entry
        except Exception as exc:  # a reader bug must not hide the file or stop the scan
            log.exception("%s: unexpected error reading the session", path)
            entry.error = f"{path}: unreadable ({type(exc).__name__}: {exc})"
            return entry
        entry.warning = self._truncation(path)
        entry.demos = [DemoEntry(demo_dir(self.out_root, d).name, d,
                                 self._unloadable(d.hand, d.object)) for d in demos]
        return entry

    @staticmethod
    def _truncation(path: Path) -> str | None:
        """A warning when the recorder did not close the file: its demos come from the readable
        part only, which the user should know before trusting them."""
        from teleop.record.session import SessionError, open_session

        try:
            session = open_session(path)
        except SessionError as exc:
            return str(exc)
        if not session.truncated:
            return None
        return (f"{path.name}: truncated at byte {session.stop_offset} of {path.stat().st_size} "
                f"(the recorder did not close it); demos are from the readable part")

    def _unloadable(self, hand: str, obj: str) -> str | None:
        """Why the demo's hand or object cannot be loaded here (cached), or None."""
        with self._lock:
            if (hand, obj) in self._loadable:
                return self._loadable[(hand, obj)]
        from sim.hand.model import Hand
        from sim.world.objects import load_object

        why = None
        try:
            Hand.load(hand)
            load_object(obj)
        except DexaugError as exc:
            why = str(exc)
        with self._lock:
            self._loadable[(hand, obj)] = why
        return why

    def demo(self, key: str) -> DemoEntry | None:
        """The listed demo with ``key`` (from the last scan), or None."""
        with self._lock:
            for s in self._sessions.values():
                for d in s.demos:
                    if d.key == key:
                        return d
        return None

    def result(self, entry: DemoEntry) -> dict[str, Any] | None:
        """The result of ``entry`` in the output folder, or None: finished under the dashboard's
        options and today's configs (``earlier``: False), or an earlier one made under others
        (``make demo``'s, a CLI run with another ``--n``: ``earlier`` True, and augmenting again
        replaces it); ``arms``: its grasps put on arms (:func:`arm_views`)."""
        folder = demo_dir(self.out_root, entry.demo)
        summary = stored(folder, entry.demo.id)
        if summary is None:
            return None
        return {**result_view({**summary.to_json(), "skipped": True}, self.out_root),
                "earlier": summary.run_key != run_key(entry.demo, self.opts),
                "arms": arm_views(folder, folder.name)}

    def result_dataset(self, entry: DemoEntry) -> Path | None:
        """The ``grasps.h5`` of ``entry``'s finished result, or None. Made from the catalog's
        own folder rule (:func:`demo_dir` under the output folder), never from a path a request
        or a summary names, so a web request can only reach the results the page lists."""
        folder = demo_dir(self.out_root, entry.demo)
        data = folder / "grasps.h5"
        if stored(folder, entry.demo.id) is None or not data.is_file():
            return None
        return data

    def to_json(self) -> list[dict[str, Any]]:
        """The listing for the page (a fresh scan)."""
        out = []
        for s in self.scan():
            out.append({"name": s.path.name, "size": s.size, "error": s.error,
                        "warning": s.warning,
                        "demos": [self._demo_json(d) for d in s.demos]})
        return out

    def _demo_json(self, entry: DemoEntry) -> dict[str, Any]:
        d = entry.demo
        return {"key": entry.key, "id": d.id, "hand": d.hand, "object": d.object,
                "fingers": list(d.fingers), "time_s": d.time_s, "how": d.how,
                "duration_s": d.duration_s, "error": entry.error,
                "thumbnail": f"/thumbnails/{quote(entry.key)}.png",
                "result": self.result(entry)}

    # ---------------------------------------------------------------------------- thumbnails

    def thumbnail_path(self, entry: DemoEntry) -> Path:
        d = entry.demo
        h = hashlib.sha256(b"".join(a.tobytes() for a in (d.joints, d.palm_pos_m,
                                                            d.palm_quat_wxyz))).hexdigest()[:12]
        return self.thumb_dir / f"{entry.key}-{h}.png"

    def thumbnail(self, key: str) -> tuple[Path | None, str | None]:
        """``(PNG path, None)`` for the demo ``key``'s thumbnail, rendered now if not cached,
        or ``(None, why not)``. Call from one thread only (module docstring)."""
        entry = self.demo(key)
        if entry is None:
            return None, f"no demo {key!r}"
        path = self.thumbnail_path(entry)
        if path.is_file():
            return path, None
        if key in self._thumb_failed:
            return None, self._thumb_failed[key]
        why = entry.error or self._gl_missing()
        if why is None:
            try:
                self._render(entry, path)
                return path, None
            except Exception as exc:  # a failed render is a placeholder, never a crash
                why = f"render failed: {type(exc).__name__}: {exc}"
        log.warning("thumbnail of %s: %s", entry.demo.id, why)
        self._thumb_failed[key] = why
        return None, why

    def _gl_missing(self) -> str | None:
        if not self._gl_probed:
            from sim.world.render import gl_available

            self._gl, self._gl_probed = gl_available(), True
        return None if self._gl else "no offscreen OpenGL on this machine (make gl)"

    def _render(self, entry: DemoEntry, path: Path) -> None:
        from sim.hand.model import Hand
        from sim.validate.validator import Validator
        from sim.world.objects import load_object
        from sim.world.render import save_png

        d = entry.demo
        img = Validator(Hand.load(d.hand), load_object(d.object)).render(d.grasp, *THUMB_SIZE)
        path.parent.mkdir(parents=True, exist_ok=True)
        save_png(path, img)
