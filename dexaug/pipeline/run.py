"""One demonstration in, a validated grasp dataset and a report out (DESIGN §1, lower half).

demo → demonstration-centred AutoWS clouds → FSG → MuJoCo validation of every grasp → HDF5
dataset (passing grasps in the main table, rejected ones with their failure in the side table)
→ report. The demonstration's own grasp is validated beside them, under the same protocol and
validator, and its verdict goes into the summary and the report (DESIGN §5): a low pass rate
reads differently when the demo grasp itself does not hold. Each demo gets its own folder
``<out>/<demo id>/`` holding ``grasps.h5``, ``report.html`` with its images, and
``summary.json``, which is written last: a folder with a summary made from the same demo,
options and configs (:func:`run_key`) is finished, and re-running skips it (resumable); a run
interrupted before the summary leaves only complete files (every write is atomic), and the next
run redoes that demo. One run writes a folder at a time (:mod:`~dexaug.pipeline.result_lock`):
a second run of the same demo waits for the first, then skips the finished demo.

Why per-demo folders and not one growing file: demos are independent units of work (the
dashboard and ``--watch`` start them one by one), and a failure in one never touches another's
results. ``augment.dataset.load`` reads any of them; ``merge_datasets`` joins them.

Compute and write are separate steps (:func:`compute_fsg` and validation make a
:class:`Computed`, plain picklable data; :func:`write_result` makes the files): the Ray scale-out
(:mod:`dexaug.scale`) computes in tasks that may be retried on another worker, and its driver
alone writes each folder, once, so a retried task never adds rows. ``augment_demo`` runs both
steps in this process, as it always has.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from augment import dataset
from augment.autows.build import build_workspace
from augment.autows.cloud import WorkspaceCloud
from augment.autows.seed import DemoSeed
from augment.fsg.params import load_fsg_params
from augment.fsg.result import FsgResult
from augment.fsg.run import TOO_WEAK, generate
from augment.fsg.table import TablePlane
from augment.object_cloud import ObjectCloud, object_cloud
from augment.power import PowerSeed, generate_power
from dexaug.pipeline.options import AugmentOptions, Progress, demo_dir, result_configs, run_key
from dexaug.pipeline.protocol_facts import DEFAULT_PROTOCOL, hold_oversample
from dexaug.pipeline.report import write_report
from dexaug.pipeline.result_lock import result_lock
from dexaug.pipeline.summary import DemoSummary, demo_grasp_text, demo_verdict, finished
from sim.demo import POWER, Demo, demo_to_json
from sim.errors import DexaugError
from sim.hand.model import Hand
from sim.io import write_bytes_atomic
from sim.pools import persistent_pool
from sim.validate.batch import SceneEffort, ScenePenetration, validate_many
from sim.validate.loads import hold_loads
from sim.validate.result import ValidationResult
from sim.world.objects import ObjectAsset, load_object
from teleop.record.demos import extract_demos

__all__ = ["Computed", "augment_demo", "augment_session", "compute_fsg", "demo_fingers", "demo_table",
           "generate_grasps", "validate_computed", "validate_demo_grasp", "write_result"]

log = logging.getLogger(__name__)

#: modules the shared worker pool preloads: FSG's sampler and the validator it checks with
POOL_PRELOAD = ("augment.fsg.run", "sim.validate.batch")


def generate_grasps(hand: Hand, obj: ObjectAsset | ObjectCloud, workspace: WorkspaceCloud, *,
                    link_penetration: bool = True, workers: int = 1,
                    hold_protocol: str | None = DEFAULT_PROTOCOL, **kwargs: Any) -> FsgResult:
    """FSG (:func:`augment.fsg.run.generate`) wired to this project's validator: with
    ``link_penetration``, the point-cloud checks end with the exact check in the validator's
    scene, so no output fails validation for a penetration the simulator sees; with
    ``hold_protocol``, FSG ranks its grasps by the actuator effort and the grip they need to
    hold that protocol's loads (:class:`sim.validate.batch.SceneEffort`,
    :func:`sim.validate.loads.hold_loads`; ``None``: by ε, as the paper), over
    ``[fsg] hold_oversample`` × n grasps found, or ``dgb_hold_oversample`` × n for the
    benchmark's loads. Every caller above ``augment`` (CLI, dashboard, benchmarks) generates
    through here."""
    exact = ScenePenetration.of(hand.name, obj.name) if link_penetration else None
    hold = effort = None
    mass_kg = math.nan  # for the warning below, which needs the hold protocol's asset
    if hold_protocol is not None:
        asset = obj if isinstance(obj, ObjectAsset) else load_object(obj.name)
        mass_kg = asset.mass_kg
        hold = hold_loads(asset, hold_protocol)
        effort = SceneEffort(hand.name, obj.name, hold_protocol)
        params = kwargs.get("params") or load_fsg_params(hand.config)
        kwargs["params"] = dataclasses.replace(
            params, hold_oversample=hold_oversample(params, hold_protocol))
    if workers > 1:
        persistent_pool(workers, preload=POOL_PRELOAD)
    res = generate(hand, obj, workspace, link_penetration=link_penetration,
                   exact_penetration=exact, workers=workers, hold=hold, effort=effort, **kwargs)
    if res.stopped == TOO_WEAK:
        log.warning("%s (%.2f kg, %s): FSG stopped: its first %d grasps all need more than "
                    "%.3g× the actuators' force limits to hold it (max_actuator_effort; above "
                    "it grasps seldom hold in simulation); this hand's fingertip grasps are unlikely "
                    "to (more fingers, a power grasp or a stronger hand are needed)",
                    obj.name, mass_kg, hold_protocol,
                    res.stats.get("effort", 0),
                    (kwargs.get("params") or load_fsg_params(hand.config)).max_actuator_effort)
    elif effort is not None:
        warn_if_too_heavy(res, effort, obj.name)
    return res


#: grasps whose actuator effort :func:`warn_if_too_heavy` checks (≈ 15 ms each)
HEAVY_CHECK_GRASPS = 20


def warn_if_too_heavy(res: FsgResult, effort: SceneEffort, name: str) -> float:
    """Warn, in one line, when none of the first :data:`HEAVY_CHECK_GRASPS` grasps could hold
    the validation's loads with the hand's actuators (effort > 1 at every one: a run of
    failures is coming, and more squeeze cannot help). Returns the least effort found."""
    efforts = [g.actuator_effort if g.actuator_effort == g.actuator_effort else effort(g.grasp)
               for g in res.grasps[:HEAVY_CHECK_GRASPS]]
    least = min(efforts, default=float("nan"))
    if efforts and least > 1.0:
        mass_kg = load_object(name).mass_kg
        log.warning("%s (%.2f kg, %s): none of the %d grasps checked can hold it with these "
                    "actuators: the least needs %.1f× their force limits (more fingers, a power "
                    "grasp or a stronger hand are needed)", name, mass_kg, effort.protocol,
                    len(efforts), least)
    return least


@dataclass
class Computed:
    """What the compute stages made of one unit of work (a demo, or an object on the manual
    workspace): no file is written and everything is plain data, so a Ray task can return it
    and the driver alone writes (:func:`write_result`). ``validation`` is None until validated
    (or when validation is off); ``timings_s`` holds seconds per stage."""

    hand: str
    object: str
    joint_names: tuple[str, ...]
    finger_names: tuple[str, ...]
    fsg: FsgResult
    timings_s: dict[str, float]
    validation: list[ValidationResult] | None = None
    demo_grasp: dict[str, Any] | None = None


def compute_fsg(hand_name: str, object_name: str, demo: Demo | None, opts: AugmentOptions, *,
                workers: int, progress: Progress | None = None,
                ) -> tuple[Computed, Hand, ObjectAsset, ObjectCloud]:
    """Workspace (demo-centred, or the hand's manual one without ``demo``) and FSG — for a
    power demo (a whole-hand wrap) the power generator it seeds instead — with
    ``workers`` processes (its output depends on that count: worker k uses seed + k). Returns
    the result and the loaded hand, object and cloud (for a report in the same process)."""
    tick = progress or (lambda stage, done, total: None)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    hand = Hand.load(hand_name)
    obj = load_object(object_name)
    cloud = object_cloud(obj)
    if demo is not None and demo.grasp_type == POWER:   # a wrap: FSG's palm check refuses it
        res = generate_power(hand, obj.name, n=opts.n, seed=opts.seed, workers=workers,
                             time_budget_s=opts.time_budget_s, demo=PowerSeed.from_demo(demo),
                             protocol=opts.validate or DEFAULT_PROTOCOL,
                             progress=lambda k: tick("fsg", k, opts.n))
        timings["fsg"] = time.perf_counter() - t0
        return (Computed(hand.name, obj.name, tuple(hand.joint_names), tuple(hand.finger_names),
                         res, timings), hand, obj, cloud)
    tick("workspace", 0, 1)
    ws = build_workspace(hand, demo=DemoSeed.from_demo(demo) if demo is not None else None)
    tick("workspace", 1, 1)
    timings["workspace"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    tick("fsg", 0, opts.n)
    res = generate_grasps(hand, cloud, ws, n=opts.n, table=demo_table(demo, opts.table),
                          finger_names=demo_fingers(demo) if demo is not None else None,
                          link_penetration=opts.link_penetration, seed=opts.seed,
                          finger_iteration=opts.finger_iteration,
                          time_budget_s=opts.time_budget_s, workers=workers,
                          hold_protocol=opts.validate or DEFAULT_PROTOCOL,
                          progress=lambda k: tick("fsg", k, opts.n))
    tick("fsg", len(res.grasps), opts.n)
    timings["fsg"] = time.perf_counter() - t0
    done = Computed(hand.name, obj.name, tuple(hand.joint_names), tuple(hand.finger_names), res,
                    timings)
    return done, hand, obj, cloud


def validate_computed(c: Computed, opts: AugmentOptions, *, progress: Progress | None = None) -> None:
    """Validate ``c``'s grasps with ``opts.validate`` on the local pool (``opts.workers``
    processes) into ``c.validation``, timing it; nothing when validation is off."""
    tick = progress or (lambda stage, done, total: None)
    t0 = time.perf_counter()
    if opts.validate and c.fsg.grasps:
        total = len(c.fsg.grasps)
        c.validation = validate_many(c.hand, c.object, [g.grasp for g in c.fsg.grasps],
                                     opts.validate, workers=opts.workers,
                                     squeeze_convention=opts.squeeze_convention,
                                     progress=lambda k: tick("validate", k, total),
                                     backend=opts.backend)
    c.timings_s["validate"] = time.perf_counter() - t0


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
    # one run per folder at a time (result_lock): a run started beside this one waits, then
    # finds the demo finished here and skips it
    with result_lock(folder, demo.id):
        if not force and (done := finished(folder, demo, opts)) is not None:
            log.info("%s: augmented by another run meanwhile (%s), skipping", demo.id, folder)
            return done
        return _augment_locked(demo, folder, opts, progress)


def _augment_locked(demo: Demo, folder: Path, opts: AugmentOptions,
                    progress: Progress | None) -> DemoSummary:
    """:func:`augment_demo`'s work, with ``folder``'s result lock held."""
    tick = progress or (lambda stage, done, total: None)
    configs = result_configs(demo)   # the inputs as they are now, before any stage reads them
    key = run_key(demo, opts, configs)
    c, hand, obj, cloud = compute_fsg(demo.hand, demo.object, demo, opts, workers=opts.workers,
                                      progress=tick)
    validate_computed(c, opts, progress=tick)
    if opts.validate:
        t0 = time.perf_counter()
        c.demo_grasp = validate_demo_grasp(hand.name, obj.name, demo, opts.validate,
                                           opts.squeeze_convention)
        c.timings_s["demo_grasp"] = time.perf_counter() - t0
    return write_result(folder, c, opts, key=key, configs=configs, demo=demo, progress=tick,
                        assets=(hand, obj, cloud))


def write_result(folder: Path, c: Computed, opts: AugmentOptions, *, key: str,
                 configs: dict[str, str], demo: Demo | None, unit_id: str | None = None,
                 source: str | None = None, progress: Progress | None = None,
                 assets: tuple[Hand, ObjectAsset, ObjectCloud] | None = None) -> DemoSummary:
    """Write ``c`` into ``folder``: ``grasps.h5``, the report (demos only, with
    ``opts.gallery`` > 0; ``assets`` saves reloading hand, object and cloud) and
    ``summary.json`` last, each atomically. The one place results become files: a caller that
    computed elsewhere (a Ray task) writes each folder once, here. ``unit_id`` and ``source``
    default to the demo's id and source."""
    with result_lock(folder, unit_id or (demo.id if demo is not None else c.object)):
        return _write_locked(folder, c, opts, key=key, configs=configs, demo=demo,
                             unit_id=unit_id, source=source, progress=progress, assets=assets)


