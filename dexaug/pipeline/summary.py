"""What an augmentation produced (``summary.json``), and whether a folder holds a finished run.

Why apart from the pipeline: the report and the dashboard read summaries without running
anything.
"""

from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from dexaug.pipeline.options import AugmentOptions, run_key
from sim.demo import Demo

__all__ = ["DemoSummary", "finished"]

log = logging.getLogger(__name__)


@dataclass
class DemoSummary:
    """What an augmentation produced (``summary.json``): counts, failure reasons, metric
    means of the kept grasps, timings (seconds) and where the files are."""

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
    skipped: bool = False

    @property
    def validated_per_min(self) -> float:
        """Passing grasps per minute of augmentation proper (workspace + FSG + validation; the
        report's rendering is not part of the throughput)."""
        total = sum(v for k, v in self.timings_s.items() if k != "report")
        return 60.0 * self.passed / total if total > 0 else 0.0

    def to_json(self) -> dict[str, Any]:
        return {k: v for k, v in asdict(self).items() if k != "skipped"}


def finished(folder: Path | str, demo: Demo, opts: AugmentOptions) -> DemoSummary | None:
    """The summary of ``folder`` when it holds ``demo`` finished under ``opts`` and today's
    configs (:func:`run_key`; what ``augment_demo`` would skip), else None: lets a caller (the
    dashboard) show results without re-running."""
    path = Path(folder) / "summary.json"
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
        summary = DemoSummary(**doc)
    except (OSError, ValueError, TypeError):
        log.warning("%s is unreadable; redoing that demo", path)
        return None
    if summary.run_key != run_key(demo, opts) or not Path(summary.dataset).is_file():
        return None
    summary.skipped = True
    return summary
