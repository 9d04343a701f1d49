"""What an augmentation produced (``summary.json``), and whether a folder holds a finished run.

Why apart from the pipeline: the report and the dashboard read summaries without running
anything.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from dexaug.pipeline.options import AugmentOptions, run_key
from sim.demo import Demo

__all__ = ["DemoSummary", "demo_grasp_text", "demo_verdict", "finished", "stored"]

log = logging.getLogger(__name__)


@dataclass
class DemoSummary:
    """What an augmentation produced (``summary.json``): counts, failure reasons, metric
    means of the kept grasps, timings (seconds), where the files are, and ``demo_grasp``: the
    demonstration's own grasp under the same protocol (:func:`demo_verdict`; None when the run
    did not validate, or the summary predates the check), so a pass rate can be read against
    whether the grasp it was augmented from holds at all (DESIGN §5)."""

    demo_id: str
    hand: str
    object: str
    source: str
    run_key: str
    requested: int
    generated: int
    passed: int
    failures: dict[str, int]
    fsg_stopped: str
    timings_s: dict[str, float]
    metrics: dict[str, float]
    dataset: str
    report: str | None
    demo_grasp: dict[str, Any] | None = None
    skipped: bool = False

    @property
    def validated_per_min(self) -> float:
        """Passing grasps per minute of augmentation proper (workspace + FSG + validation; the
        report's rendering and the demo grasp's own check produce no grasp and are not part of
        the throughput)."""
        total = sum(v for k, v in self.timings_s.items() if k not in ("report", "demo_grasp"))
        return 60.0 * self.passed / total if total > 0 else 0.0

    def to_json(self) -> dict[str, Any]:
        return {k: v for k, v in asdict(self).items() if k != "skipped"}


def demo_verdict(protocol: str, passed: bool, failure: str | None,
                 displacement_m: float = math.nan, rotation_rad: float = math.nan) -> dict[str, Any]:
    """The ``demo_grasp`` entry of a summary: the demo grasp's verdict under ``protocol``, why
    it failed, and how far the object moved (metres) and turned (degrees) relative to the hand.
    Plain JSON: metrics never measured (NaN, e.g. a grasp rejected for penetration before
    simulating) become None, since the dashboard's browser cannot parse NaN."""
    def finite(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    return {"protocol": protocol, "passed": bool(passed),
            "failure": None if failure is None else str(failure),
            "displacement_m": finite(displacement_m),
            "rotation_deg": finite(math.degrees(rotation_rad))}


def demo_grasp_text(verdict: dict[str, Any] | None) -> str:
    """One line for people (the report, the dashboard): ``"passed"`` or ``"failed (reason)"``,
    then the protocol and the drift measured, e.g. ``"failed (slipped) — lift-drop; the object
    moved 21.0 mm and turned 3.2° in the hand"``. One formatter, so both pages say the same."""
    if verdict is None:
        return "not validated (validation was off, or the run predates this check)"
    head = "passed" if verdict["passed"] else f"failed ({verdict['failure']})"
    disp, rot = verdict.get("displacement_m"), verdict.get("rotation_deg")
    from dexaug.pipeline.protocol_facts import drift_reference

    # measured from the object's initial world pose (dgb) or in the palm frame (the others)
    where = {"start": "from where it started", "palm": "in the hand"}[
        drift_reference(verdict["protocol"])]
    drift = "" if disp is None or rot is None else \
        f"; the object moved {1e3 * disp:.1f} mm and turned {rot:.1f}° {where}"
    return f"{head} — {verdict['protocol']}{drift}"


def stored(folder: Path | str, unit_id: str) -> DemoSummary | None:
    """``folder``'s summary of the demo (or object unit) ``unit_id`` whose dataset still exists,
    under whatever options and configs it was made (compare its ``run_key`` with
    :func:`run_key`), or None."""
    path = Path(folder) / "summary.json"
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
        summary = DemoSummary(**doc)
    except (OSError, ValueError, TypeError):
        log.warning("%s is unreadable; redoing that demo", path)
        return None
    if summary.demo_id != unit_id or not Path(summary.dataset).is_file():
        return None
    summary.skipped = True
    return summary


def finished(folder: Path | str, demo: Demo, opts: AugmentOptions) -> DemoSummary | None:
    """The summary of ``folder`` when it holds ``demo`` finished under ``opts`` and today's
    configs (:func:`run_key`; what ``augment_demo`` would skip), else None: lets a caller (the
    dashboard) show results without re-running."""
    summary = stored(folder, demo.id)
    return summary if summary is not None and summary.run_key == run_key(demo, opts) else None
