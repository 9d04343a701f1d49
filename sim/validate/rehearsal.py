"""Choose a grasp's closing targets by rehearsing the benchmark's closing on the free object.

Most grasps that fail DexGraspBench fail before its first push: the closing itself (pregrasp →
grasp → squeeze, object free) shoves or turns the object out of its limits (README "Most `dgb`
failures happen before the first push"). The ``dexaug`` convention derives its pregrasp and
squeeze from the grasp's contacts, and its pregrasp has no single right answer for every grasp:
whether a tendon-shared finger starts at the split that pressing leaves it in
(:mod:`sim.validate.free_modes`) or at the grasp's own, and how far back along the contact
normals the fingers start (``[common] pregrasp_backoff_m``). Every such pregrasp leads to the
same squeeze (the same grip, so the same hold against the pushes): each is closed in the
benchmark's own scene with the object free and no load, and the one that leaves the object
nearest its starting pose is kept (ties: the earlier, see :func:`pregrasp_candidates`).

Only where even that closing has already lost the object (past the benchmark's limits before
any push, so the grasp fails as made) are gentler squeezes rehearsed from that pregrasp
(``[dgb] rehearsal_fallback_squeeze_scales`` of the squeeze's travel past the grasp), and the
calmest kept. Not before: a gentler squeeze closes more calmly and then loses the pushes (measured, README
"Rehearsed closing"), so the squeeze's grip is traded away only where it has already failed.

Last, the squeeze is corrected for the drift its rehearsed closing still leaves
(:func:`drift_corrected`, ``[dgb] rehearsal_drift_corrections`` times): the fingers are position
servos, springs around their targets, so a grip that holds the object displaced by a rigid
motion holds it back where it was once every target moves by that motion's inverse at the
contacts. The calmest of the corrected closings and the uncorrected one is kept.

A closing that already scores ``[dgb] rehearsal_calm_score`` or less (a tenth of the limits),
a pregrasp candidate's or a correction's, ends the rehearsal where it stands, later candidates
and corrections unrehearsed: on five demos the same verdicts, in less time (README "A calm
closing ends the rehearsal"; for corrections too: docs/decisions/2026-12-07-dgb-speed.md).

``[dgb] early_exit`` skips only simulation whose outcome is known, so the stages chosen are
the same bit for bit: the pregrasp → grasp stage that a fallback squeeze or a correction shares
with the closing it came from is copied, not simulated again (:func:`sim.validate.dgb.closed`),
a chosen pregrasp the benchmark refuses for penetration is not corrected (a correction keeps
the pregrasp, so it scores infinity too and can never be kept), and a correction that leaves the
squeeze as it was (no hand–object contact left to correct at) ends the corrections (each next one
would be the same). Every other decision compares a
closing's drift *at the end of its rest*, which is not monotone in time (a closing that has
pushed the object past the limits can settle it back), so no candidate's closing is cut short.

This is a generator rehearsing its own execution, as a grasp pipeline does before it commits
to control targets; the pushes, which decide the verdict, are not rehearsed. Units: metres,
radians; scores are dimensionless (drift over the benchmark's limit).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import mujoco
import numpy as np

from sim.transforms import quat_to_mat
from sim.validate.config import DgbParams
from sim.validate.dgb import closed, dgb_drift, dgb_penetration_m
from sim.validate.stages import GraspStages
from sim.world.contacts import contacts_between
from sim.world.scene import Scene

__all__ = ["closing_score", "drift_corrected", "pregrasp_candidates", "rehearse", "rehearsed",
           "rehearsed_stages", "squeeze_scaled"]

#: damping (m²/rad² against the contacts' squared metres) of the least squares that turns the
#: contacts' wanted motions into joint changes: keeps a joint the contacts barely see from a
#: large change; the Shadow's fingertip Jacobians are ≈ (0.02–0.1 m)², so it is small beside them
_LSQ_DAMPING = 1e-4


def squeeze_scaled(stages: GraspStages, scales: Sequence[float]) -> list[GraspStages]:
    """``stages`` with its squeeze moved to grasp + s·(squeeze − grasp) for each scale s (1: as
    made), pregrasp and grasp unchanged."""
    return [dataclasses.replace(stages, squeeze=stages.grasp + s * (stages.squeeze - stages.grasp))
            for s in scales]


def pregrasp_candidates(stages: GraspStages, shares: Sequence[float]) -> list[GraspStages]:
    """``stages`` with its pregrasp moved to grasp + share·(pregrasp − grasp) for each share (1:
    as made, 0: start at the grasp), from the made pregrasp and then from its own-split
    alternative (``pregrasp_own_split``) where it has one; equal pregrasps listed once, first
    kept. Squeeze and grasp unchanged."""
    starts = [stages.pregrasp]
    if stages.pregrasp_own_split is not None:
        starts.append(stages.pregrasp_own_split)
    out: list[GraspStages] = []
    for share in shares:
        for start in starts:
            pre = stages.grasp + share * (start - stages.grasp)
            if not any(np.array_equal(pre, c.pregrasp) for c in out):
                out.append(dataclasses.replace(stages, pregrasp=pre))
    return out


def closing_score(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
                  stages: GraspStages) -> float:
    """The free object's drift after the benchmark's closing of ``stages`` and ``[dgb]
    rehearsal_rest_s`` more unloaded (no push), as a fraction of the benchmark's limit:
    max(metres / max_displacement_m, radians / max_rotation_rad). At 1 or above the grasp has
    already failed; infinite where the benchmark would refuse the pregrasp for penetration. Why
    the rest: a closing that has not come to rest keeps drifting through the pushes (the
    screwdriver's failing grasps 5.2° at the squeeze's end, 10.4° half a second later). The
    closing is kept (:func:`closed`): the benchmark's run of the kept candidate starts from it,
    not from the rest."""
    scene.reset_with_grasp(*palm_world, stages.pregrasp)
    if max(dgb_penetration_m(scene)) > p.max_penetration_m:
        return float("inf")
    pos0, quat0 = scene.object_pose()
    closed(scene, p, palm_world, stages)
    mujoco.mj_step(scene.model, scene.data, nstep=round(p.rehearsal_rest_s / scene.model.opt.timestep))
    moved_m, turned_rad = dgb_drift(pos0, quat0, *scene.object_pose())
    return max(moved_m / p.max_displacement_m, turned_rad / p.max_rotation_rad)


def rehearse(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
             candidates: Sequence[GraspStages], calm_score: float = 0.0) -> tuple[int, np.ndarray]:
    """(index of the candidate whose closing moves the free object least — the first of equals —,
    every candidate's :func:`closing_score`). ``scene`` is the benchmark's (``dgb``) scene.
    Candidates are rehearsed in order, and the first that scores ``calm_score`` or less ends
    the rehearsal (the later ones score infinity, unrehearsed): a closing that calm already
    holds as well as a calmer one would, and each rehearsal costs a closing and a rest."""
    if not candidates:
        raise ValueError("rehearse: no candidate stages")
    scores = np.full(len(candidates), np.inf)
    for i, candidate in enumerate(candidates):
        scores[i] = closing_score(scene, p, palm_world, candidate)
        if scores[i] <= calm_score:
            break
    return int(np.argmin(scores)), scores


def drift_corrected(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
                    stages: GraspStages) -> GraspStages:
    """``stages`` with the squeeze moved to hold the object where the closing started (module
    docstring): the benchmark's closing of ``stages`` leaves the free object moved by a rigid
    motion (R, t); each hand–object contact point x is then wanted at R⁻¹(x − t), and the
    squeeze changes by the damped least-squares joint change that moves the contact points so
    (their Jacobians on the scene's hand joints). Pregrasp and grasp unchanged."""
    m, d = scene.model, scene.data
    scene.reset_with_grasp(*palm_world, stages.pregrasp)
    pos0, quat0 = scene.object_pose()
    closed(scene, p, palm_world, stages)
    pos1, quat1 = scene.object_pose()
    back = quat_to_mat(quat0) @ quat_to_mat(quat1).T   # the inverse rotation, world frame
    touching = contacts_between(m, d, scene.hand_geom_mask, scene.obj_geom_mask)
    if not len(touching.dist):
        return stages
    jac = np.zeros((3, m.nv))
    rows, wanted = [], []
    for point, body in zip(touching.pos, touching.body_a, strict=True):
        mujoco.mj_jac(m, d, jac, None, point, int(body))
        rows.append(jac[:, scene.hand_dadr].copy())
        wanted.append(back @ (point - pos1) + pos0 - point)
    a, b = np.vstack(rows), np.concatenate(wanted)
    dq = np.linalg.solve(a.T @ a + _LSQ_DAMPING * np.eye(a.shape[1]), a.T @ b)
    squeeze = stages.squeeze.copy()
    squeeze[scene.hand_joint_kept] += dq
    return dataclasses.replace(stages, squeeze=squeeze)


def rehearsed_stages(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
                     pregrasps: Sequence[GraspStages], fallback_scales: Sequence[float],
                     corrections: int = 0, calm_score: float = 0.0) -> GraspStages:
    """The stages to run (module docstring): of ``pregrasps`` (the same squeeze from different
    pregrasps, in order of preference) the calmest; where that closing scores 1 or more, the
    calmest of it and of it with its squeeze at ``fallback_scales``; then the calmest of that
    and its ``corrections`` successive :func:`drift_corrected` squeezes, unless it already
    scores ``calm_score`` or less."""
    best, scores = rehearse(scene, p, palm_world, pregrasps, calm_score)
    chosen, score = pregrasps[best], float(scores[best])
    if score >= 1.0 and fallback_scales:
        gentler = squeeze_scaled(chosen, fallback_scales)
        calmest, gentle_scores = rehearse(scene, p, palm_world, gentler)
        if gentle_scores[calmest] < score:
            chosen, score = gentler[calmest], float(gentle_scores[calmest])
    current = chosen
    # a pregrasp the benchmark refuses (score infinite) stays refused: corrections keep it, so
    # none can score lower, and each would still simulate a closing (early exit skips them)
    if p.early_exit and score == float("inf"):
        corrections = 0
    # each from the last: a correction can pass through a worse closing; a calm one ends them
    # as it ends the pregrasp candidates, and one that leaves the squeeze as it was (no contact
    # left to correct at) would only repeat its closing
    for _ in range(corrections if score > calm_score else 0):
        corrected = drift_corrected(scene, p, palm_world, current)
        if p.early_exit and np.array_equal(corrected.squeeze, current.squeeze):
            break
        current = corrected
        if (corrected_score := closing_score(scene, p, palm_world, current)) < score:
            chosen, score = current, corrected_score
        if score <= calm_score:
            break
    return chosen


def rehearsed(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
              stages: GraspStages) -> GraspStages:
    """The stages the benchmark runs for ``stages`` as a convention made them: rehearsed
    (:func:`rehearsed_stages` over :func:`pregrasp_candidates`, ``p``'s shares and scales) when
    the ``dexaug`` convention made them and ``p.rehearse_closing``; else unchanged."""
    if stages.made_by != "dexaug" or not p.rehearse_closing:
        return stages
    return rehearsed_stages(scene, p, palm_world, pregrasp_candidates(stages, p.rehearsal_pregrasp_shares),
                            p.rehearsal_fallback_squeeze_scales, p.rehearsal_drift_corrections,
                            p.rehearsal_calm_score)
