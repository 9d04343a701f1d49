"""FSG's entry point, :func:`generate`: input checks, worker processes, finger iteration and the
merge of the workers' grasps (the :mod:`augment.fsg` overview, last two paragraphs).

Finger iteration (:func:`run_rounds`): a round is ``outer`` outer iterations; when a round
yields fewer than ``min_valid`` grasps with the current fingers, the least important finger is
dropped (down to ``min_fingers``, at least 2), and generation goes on within the same call until
``n`` grasps or the time budget. Unused finger joints stay 0.

Closure relaxation (dexaug, ``relax_closure``): when no finger is dropped after a round
(finger iteration off, as with a demonstration, at ``min_fingers``, or the round was not short)
and the round's rate of grasps cannot reach ``n`` within the time budget left
(:func:`misses_budget`), the force-closure filter is the next condition relaxed, in the paper's
spirit of relaxing conditions "if the number of valid gestures is insufficient": from then on
candidates that pass every geometric check but have ε ≤ ``min_epsilon`` are kept too. Output is
sorted by ε, so every force-closure grasp comes before them, and the simulated validation
decides. Why: on the authors' bowl demonstration (three fingertips on the rim) 99 % of the
geometrically valid candidates have no force closure under the rigid point-contact GWS, so the
strict filter returned 8 grasps of 200 in 60 s; relaxed, 198 come in 13 s and 12 % of them hold
in lift-drop. The authors' implementation (``src/gws.cc``, read, not run) has no strict filter
either: it takes ``-offset`` of the facet with the smallest absolute offset as ε, which can be
positive when the origin lies outside the hull.

Ranking by what the hand can hold (dexaug, ``effort`` and ``hold``): given the loads the
caller's validation will apply (the object's weight for lift-drop, the pushes of six-dir and
the benchmark: :func:`sim.validate.loads.hold_loads`), every accepted grasp gets its actuator
effort — the least worst actuator force, as a fraction of its limit, with which the hand could
hold the worst load at the placed grasp (:mod:`sim.validate.effort`, via the caller's scene) —
and its grip ratio — the least total normal force within the simulation's friction cones, over
the load (:mod:`sim.metrics.holding`); the workers find ``hold_oversample`` × n grasps, and the
n with the least effort are kept (grip ratio, then ε break ties; a grasp that cannot hold some
load comes last). With ``max_actuator_effort`` finite, a grasp whose effort exceeds it is
rejected like a penetrating one (counted as ``effort``) and the search goes on: above 1 the
actuators cannot hold the loads at those contacts however they squeeze, which the validator
then confirms at the price of a simulation. Scoring costs ≈ 15 ms per accepted grasp, so it
runs only when ``hold_oversample`` > 1 or the effort filter is on. Output is sorted by ε as in
the paper unless ranked.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from augment.fsg.batch import Sampler, SamplerSetup
from augment.fsg.checks import Dedup, EffortScore, PenetrationCheck
from augment.fsg.params import FsgError, FsgParams, load_fsg_params
from augment.fsg.progress import run_workers, worker_slot
from augment.fsg.result import FsgGrasp, FsgResult
from augment.fsg.table import TablePlane
from sim.metrics.holding import HoldLoads

if TYPE_CHECKING:
    from augment.autows.cloud import WorkspaceCloud
    from augment.object_cloud import ObjectCloud
    from sim.hand.model import Hand
    from sim.world.objects import ObjectAsset

__all__ = ["TOO_WEAK", "TOO_WEAK_AFTER", "generate", "merge", "misses_budget", "run_rounds"]

log = logging.getLogger(__name__)

#: what one worker returns: accepted grasps, counts, why it stopped, finger sets tried
WorkerOutput = tuple[list[FsgGrasp], dict[str, int], str, list[tuple[str, ...]]]


#: stop reason of a search whose first :data:`TOO_WEAK_AFTER` grasps all needed more than
#: ``max_actuator_effort``; 30 without one accepted is far beyond the share such grasps make of
#: an object the hand can hold (44 % of the authors' sugar-box demo's at the default 0.25:
#: thirty in a row has odds ≈ 1e-11; README "Grasps that hold")
TOO_WEAK = "actuators too weak"
TOO_WEAK_AFTER = 30


def run_rounds(sampler: Sampler, n: int, deadline: float,
               on_batch: Callable[[int], None] | None = None) -> tuple[str, list[tuple[str, ...]]]:
    """Batches of ``sampler`` in rounds of ``outer`` outer iterations, with finger iteration and
    closure relaxation, until it holds ``n`` grasps ("done") or ``time.monotonic()`` passes
    ``deadline`` ("time budget"), or until :data:`TOO_WEAK_AFTER` grasps were rejected for
    the actuator effort before any was accepted (:data:`TOO_WEAK`: an object the hand's
    actuators cannot hold, reported at once rather than after the whole budget). Returns the
    reason and the finger sets used, in order.
    ``on_batch`` gets the number of grasps held after each batch (progress)."""
    fingers = sampler.setup.fingers
    sets = [fingers]
    p = sampler.params
    while True:
        round_start, round_effort = len(sampler.accepted), sampler.stats["effort"]
        round_t0 = time.monotonic()
        done_outer = 0
        while done_outer < p.outer:
            if len(sampler.accepted) >= n:
                return "done", sets
            if time.monotonic() > deadline:
                return "time budget", sets
            b = min(p.outer_batch, p.outer - done_outer)
            sampler.batch(fingers, b)
            done_outer += b
            if not sampler.accepted and sampler.stats["effort"] >= TOO_WEAK_AFTER:
                return TOO_WEAK, sets
            if on_batch is not None:
                on_batch(len(sampler.accepted))
        if len(sampler.accepted) >= n:
            return "done", sets
        now = time.monotonic()
        found = len(sampler.accepted) - round_start
        # a grasp rejected for its effort was found: finger iteration drops fingers the object
        # cannot be reached with, never because the load is heavy (fewer fingers hold less)
        reached = found + sampler.stats["effort"] - round_effort
        if (sampler.setup.finger_iteration and reached < p.min_valid
                and len(fingers) > p.min_fingers):
            fingers = fingers[:-1]
            sets.append(fingers)
            log.info("worker %d: %d grasps in a round; dropping finger, now %s", sampler.worker,
                     found, ", ".join(fingers))
        elif (p.relax_closure and sampler.require_closure
              and misses_budget(n - len(sampler.accepted), found, now - round_t0, deadline - now)):
            sampler.require_closure = False
            sampler.stats["relaxed"] += 1
            log.info("worker %d: %d grasps in a %.1f s round with %s cannot reach %d in the "
                     "%.1f s left; keeping grasps without force closure from now on (ranked "
                     "after every force-closure grasp)", sampler.worker, found, now - round_t0,
                     ", ".join(fingers), n, deadline - now)


def misses_budget(missing: int, found: int, round_s: float, left_s: float) -> bool:
    """Whether ``missing`` more grasps, at ``found`` per round of ``round_s`` seconds, take
    longer than the ``left_s`` seconds of budget left (always, when a round found none)."""
    return found <= 0 or missing / found * round_s > left_s


def _worker_run(setup: SamplerSetup, seed: int, worker: int, n: int, deadline: float,
                board: str | None = None) -> WorkerOutput:
    sampler = Sampler(setup, seed, worker)
    if board is None:
        stopped, sets = run_rounds(sampler, n, deadline)
        return sampler.accepted, sampler.stats, stopped, sets
    set_count, close = worker_slot(board, worker)
    try:
        stopped, sets = run_rounds(sampler, n, deadline, set_count)
    finally:
        close()
    return sampler.accepted, sampler.stats, stopped, sets


def _run_pool(setup: SamplerSetup, seed: int, n: int, deadline: float, workers: int,
              progress: Callable[[int], None] | None) -> list[WorkerOutput]:
    """The workers' runs on the persistent pool; with ``progress``, their summed count of
    accepted grasps (at most ``n``) reported about every 0.2 s while they run."""
    share = math.ceil(n / workers)
    return run_workers(_worker_run, [(setup, seed + k, k, share, deadline)
                                     for k in range(workers)], n, progress, (__name__,))


def merge(outs: Sequence[WorkerOutput], nq: int, params: FsgParams
          ) -> tuple[list[FsgGrasp], dict[str, int], str, list[tuple[str, ...]]]:
    """The workers' outputs, in worker order, as one: grasps de-duplicated across workers
    (step 8 again; not yet sorted or cut to ``n``), counts summed, the finger sets in first-seen
    order, and "done" unless a worker stopped otherwise."""
    dedup = Dedup(nq, params)
    grasps: list[FsgGrasp] = []
    stats: dict[str, int] = {}
    sets: list[tuple[str, ...]] = []
    stopped = "done"
    for accepted, st, stop, fs in outs:
        for k, v in st.items():
            stats[k] = stats.get(k, 0) + v
        for s in fs:
            if s not in sets:
                sets.append(s)
        if stop != "done":
            stopped = stop
        for g in accepted:
            if not dedup.is_duplicate(g.grasp.palm_pos, g.grasp.palm_quat_wxyz, g.grasp.joints):
                dedup.add(g.grasp.palm_pos, g.grasp.palm_quat_wxyz, g.grasp.joints)
                grasps.append(g)
    return grasps, stats, stopped, sets


def _idle_skeletons(hand: Hand) -> dict[str, np.ndarray]:
    """Each finger's link skeleton (K,3, ``frame_palm``) at zero joints, where a grasp leaves
    the fingers it does not use: table mode keeps them out of the table too."""
    q = np.zeros(hand.nq)
    return {f: hand.skeleton(q, f)[0] for f in hand.finger_names}


def generate(hand: Hand, obj: ObjectAsset | ObjectCloud, workspace: WorkspaceCloud, *,
             n: int = 10, fingers: int | None = None,
             finger_names: Sequence[str] | None = None, table: bool | TablePlane = False,
             use_affordance: bool = True, finger_iteration: bool = True,
             link_penetration: bool = False,
             exact_penetration: PenetrationCheck | None = None, seed: int = 0,
             time_budget_s: float = 60.0, workers: int = 1,
             params: FsgParams | None = None, hold: HoldLoads | None = None,
             effort: EffortScore | None = None,
             progress: Callable[[int], None] | None = None) -> FsgResult:
    """Generate up to ``n`` grasps of ``obj`` with ``hand`` from ``workspace`` (the
    :mod:`augment.fsg` overview).

    Args:
        hand: the hand (for the joint vector layout and the palm box).
        obj: the object, or its prepared :class:`~augment.object_cloud.ObjectCloud`.
        workspace: AutoWS clouds of this hand.
        n: grasps wanted.
        fingers: use at most this many fingers (the most important ones); default all.
        finger_names: use only these fingers (kept in priority order): with a demonstration,
            the fingers that touched in it — the paper's augmented grasps "involve only those
            fingers", and the others' demo-centred clouds rarely reach the object.
        table: reject palms (and fingertips' faces) below a table: ``True`` for the paper's
            (horizontal, through the object's lowest point), or a :class:`TablePlane` (where a
            demonstration's object really lay).
        use_affordance: ``True`` samples ``cloud_part`` (affordance annotation, else the
            curvature filter; the paper's "+Aff"); ``False`` samples the whole ``cloud_full``
            (the paper's plain "FSG").
        finger_iteration: drop fingers when a round yields fewer than ``min_valid`` grasps.
        link_penetration: the paper's eq. 3 check of the link skeletons (step 6).
        exact_penetration: the exact check in the validator's scene that ends step 6 (given by
            the caller; ``None``: the point-cloud checks only).
        seed: worker k uses ``seed + k``.
        time_budget_s: wall-clock limit; on expiry the grasps found so far are returned and the
            shortfall is logged (``FsgResult.stopped == "time budget"``).
        workers: processes (1: in this process).
        params: sampler parameters (default ``[fsg]`` of ``configs/augment.toml``).
        hold: the loads the caller's validation applies: rank by grip ratio over
            ``hold_oversample`` × n grasps found (module docstring); ``None``: rank by ε.
        effort: the caller's actuator-effort score: rank by it first (then grip ratio, ε).
        progress: called with the number of grasps found so far while the search runs (at
            most ``n``; before the merge removes the workers' duplicates), about every 0.2 s
            (:mod:`augment.fsg.progress`).

    Raises:
        FsgError: a workspace cloud of another hand, or bad options.
    """
    from augment.object_cloud import ObjectCloud, object_cloud

    t0 = time.monotonic()
    params = params or load_fsg_params(hand.config)
    if n < 1 or workers < 1 or not time_budget_s > 0:
        raise FsgError(f"need n >= 1, workers >= 1 and time_budget_s > 0; got n={n}, "
                       f"workers={workers}, time_budget_s={time_budget_s}")
    if workspace.hand != hand.name:
        raise FsgError(f"workspace cloud is for hand {workspace.hand!r}, not {hand.name!r}")
    for fc in workspace.fingers:
        missing = [j for j in fc.joint_names if j not in hand.joint_names]
        if missing or fc.name not in hand.finger_names:
            raise FsgError(f"workspace finger {fc.name!r} (joints {missing or fc.joint_names}) "
                           f"does not belong to hand {hand.name!r}")
    cloud = obj if isinstance(obj, ObjectCloud) else object_cloud(obj)
    part_idx = (np.flatnonzero(cloud.part_mask) if use_affordance
                else np.arange(len(cloud.points)))
    active = workspace.finger_names
    if finger_names is not None:
        unknown = sorted(set(finger_names) - set(active))
        if unknown:
            raise FsgError(f"finger_names {unknown} are not fingers of the workspace "
                           f"{list(active)}")
        active = tuple(f for f in active if f in set(finger_names))
    if fingers is not None:
        if fingers < 1:
            raise FsgError(f"fingers must be >= 1, got {fingers}")
        active = active[:fingers]
    if len(active) < 2:
        raise FsgError(f"FSG needs at least 2 fingers, got {list(active)}")
    # scoring costs ≈ 15 ms per accepted grasp (effort LP and collision pass), so it runs only
    # when it selects (hold_oversample > 1) or filters (a finite max_actuator_effort)
    filters = effort is not None and math.isfinite(params.max_actuator_effort)
    if params.hold_oversample <= 1.0:
        hold = None
        if not filters:
            effort = None
    palm = hand.config.palm
    setup = SamplerSetup(
        hand=hand.name, cloud=cloud, workspace=workspace, part_idx=part_idx,
        fingers=tuple(active),
        nq=hand.nq, finger_qadr={f: np.asarray(hand.finger_qadr[f]) for f in active},
        palm_center=np.asarray(palm.box_center, float),
        palm_half=np.asarray(palm.box_half_extents, float),
        table=TablePlane.horizontal(cloud.z_min_m) if table is True else (table or None),
        finger_iteration=finger_iteration, link_penetration=link_penetration,
        exact_penetration=exact_penetration,
        params=dataclasses.replace(params, min_fingers=max(params.min_fingers, 2)), hold=hold,
        effort=effort, idle_skeletons=_idle_skeletons(hand) if table else {})
    # with loads, find more than n and keep the n that hold them with the least effort / grip
    ranked = params.hold_oversample > 1.0 and (hold is not None or effort is not None)
    wanted = math.ceil(n * params.hold_oversample) if ranked else n
    shown = (None if progress is None
             else lambda k: progress(min(n, k * n // wanted)))
    # one absolute deadline (CLOCK_MONOTONIC is system-wide): a worker's start-up, its sampler
    # set-up and the pool's queueing count against the budget, not only its own sampling
    deadline = t0 + time_budget_s
    if workers == 1:
        sampler = Sampler(setup, seed, 0)
        stopped, sets = run_rounds(sampler, wanted, deadline, shown)
        outs = [(sampler.accepted, sampler.stats, stopped, sets)]
    else:
        outs = _run_pool(setup, seed, wanted, deadline, workers, shown)
    grasps, stats, stopped, sets = merge(outs, hand.nq, setup.params)
    if ranked:
        grasps.sort(key=lambda g: (0.0 if effort is None else g.actuator_effort,
                                   0.0 if hold is None else g.grip_ratio, -g.epsilon))
    else:
        grasps.sort(key=lambda g: -g.epsilon)
    grasps = grasps[:n]
    result = FsgResult(grasps=grasps, requested=n, stopped=stopped,
                       elapsed_s=time.monotonic() - t0, stats=stats, finger_sets=sets)
    if result.shortfall:
        log.warning("FSG on %s: %d of %d grasps (shortfall %d, stopped: %s) after %.1f s; "
                    "rejections %s", cloud.name, len(grasps), n, result.shortfall, stopped,
                    result.elapsed_s, stats)
    else:
        log.info("FSG on %s: %d grasps in %.2f s", cloud.name, len(grasps), result.elapsed_s)
    return result
