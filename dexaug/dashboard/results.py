"""Every result folder under the dashboard's output folder, whatever made it.

Why: results are not only the listed sessions' (``make demo``, ``dexaug augment`` with another
``--out`` below it, a session since deleted); a user looks for them all on one page. A folder is
a result when it holds ``summary.json``; the search goes :data:`MAX_DEPTH` folders down and
skips hidden ones (``.thumbnails``). A summary that cannot be read is listed with the reason.
Links are ``/results/…`` URLs relative to the output folder, never a file-system path.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any
from urllib.parse import quote

__all__ = ["MAX_DEPTH", "list_results"]

MAX_DEPTH = 4
#: the files a result folder may hold that the page links to
LINKED = {"report": "report.html", "viewer": "viewer.html"}


def _url(rel: Path) -> str:
    return "/results/" + "/".join(quote(p) for p in rel.parts)


def _summaries(root: Path) -> list[Path]:
    found = []
    for here, dirs, files in os.walk(root):
        depth = len(Path(here).relative_to(root).parts)
        dirs[:] = sorted(d for d in dirs if not d.startswith(".")) if depth < MAX_DEPTH else []
        if "summary.json" in files:
            found.append(Path(here) / "summary.json")
    return sorted(found)


def _entry(root: Path, path: Path) -> dict[str, Any]:
    folder = path.parent
    rel = folder.relative_to(root)
    entry: dict[str, Any] = {"folder": rel.as_posix() or ".", "error": None,
                             **{k: (_url(rel / f) if (folder / f).is_file() else None)
                                for k, f in LINKED.items()}}
    try:
        doc = json.loads(path.read_text())
        generated, passed = int(doc["generated"]), int(doc["passed"])
        entry.update(demo=str(doc["demo_id"]), object=str(doc["object"]), hand=str(doc["hand"]),
                     generated=generated, passed=passed,
                     pass_rate=passed / generated if generated else None)
    except OSError as exc:   # its text would name the absolute path: only the cause is shown
        entry["error"] = (f"{rel.as_posix()}/summary.json is unreadable "
                          f"({type(exc).__name__}: {exc.strerror or 'cannot be read'})")
    except (ValueError, KeyError, TypeError) as exc:
        entry["error"] = (f"{rel.as_posix()}/summary.json is unreadable "
                          f"({type(exc).__name__}: {exc})")
    return entry


def list_results(root: Path) -> list[dict[str, Any]]:
    """One entry per result folder under ``root`` (module docstring), in path order."""
    root = Path(root)
    if not root.is_dir():
        return []
    return [_entry(root, p) for p in _summaries(root)]
