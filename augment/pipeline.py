"""One demonstration in, a validated grasp dataset and a report out (DESIGN §1, lower half).

demo → demonstration-centred AutoWS clouds → FSG → MuJoCo validation of every grasp → HDF5
dataset (passing grasps in the main table, rejected ones with their failure in the side table)
→ report. Each demo gets its own folder ``<out>/<demo id>/`` holding ``grasps.h5``,
``report.html`` with its images, and ``summary.json``, which is written last: a folder with a
summary made from the same demo, options and configs (:func:`run_key`) is finished, and
re-running skips it (resumable); a run
interrupted before the summary leaves only complete files (every write is atomic), and the next
run redoes that demo.

Why per-demo folders and not one growing file: demos are independent units of work (the
dashboard and ``--watch`` start them one by one), and a failure in one never touches another's
results. ``augment.dataset.load`` reads any of them; ``merge_datasets`` joins them.
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from augment import dataset
from augment.demo import Demo, demo_to_json, extract_demos
from augment.fsg import AUGMENT_TOML, generate
from augment.object_cloud import object_cloud
from augment.workspace import build_workspace
from sim.batch import default_workers, validate_many
from sim.hand import Hand
from sim.hand_config import hand_config_path
from sim.io import write_bytes_atomic
from sim.objects import load_object
from sim.validate import VALIDATE_TOML

__all__ = ["AugmentOptions", "DemoSummary", "augment_demo", "augment_session", "demo_dir",
           "demo_fingers", "finished"]

log = logging.getLogger(__name__)

#: progress(stage, done, total): stage is "workspace", "fsg", "validate", "report".
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class AugmentOptions:
    """What one augmentation run does. ``validate``: "lift-drop", "six-dir" or None (keep
    every FSG grasp unvalidated); ``time_budget_s`` bounds FSG (wall seconds); ``gallery``
    renders this many grasps for the report (0: no images)."""

    n: int = 200
    validate: str | None = "lift-drop"
    link_penetration: bool = True
    table: bool = False
    seed: int = 0
    workers: int = field(default_factory=default_workers)
    time_budget_s: float = 120.0
    gallery: int = 6


#: the configuration files an augmentation's results depend on (besides the hand's own)
RESULT_CONFIGS = (AUGMENT_TOML, VALIDATE_TOML)


def result_configs(demo: Demo) -> dict[str, str]:
    """``"config:<file name>"`` → text of each configuration file the stages read for ``demo``
    (AutoWS and FSG parameters, the validator's, the hand's; "" when absent): read once per
    run, hashed into :func:`run_key` and stored in the dataset as provenance."""
    paths = (*RESULT_CONFIGS, hand_config_path(demo.hand))
    return {f"config:{p.name}": p.read_text() if p.is_file() else "" for p in paths}


def run_key(demo: Demo, opts: AugmentOptions, configs: dict[str, str] | None = None) -> str:
    """Hash of everything that changes an augmentation's results: the options (not
    ``workers`` or ``gallery``), the demo itself, and the configuration texts
    (:func:`result_configs`, read now unless given). A re-run skips a demo only when this
    matches, so a re-recorded demo or an edited config is redone, not served stale."""
    options = asdict(opts)
    options.pop("workers")
    options.pop("gallery")
    doc = {"options": options, "demo": demo_to_json(demo),
           "configs": configs if configs is not None else result_configs(demo)}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]


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


def demo_dir(out_root: Path | str, demo: Demo) -> Path:
    """The folder of ``demo``'s results: its id with path-unsafe characters replaced."""
    return Path(out_root) / re.sub(r"[^A-Za-z0-9_.@-]+", "_", demo.id)


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


