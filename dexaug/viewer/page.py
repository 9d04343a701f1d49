"""The viewer as one self-contained HTML file: the page, its script and the scene inline.

Why one file: it opens the same from the dashboard (``/results/…/viewer.html``), from a report
folder copied elsewhere and from a ``file://`` URL, where a browser refuses to fetch a JSON file
beside the page. Written atomically, like every output.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from dexaug.viewer.scene import scene_json
from sim.io import write_bytes_atomic

__all__ = ["viewer_html", "write_viewer"]


def _static(name: str) -> str:
    return (resources.files("dexaug.viewer") / "static" / name).read_text(encoding="utf-8")


def viewer_html(scene: dict[str, Any]) -> str:
    """The page for ``scene`` (:func:`dexaug.viewer.scene.viewer_scene`)."""
    script = _static("viewer.js")
    if "</script" in script.lower():
        raise ValueError("viewer.js must not contain '</script' (it is inlined in the page)")
    template = _static("viewer.html")
    # the scene last: its base64 and JSON text can never hold the script placeholder
    return template.replace("__VIEWER_JS__", script).replace("__SCENE__", scene_json(scene))


def write_viewer(path: Path, scene: dict[str, Any]) -> Path:
    """Write the viewer page for ``scene`` to ``path`` (atomically); returns ``path``."""
    write_bytes_atomic(Path(path), viewer_html(scene).encode("utf-8"))
    return Path(path)