def _write_locked(folder: Path, c: Computed, opts: AugmentOptions, *, key: str,
                  configs: dict[str, str], demo: Demo | None, unit_id: str | None,
                  source: str | None, progress: Progress | None,
                  assets: tuple[Hand, ObjectAsset, ObjectCloud] | None) -> DemoSummary:
    """:func:`write_result`'s work, with ``folder``'s result lock held."""
    tick = progress or (lambda stage, done, total: None)
    unit_id = unit_id if unit_id is not None else demo.id if demo is not None else c.object
    source = source if source is not None else str(demo.source) if demo is not None else ""
    res, results, timings = c.fsg, c.validation, c.timings_s
    provenance = {"hand": c.hand, "demo_source": source, "seed": opts.seed,
                  "options": json.dumps(asdict(opts)), "run_key": key, **configs,
                  "protocol": opts.validate or "none", "fsg_stopped": res.stopped,
                  # the demonstration itself, so a later stage (dexaug arm --as-it-lies) can
                  # rebuild its workspace without the session file
                  "demo": json.dumps(demo_to_json(demo)) if demo is not None else ""}
    table = dataset.from_fsg(res.grasps, c.joint_names, c.finger_names, results,
                             demo_id=demo.id if demo is not None else "", attrs=provenance,
                             split_rejected=results is not None)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "summary.json").unlink(missing_ok=True)   # not finished until rewritten
    data_path = folder / "grasps.h5"
    dataset.save(data_path, {c.object: table})
    failures = Counter(str(r.failure) for r in results or [] if not r.passed)
    kept = table
    sim_eps = np.asarray(kept["sim_epsilon"], float)
    closed = sim_eps[np.isfinite(sim_eps) & (sim_eps > 0)]
    gws = np.asarray(kept["gws"], float)
    metrics = {"fsg_force_closure_pct": 100.0 * float((gws > 0).sum()) / len(kept) if len(kept) else 0.0,
               "fsg_epsilon_mean_closed": _mean(gws[gws > 0]),
               "fsg_volume_mean": _mean(kept["volume"]),
               "sim_force_closure_pct": 100.0 * len(closed) / len(kept) if len(kept) else 0.0,
               "sim_epsilon_mean_closed": _mean(closed),
               "displacement_mm_mean": 1e3 * _mean(kept["displacement_m"])}
    summary = DemoSummary(
        demo_id=unit_id, hand=c.hand, object=c.object, source=source,
        run_key=key, requested=opts.n, generated=len(res.grasps),
        passed=len(kept) if results is not None else 0, failures=dict(failures),
        fsg_stopped=res.stopped, timings_s=timings, metrics=metrics, dataset=str(data_path),
        report=None, demo_grasp=c.demo_grasp)
    if opts.gallery > 0 and demo is not None:
        t0 = time.perf_counter()
        tick("report", 0, 1)
        hand, obj, cloud = assets or _load_assets(c.hand, c.object)
        summary.report = str(write_report(folder, demo, hand, obj, table, summary,
                                          np.asarray(cloud.points), gallery=opts.gallery))
        tick("report", 1, 1)
        timings["report"] = time.perf_counter() - t0
    write_bytes_atomic(folder / "summary.json",
                       (json.dumps(summary.to_json(), indent=1) + "\n").encode())
    log.info("%s: %d of %d generated grasps passed %s; demo grasp %s (%s)", unit_id,
             summary.passed, summary.generated, opts.validate, demo_grasp_text(c.demo_grasp),
             folder)
    return summary


