"""The per-demo HTML report: demo image and verdict, gallery of kept grasps, palm-position
cloud, metrics.

The report states exactly the numbers of ``summary.json`` and the dataset (it is written from
the same :class:`~dexaug.pipeline.summary.DemoSummary` and table), so a reader can trust either. The
palm-position cloud is the paper's Figs. 10–11 view: every kept grasp's palm position around
the object's point cloud, seen from the top (x–y) and the side (x–z), drawn with Pillow (no
plotting library needed). Renders need offscreen OpenGL; without it the report says so and
keeps the numbers.
"""

from __future__ import annotations

import html
import logging
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dexaug.pipeline.summary import DemoSummary, demo_grasp_text
from dexaug.viewer.page import write_viewer
from dexaug.viewer.scene import viewer_scene
from sim.io import write_bytes_atomic
from sim.world.drawing import Canvas
from sim.world.render import gl_available, save_png

if TYPE_CHECKING:
    from augment.dataset import ObjectTable
    from sim.demo import Demo
    from sim.grasp import Grasp
    from sim.hand.model import Hand
    from sim.world.objects import ObjectAsset

__all__ = ["palm_cloud_image", "write_report"]

log = logging.getLogger(__name__)

#: the interactive 3D viewer written beside the report (:mod:`dexaug.viewer`)
VIEWER_PAGE = "viewer.html"


