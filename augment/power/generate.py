"""Generate power grasps: place the palm, close the whole hand in simulation, keep what holds.

See :mod:`augment.power` for the idea. Each candidate costs one closing simulation in the
validator's scene (about 20–40 ms for the Shadow Hand) plus the effort score (≈ 15 ms), so the
work is split over processes like FSG's (worker k samples with ``seed + k``) and ends at the
time budget with what was found. Grasps come out ranked by actuator effort, least first: the
grasps the actuators hold most comfortably.
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from augment.fsg.checks import Dedup
from augment.fsg.params import load_fsg_params
from augment.fsg.progress import run_workers, worker_slot
from augment.fsg.result import FsgGrasp, FsgResult
from augment.object_cloud import ObjectCloud, object_cloud
from augment.power.demo_seed import (
    MIN_OTHER_FINGERS,
    PowerSeed,
    SeedShare,
    approach_postures,
    place_seeded,
    seeded_palm,
    seeded_target,
)
from augment.power.params import PowerParams, load_power_params
from augment.power.placement import hand_gaps_m, palm_quats, place_palm
from sim.errors import DexaugError
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.metrics.gws import gws_metrics
from sim.transforms import quat_to_mat
from sim.validate.batch import SceneEffort, cached_validator
from sim.world.closing import close_on_object
from sim.world.contacts import contacts_between, merge_nearby
from sim.world.objects import load_object
from sim.world.scene import HAND_PREFIX, Scene

__all__ = ["PowerError", "generate_power"]

log = logging.getLogger(__name__)

#: friction coefficient of the ε reported with each grasp (the paper's GWS μ, as FSG's)
_GWS_MU = 0.5


class PowerError(DexaugError, ValueError):
    """The power mode cannot run for this hand (e.g. its config names no close posture)."""


@dataclass(frozen=True)
class _Job:
    """What one worker needs (plain names, so it pickles)."""

    hand: str
    obj: str
    protocol: str
    params: PowerParams
    use_affordance: bool
    seed: PowerSeed | None = None


def _finger_of_body(scene: Scene, hand: Hand) -> dict[int, int]:
    """Scene body id → index into ``hand.finger_names`` for every link of every finger."""
    return {scene.model.body(HAND_PREFIX + link).id: k
            for k, f in enumerate(hand.config.fingers) for link in {*f.links, f.tip_body}}


def _postures(hand: Hand, p: PowerParams) -> tuple[np.ndarray, np.ndarray]:
    q_open, q_close = hand.posture(p.approach_pose), hand.posture(p.close_pose)
    if np.allclose(q_open, q_close):
        raise PowerError(f"hand {hand.name}: [grasp] {p.approach_pose} and {p.close_pose} of "
                         f"its hand.toml are the same posture; the power mode closes from the "
                         f"first toward the second")
    return q_open, q_close


def _contacts(scene: Scene, finger_of: dict[int, int], contact_m: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """The closed hand's contacts in the object frame: points (M,3), outward normals (M,3),
    finger index (M,) of the finger contacts (merged per body and 1 cm cell), and whether the
    palm touches."""
    m, d = scene.model, scene.data
    con = contacts_between(m, d, scene.hand_geom_mask, scene.obj_geom_mask)
    touch = con.dist <= contact_m
    palm = bool((con.body_a[touch] == scene.palm_body).any())
    fingers = np.array([finger_of.get(int(b), -1) for b in con.body_a], int)
    keep = touch & (fingers >= 0)
    pos, quat = scene.object_pose()
    rot = quat_to_mat(quat)                      # object → world; rows @ rot = world → object
    pts = (con.points_a[keep] - pos) @ rot
    nrm = -con.normal[keep] @ rot                # hand → object is inward: flip to outward
    labels = con.body_a[keep]
    if not len(pts):
        return pts, nrm, np.zeros(0, int), palm
    merged_pts, merged_nrm, merged_fingers = [], [], []
    for body in np.unique(labels):
        sel = labels == body
        p_b, n_b = merge_nearby(pts[sel], nrm[sel])
        merged_pts.append(p_b)
        merged_nrm.append(n_b)
        merged_fingers.append(np.full(len(p_b), finger_of[int(body)]))
    return (np.concatenate(merged_pts), np.concatenate(merged_nrm),
            np.concatenate(merged_fingers), palm)


#: placements tried per closing allowed: a placement is a few collision passes (≈ 3 ms), a
#: closing a simulation (≈ 25 ms), and on a box most points lie on faces the palm overhangs
_PLACEMENTS_PER_CLOSING = 10
#: tries of :func:`_clear_of_object` to move the closed hand out of the object
_CLEARING_STEPS = 3


def _clear_of_object(scene: Scene, grasp: Grasp, contact_m: float) -> Grasp | None:
    """``grasp`` with its palm moved back, away from the palm face (frame_palm −y), until no
    hand geom is more than ``contact_m`` inside the object (None when three moves do not get it
    out), the scene left placed at it. Why: servos closing on an object can leave a link a
    millimetre or two inside it, and in a validation, where the object is free, that overlap
    kicks the object away before the fingers close."""
    pos = grasp.palm_pos.copy()
    back = -quat_to_mat(grasp.palm_quat_wxyz)[:, 1]
    for _ in range(_CLEARING_STEPS + 1):
        _, hand_gap = hand_gaps_m(scene, pos, grasp.palm_quat_wxyz, grasp.joints)
        if hand_gap >= -contact_m:
            mujoco.mj_forward(scene.model, scene.data)
            return Grasp.from_arrays(pos, grasp.palm_quat_wxyz, grasp.joints)
        pos = pos + back * (-hand_gap)
    return None


def _place(scene: Scene, rng: np.random.Generator, job: _Job, cloud: ObjectCloud,
           idx: np.ndarray, approaches: list[np.ndarray], seeded: bool
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """One placement: (palm position, palm quaternion, approach posture), object frame; None
    when it misses. ``seeded``: the demo's palm varied (:func:`seeded_palm`); else a sampled
    surface point of ``cloud`` (``idx``) with the palm against it, the first of
    ``approaches`` that places."""
    p = job.params
    if seeded and job.seed is not None:   # the person's approach
        point, normal, quat = seeded_palm(rng, job.seed, cloud.com_m, p.seed_turn_deg,
                                          p.seed_shift_m)
        placed = place_seeded(scene, point, normal, quat, approaches, p.standoff_m)
        return None if placed is None else (placed[0], quat, placed[1])
    k = int(rng.choice(idx))
    point, normal = cloud.points[k], cloud.normals[k]
    quat = palm_quats(normal[None], rng.uniform(0.0, 2 * math.pi, 1))[0]
    for q_from in approaches:
        pos = place_palm(scene, point, normal, quat, q_from, p.standoff_m, p.max_palm_gap_m)
        if pos is not None:
            return pos, quat, q_from
    return None


def _worker_run(job: _Job, seed: int, worker: int, n: int, deadline: float,
                board: str | None = None) -> tuple[list[FsgGrasp], dict[str, int]]:
    """One worker's search: up to ``n`` grasps, at most ``n × tries_per_grasp`` closings,
    until ``deadline`` (``time.time()``)."""
    set_count, close = worker_slot(board, worker) if board else (lambda k: None, lambda: None)
    try:
        return _search(job, seed, worker, n, deadline, set_count)
    finally:
        close()


def _search(job: _Job, seed: int, worker: int, n: int, deadline: float,
            set_count: Callable[[int], None]) -> tuple[list[FsgGrasp], dict[str, int]]:
    p = job.params
    validator = cached_validator(job.hand, job.obj)
    hand, scene = validator.hand, validator.scene("lift-drop")
    effort = SceneEffort(job.hand, job.obj, job.protocol)
    q_open, q_close = _postures(hand, p)
    approaches = [q_open]
    if job.seed is not None:   # a power demo: from and toward the person's posture
        approaches = approach_postures(job.seed, q_open)
        q_close = seeded_target(hand, job.seed, q_close, p.seed_overshoot)
    min_used = 1 + (MIN_OTHER_FINGERS if job.seed is not None else 1)
    share = SeedShare(p.seed_share) if job.seed is not None else None
    cloud = object_cloud(load_object(job.obj))
    idx = cloud.part_indices if job.use_affordance and cloud.part_mask.any() else \
        np.arange(len(cloud.points))
    finger_of = _finger_of_body(scene, hand)
    thumb = 0   # fingers are in priority order, thumb first (hand.toml convention)
    dedup = Dedup(hand.nq, load_fsg_params(hand.config))
    rng = np.random.default_rng(seed)
    stats: Counter[str] = Counter()
    out: list[FsgGrasp] = []
    closings = n * p.tries_per_grasp
    release_s = p.close_time_s + p.hold_time_s if p.settle_free else math.inf
    for _ in range(closings * _PLACEMENTS_PER_CLOSING):
        if len(out) >= n or time.time() >= deadline or stats["closed"] >= closings:
            break
        stats["candidates"] += 1
        seeded = share is not None and share.pick(rng)
        placed = _place(scene, rng, job, cloud, idx, approaches, seeded)
        if placed is None:
            stats["placement"] += 1
            continue
        pos, quat, q_from = placed
        stats["closed"] += 1
        if seeded:
            stats["seeded_closed"] += 1
        closed = close_on_object(scene, pos, quat, q_from, q_close, close_time_s=p.close_time_s,
                                 hold_time_s=p.hold_time_s, release_after_s=release_s)
        grasp = _clear_of_object(scene, closed, p.contact_m)
        if grasp is None:
            stats["penetration"] += 1
            continue
        pts, nrm, fin, palm = _contacts(scene, finger_of, p.contact_m)
        used = sorted(set(fin.tolist()))
        if share is not None:
            share.record(seeded, thumb in used and len(used) >= min_used)
        if thumb not in used or len(used) < min_used:
            stats["no_opposition"] += 1
            continue
        if dedup.is_duplicate(grasp.palm_pos, grasp.palm_quat_wxyz, grasp.joints):
            stats["duplicate"] += 1
            continue
        e = effort(grasp)
        if not e <= p.max_effort:
            stats["effort"] += 1
            continue
        dedup.add(grasp.palm_pos, grasp.palm_quat_wxyz, grasp.joints)
        metrics = gws_metrics(pts, -nrm, mu=_GWS_MU, centre=cloud.com_m,
                              torque_scale_m=cloud.max_radius_m)
        names = tuple(hand.finger_names[i] for i in used)
        out.append(FsgGrasp(grasp=grasp, fingers=names, contact_points=pts,
                            contact_normals=nrm,
                            contact_finger=np.array([used.index(i) for i in fin], np.int8),
                            ws_index=(), face_index=(), epsilon=metrics.epsilon,
                            volume=metrics.volume, worker=worker, actuator_effort=e))
        stats["accepted"] += 1
        stats["palm_contact"] += palm
        if seeded:
            stats["seeded_accepted"] += 1
        set_count(len(out))
    return out, dict(stats)


def generate_power(hand: Hand, obj_name: str, *, n: int = 10, seed: int = 0,
                   workers: int = 1, time_budget_s: float = 60.0, protocol: str = "lift-drop",
                   use_affordance: bool = True, params: PowerParams | None = None,
                   progress: Callable[[int], None] | None = None,
                   demo: PowerSeed | None = None) -> FsgResult:
    """Up to ``n`` power grasps of object ``obj_name`` with ``hand`` (module docstring),
    ranked by the actuator effort that ``protocol``'s loads need, least first: the search finds
    ``oversample`` × n and keeps the n of least effort. With ``demo`` (a power demo), the
    fingers close toward the person's posture and part of the palms are the person's, varied
    (:mod:`augment.power.demo_seed`); kept grasps touch with the thumb and two other fingers.

    Stats: ``candidates`` placements tried, dropped at ``placement`` (the palm overhangs an
    edge), ``closed`` hands closed on the object, dropped at ``penetration`` (a link stays
    inside the object), ``no_opposition`` (the closed hand does not touch with the thumb
    and another finger), ``duplicate``, ``effort`` (the actuators cannot hold the loads at
    these contacts), ``accepted`` (``palm_contact`` of them with the palm touching); with
    ``demo``, ``seeded_closed`` / ``seeded_accepted`` of them from the demo's palm varied."""
    p = params or load_power_params(hand_file=hand.config.file)
    _postures(hand, p)
    job = _Job(hand.name, obj_name, protocol, p, use_affordance, demo)
    t0 = time.perf_counter()
    deadline = time.time() + time_budget_s
    wanted = math.ceil(n * p.oversample)
    shown = (None if progress is None
             else lambda k: progress(min(n, k * n // wanted)))
    if workers <= 1:
        outs = [_search(job, seed, 0, wanted, deadline, shown or (lambda k: None))]
    else:
        outs = _run_pool(job, seed, wanted, deadline, workers, shown)
    grasps: list[FsgGrasp] = []
    stats: Counter[str] = Counter()
    dedup = Dedup(hand.nq, load_fsg_params(hand.config))
    for found, st in outs:
        stats.update(st)
        for g in found:
            if not dedup.is_duplicate(g.grasp.palm_pos, g.grasp.palm_quat_wxyz, g.grasp.joints):
                dedup.add(g.grasp.palm_pos, g.grasp.palm_quat_wxyz, g.grasp.joints)
                grasps.append(g)
    grasps.sort(key=lambda g: g.actuator_effort)
    grasps = grasps[:n]
    elapsed = time.perf_counter() - t0
    stopped = "done" if len(grasps) >= n else (
        "time budget" if time.time() >= deadline else "tries")   # tries: tries_per_grasp
    if not grasps and stats["effort"]:
        log.warning("%s: no power grasp can hold %.2f kg with these actuators (%s loads): "
                    "the %d that touched with the thumb and another finger need more than "
                    "%g of their force limits", obj_name, load_object(obj_name).mass_kg,
                    protocol, stats["effort"], p.max_effort)
    elif len(grasps) < n:
        log.warning("power grasps of %s: %d of %d after %d candidates (%s); rejected: %s",
                    obj_name, len(grasps), n, stats["candidates"], stopped,
                    {k: v for k, v in stats.items() if k not in ("candidates", "accepted")})
    return FsgResult(grasps=grasps, requested=n, stopped=stopped, elapsed_s=elapsed,
                     stats=dict(stats),
                     finger_sets=[tuple(demo.fingers if demo else hand.finger_names)])


def _run_pool(job: _Job, seed: int, n: int, deadline: float, workers: int,
              progress: Callable[[int], None] | None
              ) -> list[tuple[list[FsgGrasp], dict[str, int]]]:
    share = math.ceil(n / workers)
    return run_workers(_worker_run, [(job, seed + k, k, share, deadline)
                                     for k in range(workers)], n, progress, (__name__,))
