"""The per-demo HTML report: demo image and verdict, gallery of kept grasps, palm-position
cloud, metrics.

The report states exactly the numbers of ``summary.json`` and the dataset (it is written from
the same :class:`~dexaug.pipeline.summary.DemoSummary` and table), so a reader can trust either. The
palm-position cloud is the paper's Figs. 10–11 view: every kept grasp's palm position around
the object's point cloud, seen from the top (x–y) and the side (x–z), drawn with OpenCV (no
plotting library needed). Renders need offscreen OpenGL; without it the report says so and
keeps the numbers.
"""

from __future__ import annotations

import html
import logging
import re
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from dexaug.pipeline.summary import DemoSummary, demo_grasp_text
from sim.io import write_bytes_atomic
from sim.world.render import gl_available, save_png

if TYPE_CHECKING:
    from augment.dataset import ObjectTable
    from sim.demo import Demo
    from sim.grasp import Grasp
    from sim.hand.model import Hand
    from sim.world.objects import ObjectAsset

__all__ = ["palm_cloud_image", "write_report"]

log = logging.getLogger(__name__)


def palm_cloud_image(object_points: np.ndarray, palm_positions: np.ndarray,
                     size_px: int = 360) -> np.ndarray:
    """RGB image: top (x–y) and side (x–z) views of the object points (grey) and the palm
    positions (red), same metric scale in both, object frame, axes labelled."""
    views = (("top  x-y", (0, 1)), ("side  x-z", (0, 2)))
    allp = np.vstack([object_points, palm_positions]) if len(palm_positions) else object_points
    centre = 0.5 * (allp.min(axis=0) + allp.max(axis=0))
    half = 0.55 * float(np.max(allp.max(axis=0) - allp.min(axis=0))) or 0.1
    panels = []
    for title, (a, b) in views:
        img = np.full((size_px, size_px, 3), 255, np.uint8)

        def px(p: np.ndarray, a: int = a, b: int = b) -> np.ndarray:
            u = (p[:, a] - centre[a]) / half * 0.5 + 0.5
            v = 0.5 - (p[:, b] - centre[b]) / half * 0.5
            return np.round(np.column_stack([u, v]) * (size_px - 1)).astype(int)

        for u, v in px(object_points):
            cv2.circle(img, (int(u), int(v)), 1, (170, 170, 170), -1)
        for u, v in px(palm_positions):
            cv2.circle(img, (int(u), int(v)), 3, (220, 40, 40), -1)
        cv2.putText(img, title, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1)
        bar = 0.05 / (2 * half) * (size_px - 1)   # a 5 cm scale bar
        cv2.line(img, (10, size_px - 12), (10 + int(bar), size_px - 12), (0, 0, 0), 2)
        cv2.putText(img, "5 cm", (12, size_px - 18), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        panels.append(img)
    return np.hstack(panels)


def _render(hand: Hand, obj: ObjectAsset, grasps: list[Grasp], folder: Path,
            names: list[str]) -> list[str]:
    from sim.validate.validator import Validator

    validator = Validator(hand, obj)
    out = []
    for g, name in zip(grasps, names, strict=True):
        save_png(folder / name, validator.render(g, width=320, height=240))
        out.append(name)
    return out


def write_report(folder: Path, demo: Demo, hand: Hand, obj: ObjectAsset, table: ObjectTable,
                 summary: DemoSummary, object_points: np.ndarray, *, gallery: int = 6) -> Path:
    """Write ``report.html`` and its PNGs into ``folder``; returns the HTML path.
    ``object_points`` (n, 3): the object cloud the palm positions are drawn around."""
    from sim.grasp import Grasp

    pose = table["palm_pose"]
    save_png(folder / "palm_cloud.png", palm_cloud_image(np.asarray(object_points), pose[:, :3]))
    images: list[str] = []
    note = ""
    if gl_available() is not None:
        order = np.argsort(-table["sim_epsilon"] if np.isfinite(table["sim_epsilon"]).any()
                           else -table["gws"])[:gallery]
        kept = [Grasp.from_arrays(pose[i, :3], pose[i, 3:], table["hand_pose"][i])
                for i in order]
        images = _render(hand, obj, [demo.grasp, *kept], folder,
                         ["demo.png", *[f"grasp_{k:02d}.png" for k in range(len(kept))]])
    else:
        note = "<p><em>No offscreen OpenGL on this machine: grasp images were not rendered.</em></p>"
    doc = _html(demo, summary, images, note)
    path = folder / "report.html"
    write_bytes_atomic(path, doc.encode())
    return path


def _html(demo: Demo, s: DemoSummary, images: list[str], note: str) -> str:
    e = html.escape
    rows = [("object", s.object), ("hand", s.hand), ("demo", f"{demo.id} ({demo.how}, fingers "
            f"{', '.join(demo.fingers) or '—'})"), ("source", s.source),
            ("grasps requested", s.requested), ("grasps generated (FSG)", s.generated),
            ("grasps passed validation", s.passed),
            ("pass rate", f"{100 * s.passed / s.generated:.1f} %" if s.generated else "—"),
            ("demonstration grasp", demo_grasp_text(s.demo_grasp)),
            ("FSG stopped", s.fsg_stopped),
            ("validated grasps / min", f"{s.validated_per_min:.1f}")]
    rows += [(f"failures: {k}", v) for k, v in sorted(s.failures.items())]
    rows += [(k.replace("_", " "), f"{v:.4g}") for k, v in s.metrics.items()]
    rows += [(f"time: {k} (s)", f"{v:.2f}") for k, v in s.timings_s.items()]
    table = "\n".join(f"<tr><th>{e(str(k))}</th><td id='m-{e(_slug(str(k)))}'>{e(str(v))}</td></tr>"
                      for k, v in rows)
    demo_img = "<img src='demo.png' alt='demo grasp'>" if "demo.png" in images else ""
    gallery = "".join(f"<img src='{e(n)}' alt='{e(n)}'>" for n in images if n != "demo.png")
    return f"""<!doctype html>
<html><head><meta charset="utf-8"><title>dexaug report: {e(s.demo_id)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1100px}}
table{{border-collapse:collapse}}th,td{{border:1px solid #ccc;padding:4px 8px;text-align:left}}
img{{margin:4px;border:1px solid #ddd}}</style></head>
<body><h1>Augmentation of {e(s.demo_id)}</h1>
<h2>Demonstration</h2>{demo_img}{note}
<p id="demo-grasp">Demonstration grasp: {e(demo_grasp_text(s.demo_grasp))}</p>
<h2>Metrics</h2><table id="metrics">{table}</table>
<h2>Palm positions of the kept grasps</h2><img src="palm_cloud.png" alt="palm cloud">
<h2>Gallery (best simulated ε first)</h2>{gallery or '<p>No grasps passed.</p>'}
<p>Dataset: <code>{e(s.dataset)}</code> (load with <code>augment.dataset.load(path)</code>).</p>
</body></html>
"""


def _slug(text: str) -> str:
    """``"grasps generated (FSG)"`` → ``"grasps-generated-fsg"``: stable ids for tests/tools."""
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")