def palm_cloud_image(object_points: np.ndarray, palm_positions: np.ndarray,
                     size_px: int = 360, *, demo_palm: np.ndarray | None = None,
                     table: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """RGB image: top (x–y) and side (x–z) views of the object points (grey), the palm
    positions (red), the demonstration's palm (green diamond) and the table plane (blue line,
    ``table`` = (point, unit normal)), same metric scale in both, object frame: each panel has
    its two axes drawn from the object's origin and labelled, a 5 cm scale bar and a legend."""
    views = (("top  x-y", (0, 1)), ("side  x-z", (0, 2)))
    extra = [p for p in (demo_palm,) if p is not None]
    allp = np.vstack([object_points, np.reshape(palm_positions, (-1, 3)),
                      *[np.reshape(e, (1, 3)) for e in extra]])
    centre = 0.5 * (allp.min(axis=0) + allp.max(axis=0))
    half = 0.55 * float(np.max(allp.max(axis=0) - allp.min(axis=0))) or 0.1
    names = "xyz"
    panels = []
    for title, (a, b) in views:
        img = np.full((size_px, size_px, 3), 255, np.uint8)

        def px(p: np.ndarray, a: int = a, b: int = b) -> np.ndarray:
            p = np.reshape(p, (-1, 3))
            u = (p[:, a] - centre[a]) / half * 0.5 + 0.5
            v = 0.5 - (p[:, b] - centre[b]) / half * 0.5
            return np.round(np.column_stack([u, v]) * (size_px - 1)).astype(int)

        with Canvas(img) as canvas:
            if table is not None:
                _table_line(canvas, table, a, b, centre, half, size_px)
            for uv in px(object_points):
                canvas.disk(uv, 1, (170, 170, 170))
            for uv in px(palm_positions):
                canvas.disk(uv, 3, (220, 40, 40))
            if demo_palm is not None:
                canvas.diamond(px(demo_palm)[0], (0, 150, 60), size=16, width=3)
            (ou, ov), = px(np.zeros(3))
            arrow = int(0.25 * size_px)
            for axis, (du, dv) in ((a, (arrow, 0)), (b, (0, -arrow))):
                canvas.arrow((ou, ov), (ou + du, ov + dv), (40, 40, 40), tip=0.08)
                canvas.text((ou + du + 4, ov + dv + 4), names[axis], (40, 40, 40), size_px=14)
            canvas.text((8, 20), title + " (object frame)", (0, 0, 0), size_px=15)
            bar = 0.05 / (2 * half) * (size_px - 1)   # a 5 cm scale bar
            canvas.line((10, size_px - 12), (10 + int(bar), size_px - 12), (0, 0, 0), width=2)
            canvas.text((12, size_px - 18), "5 cm", (0, 0, 0), size_px=12)
        panels.append(img)
    legend = np.full((24, 2 * size_px, 3), 255, np.uint8)
    with Canvas(legend) as canvas:
        canvas.text((8, 16), "grey: object   red: palms of kept grasps   green: demo palm   "
                    "blue: table", (0, 0, 0), size_px=14)
    return np.vstack([np.hstack(panels), legend])


def _table_line(canvas: Canvas, table: tuple[np.ndarray, np.ndarray], a: int, b: int,
                centre: np.ndarray, half: float, size_px: int) -> None:
    """The table plane's trace in the (a, b) view: where it cuts the plane through the view's
    centre along the third axis; nothing when the plane is (nearly) parallel to the view."""
    point, normal = (np.asarray(x, float) for x in table)
    c = 3 - a - b
    rest = float(normal @ point) - normal[c] * centre[c]   # n_a·u + n_b·v = rest
    span = np.array([-1.0, 1.0]) * 2 * half
    if abs(normal[b]) >= abs(normal[a]) and abs(normal[b]) > 1e-6:
        us = centre[a] + span
        vs = (rest - normal[a] * us) / normal[b]
    elif abs(normal[a]) > 1e-6:
        vs = centre[b] + span
        us = (rest - normal[b] * vs) / normal[a]
    else:
        return
    pts = [(round(((u - centre[a]) / half * 0.5 + 0.5) * (size_px - 1)),
            round((0.5 - (v - centre[b]) / half * 0.5) * (size_px - 1)))
           for u, v in zip(us, vs, strict=True)]
    canvas.line(pts[0], pts[1], (60, 90, 220), width=2)


def _render(hand: Hand, obj: ObjectAsset, grasps: list[Grasp], folder: Path,
            names: list[str]) -> list[str]:
    from sim.validate.validator import Validator

    validator = Validator(hand, obj)
    out = []
    for g, name in zip(grasps, names, strict=True):
        save_png(folder / name, validator.render(g, width=480, height=360))
        out.append(name)
    return out


def write_report(folder: Path, demo: Demo, hand: Hand, obj: ObjectAsset, table: ObjectTable,
                 summary: DemoSummary, object_points: np.ndarray, *, gallery: int = 6) -> Path:
    """Write ``report.html``, its PNGs and the 3D viewer (``viewer.html``: every grasp of the
    table, passed and rejected) into ``folder``; returns the HTML path.
    ``object_points`` (n, 3): the object cloud the palm positions are drawn around."""
    from sim.grasp import Grasp

    pose = table["palm_pose"]
    plane = (None if demo.table is None
             else (np.asarray(demo.table["point_m"]), np.asarray(demo.table["normal"])))
    save_png(folder / "palm_cloud.png",
             palm_cloud_image(np.asarray(object_points), pose[:, :3],
                              demo_palm=np.asarray(demo.palm_pos_m), table=plane))
    write_viewer(folder / VIEWER_PAGE, viewer_scene(table, hand, obj, demo=demo,
                                                    title=f"{summary.demo_id}: {obj.name}"))
    images: list[tuple[str, str]] = []
    note = ""
    if gl_available() is not None:
        order = np.argsort(-table["sim_epsilon"] if np.isfinite(table["sim_epsilon"]).any()
                           else -table["gws"])[:gallery]
        kept = [Grasp.from_arrays(pose[i, :3], pose[i, 3:], table["hand_pose"][i])
                for i in order]
        names = _render(hand, obj, [demo.grasp, *kept], folder,
                        ["demo.png", *[f"grasp_{k:02d}.png" for k in range(len(kept))]])
        captions = [f"demonstration: {demo_grasp_text(summary.demo_grasp)}",
                    *[_caption(table, int(i), k) for k, i in enumerate(order)]]
        images = list(zip(names, captions, strict=True))
    else:
        note = "<p><em>No offscreen OpenGL on this machine: grasp images were not rendered.</em></p>"
    doc = _html(demo, summary, images, note)
    path = folder / "report.html"
    write_bytes_atomic(path, doc.encode())
    return path


def _caption(table: ObjectTable, i: int, rank: int) -> str:
    """What a gallery image shows: its rank, row, fingers and the simulated numbers."""
    cols = table.columns
    used = cols.get("fingers_used")
    fingers = ([f for f, on in zip(table.finger_names, used[i], strict=True) if on]
               if used is not None else [])
    parts = [f"#{rank + 1} (row {i})", ", ".join(fingers) or "fingers ?"]
    if "sim_epsilon" in cols and np.isfinite(cols["sim_epsilon"][i]):
        parts.append(f"simulated ε {float(cols['sim_epsilon'][i]):.3g}")
    if "displacement_m" in cols and np.isfinite(cols["displacement_m"][i]):
        parts.append(f"moved {1e3 * float(cols['displacement_m'][i]):.1f} mm in the lift")
    return "; ".join(parts)


def _html(demo: Demo, s: DemoSummary, images: list[tuple[str, str]], note: str) -> str:
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
    figures = {n: (f"<figure><img src='{e(n)}' alt='{e(c)}'><figcaption>{e(c)}</figcaption>"
                   f"</figure>") for n, c in images}
    demo_img = figures.get("demo.png", "")
    gallery = "".join(f for n, f in figures.items() if n != "demo.png")
    return f"""<!doctype html>
<html><head><meta charset="utf-8"><title>dexaug report: {e(s.demo_id)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1100px}}
table{{border-collapse:collapse}}th,td{{border:1px solid #ccc;padding:4px 8px;text-align:left}}
img{{border:1px solid #ddd}}figure{{display:inline-block;margin:6px;max-width:480px}}
figcaption{{font-size:0.85em}}
iframe.viewer{{width:100%;height:640px;border:1px solid #ccc}}
@media print{{.viewer{{display:none}}}}</style></head>
<body><h1>Augmentation of {e(s.demo_id)}</h1>
<section class="viewer"><h2>Every grasp in 3D</h2>
<iframe class="viewer" src="{VIEWER_PAGE}" title="3D grasp viewer"></iframe>
<p><a href="{VIEWER_PAGE}">Open the viewer on its own page</a> (filter by verdict, failure
reason and fingers; the hand posed by the hand model's forward kinematics).</p></section>
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
