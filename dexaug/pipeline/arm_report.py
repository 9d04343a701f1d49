"""The HTML report of an arm dataset (paper §5.3, its Fig. 12): per object, what became of the
(placement, grasp) pairs, and images of held grasps at the end of their lift.

Written from the same results as the arm dataset (:mod:`dexaug.pipeline.arm_run`), so its
numbers are the file's. Images need offscreen OpenGL; without it the report says so and keeps
the numbers.
"""

from __future__ import annotations

import html
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.arm.evaluate import ArmGraspResult
from sim.arm.scene import ArmScene
from sim.io import write_bytes_atomic
from sim.world.render import gl_available, render_scene, save_png

__all__ = ["ArmReportPart", "render_arm_result", "write_arm_report"]


def render_arm_result(scene: ArmScene, result: ArmGraspResult, path: Path,
                      width: int = 480, height: int = 360) -> None:
    """The scene at the end of ``result``'s simulation (the object lifted in the hand), seen
    from beside the table, written as a PNG to ``path``."""
    import mujoco  # deferred: MUJOCO_GL must be chosen before MuJoCo's first import

    d = mujoco.MjData(scene.model)
    d.qpos[:] = result.final_qpos
    mujoco.mj_forward(scene.model, d)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_png(path, render_scene(scene.model, d, lookat=d.qpos[scene.obj_qadr:scene.obj_qadr + 3],
                                distance_m=0.8, azimuth_deg=200.0, elevation_deg=-12.0,
                                width=width, height=height))


@dataclass(frozen=True)
class ArmReportPart:
    """One object's section: its scene (for renders), results and how its grasps were made
    (``grasps_from``; ``made`` per resting pose when made as it lies)."""

    object: str
    scene: ArmScene
    results: Sequence[ArmGraspResult]
    placements: int
    grasps_from: str
    made: dict[int, dict[str, int]]


def _gallery_picks(results: Sequence[ArmGraspResult], gallery: int) -> list[ArmGraspResult]:
    """Up to ``gallery`` held grasps, each from a different placement while there are any."""
    first: dict[int, ArmGraspResult] = {}
    others: list[ArmGraspResult] = []
    for r in results:
        if not r.passed:
            continue
        if r.placement in first:
            others.append(r)
        else:
            first[r.placement] = r
    return [*first.values(), *others][:gallery]


def write_arm_report(path: Path, arm: str, hand: str, parts: Sequence[ArmReportPart], *,
                     gallery: int = 4) -> Path:
    """Write the report to ``path`` (HTML) and its images beside it in ``<stem>_images/``."""
    e = html.escape
    img_dir = path.parent / f"{path.stem}_images"
    can_render = gallery > 0 and gl_available() is not None
    sections = []
    for part in parts:
        res = part.results
        n = len(res)
        held = sum(r.passed for r in res)
        planned = [r for r in res if r.times_s is not None]
        per = (sum(r.plan_s + r.sim_s for r in planned) / len(planned)) if planned else float("nan")
        failures = Counter(r.failure for r in res if r.failure)
        made = "; ".join(f"pose {k}: {v['passed']} of {v['generated']}"
                         for k, v in sorted(part.made.items()))
        rows = [("grasps", part.grasps_from + (f" (per resting pose, made ones that hold "
                                               f"hanging as it hangs: {made})" if made else "")),
                ("placements", part.placements), ("placement × grasp pairs", n),
                ("held", f"{held} ({100 * held / n:.1f} %)" if n else "0"),
                ("placements with a held grasp",
                 f"{len({r.placement for r in res if r.passed})} of {part.placements}"),
                ("failures", ", ".join(f"{k} {v}" for k, v in sorted(failures.items())) or "—"),
                ("seconds per planned grasp (IK + planning + simulation)", f"{per:.2f}")]
        table = "".join(f"<tr><th>{e(str(k))}</th><td>{e(str(v))}</td></tr>" for k, v in rows)
        figs = []
        for r in _gallery_picks(res, gallery) if can_render else []:
            name = f"{part.object}_p{r.placement:03d}_g{r.grasp:03d}.png"
            render_arm_result(part.scene, r, img_dir / name)
            caption = (f"placement {r.placement} (resting pose {r.rest_index}), grasp {r.grasp}: "
                       f"lifted {1e3 * r.lifted_m:.0f} mm, moved {1e3 * r.displacement_m:.1f} mm "
                       f"and turned {np.degrees(r.rotation_rad):.1f}° in the hand")
            figs.append(f"<figure><img src='{e(img_dir.name)}/{e(name)}' alt='{e(caption)}'>"
                        f"<figcaption>{e(caption)}</figcaption></figure>")
        if not can_render:
            note = ("<p><em>No offscreen OpenGL on this machine: no images.</em></p>"
                    if gallery > 0 else "")
        else:
            note = "" if figs else "<p>No grasp held.</p>"
        sections.append(f"<h2>{e(part.object)}</h2><table>{table}</table>{note}"
                        f"<div class='gallery'>{''.join(figs)}</div>")
    doc = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>dexaug arm report: {e(hand)} on {e(arm)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1100px}}
table{{border-collapse:collapse}}th,td{{border:1px solid #ccc;padding:4px 8px;text-align:left}}
figure{{display:inline-block;margin:6px;max-width:480px}}img{{border:1px solid #ddd}}
figcaption{{font-size:0.85em}}</style></head>
<body><h1>Grasps of {e(hand)} on {e(arm)} at a table</h1>{''.join(sections)}</body></html>
"""
    write_bytes_atomic(path, doc.encode())
    return path