def augment_demo(demo: Demo, out_root: Path | str, opts: AugmentOptions | None = None, *,
                 progress: Progress | None = None, force: bool = False) -> DemoSummary:
    """Augment one demo into ``demo_dir(out_root, demo)`` (module docstring); a folder already
    finished with the same inputs (:func:`run_key`) is returned as is unless ``force``.

    Raises:
        DexaugError subclasses: the hand is not installed, the object cannot be loaded, bad
            options (each message names what and where).
    """
    opts = opts or AugmentOptions()
    folder = demo_dir(out_root, demo)
    if not force and (done := finished(folder, demo, opts)) is not None:
        log.info("%s: already augmented (%s), skipping", demo.id, folder)
        return done
    tick = progress or (lambda stage, done, total: None)
    configs = result_configs(demo)   # the inputs as they are now, before any stage reads them
    key = run_key(demo, opts, configs)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    hand = Hand.load(demo.hand)
    obj = load_object(demo.object)
    cloud = object_cloud(obj)
    tick("workspace", 0, 1)
    ws = build_workspace(hand, demo=demo.seed())
    tick("workspace", 1, 1)
    timings["workspace"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    tick("fsg", 0, opts.n)
    res = generate(hand, cloud, ws, n=opts.n, table=opts.table, finger_names=demo_fingers(demo),
                   link_penetration=opts.link_penetration, seed=opts.seed,
                   time_budget_s=opts.time_budget_s, workers=opts.workers)
    tick("fsg", len(res.grasps), opts.n)
    timings["fsg"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    results = None
    if opts.validate and res.grasps:
        total = len(res.grasps)
        results = validate_many(hand.name, obj.name, [g.grasp for g in res.grasps],
                                opts.validate, workers=opts.workers,
                                progress=lambda k: tick("validate", k, total))
    timings["validate"] = time.perf_counter() - t0

    provenance = {"hand": hand.name, "demo_source": str(demo.source), "seed": opts.seed,
                  "options": json.dumps(asdict(opts)), "run_key": key, **configs,
                  "protocol": opts.validate or "none", "fsg_stopped": res.stopped}
    table = dataset.from_fsg(res.grasps, hand.joint_names, hand.finger_names, results,
                             demo_id=demo.id, attrs=provenance,
                             split_rejected=results is not None)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "summary.json").unlink(missing_ok=True)   # not finished until rewritten
    data_path = folder / "grasps.h5"
    dataset.save(data_path, {obj.name: table})
    failures = Counter(str(r.failure) for r in results or [] if not r.passed)
    kept = table
    sim_eps = np.asarray(kept["sim_epsilon"], float)
    closed = sim_eps[np.isfinite(sim_eps) & (sim_eps > 0)]
    metrics = {"fsg_epsilon_mean": _mean(kept["gws"]), "fsg_volume_mean": _mean(kept["volume"]),
               "sim_force_closure_pct": 100.0 * len(closed) / len(kept) if len(kept) else 0.0,
               "sim_epsilon_mean_closed": _mean(closed),
               "displacement_mm_mean": 1e3 * _mean(kept["displacement_m"])}
    summary = DemoSummary(
        demo_id=demo.id, hand=hand.name, object=obj.name, source=str(demo.source),
        run_key=key, requested=opts.n, generated=len(res.grasps),
        passed=len(kept) if results is not None else 0, failures=dict(failures),
        fsg_stopped=res.stopped, timings_s=timings, metrics=metrics, dataset=str(data_path),
        report=None)
    if opts.gallery > 0:
        from augment.report import write_report

        t0 = time.perf_counter()
        tick("report", 0, 1)
        summary.report = str(write_report(folder, demo, hand, obj, table, summary,
                                          np.asarray(cloud.points), gallery=opts.gallery))
        tick("report", 1, 1)
        timings["report"] = time.perf_counter() - t0
    write_bytes_atomic(folder / "summary.json",
                       (json.dumps(summary.to_json(), indent=1) + "\n").encode())
    log.info("%s: %d of %d generated grasps passed %s (%s)", demo.id, summary.passed,
             summary.generated, opts.validate, folder)
    return summary


def demo_fingers(demo: Demo) -> tuple[str, ...] | None:
    """The fingers augmented grasps use: those that touched in the demo (paper §5.2), or all
    when fewer than two did (a lone mark on a one-finger touch)."""
    return demo.fingers if len(demo.fingers) >= 2 else None


def _mean(x: np.ndarray) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if len(x) else float("nan")


def augment_session(path: Path | str, out_root: Path | str, opts: AugmentOptions | None = None,
                    *, progress: Progress | None = None, force: bool = False,
                    on_demo: Callable[[Demo], None] | None = None) -> list[DemoSummary]:
    """Every demo of the session at ``path`` (``augment.demo.extract_demos``), augmented.

    Raises:
        augment.demo.DemoError: the session holds no usable grasp (the reason is the message).
    """
    out = []
    for demo in extract_demos(path):
        if on_demo is not None:
            on_demo(demo)
        out.append(augment_demo(demo, out_root, opts, progress=progress, force=force))
    return out