def _load_assets(hand: str, obj: str) -> tuple[Hand, ObjectAsset, ObjectCloud]:
    asset = load_object(obj)
    return Hand.load(hand), asset, object_cloud(asset)


def validate_demo_grasp(hand: str, obj: str, demo: Demo, protocol: str,
                        squeeze_convention: str | None = None) -> dict[str, Any]:
    """The verdict (:func:`~dexaug.pipeline.summary.demo_verdict`) of ``demo``'s own grasp
    under ``protocol``, checked by the validator the augmented grasps get (``validate_many``,
    default config, in this process). A grasp that cannot be validated at all (joint vector
    of another hand, a broken quaternion) is reported failed with the reason: this is a
    diagnostic beside the augmentation and never fails it."""
    try:
        (r,) = validate_many(hand, obj, [demo.grasp], protocol, workers=1,
                             squeeze_convention=squeeze_convention)
    except DexaugError as exc:
        log.warning("%s: the demo grasp could not be validated: %s", demo.id, exc)
        return demo_verdict(protocol, False, f"not validated: {exc}")
    return demo_verdict(protocol, r.passed, r.failure, r.displacement_m, r.rotation_rad)


def demo_table(demo: Demo | None, table: bool | None) -> TablePlane | bool:
    """FSG's table for augmenting ``demo`` (:attr:`AugmentOptions.table`): the plane the
    demo's object rested on (object frame) unless ``table`` is False; with ``table`` True
    and no recorded table, the paper's horizontal table under the object."""
    recorded = None if demo is None or demo.table is None else TablePlane.through(
        demo.table["point_m"], demo.table["normal"])
    if table is False:
        return False
    return recorded if recorded is not None else bool(table)


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
    """Every demo of the session at ``path`` (``teleop.record.demos.extract_demos``), augmented.

    Raises:
        sim.demo.DemoError: the session holds no usable grasp (the reason is the message).
    """
    out = []
    for demo in extract_demos(path):
        if on_demo is not None:
            on_demo(demo)
        out.append(augment_demo(demo, out_root, opts, progress=progress, force=force))
    return out
