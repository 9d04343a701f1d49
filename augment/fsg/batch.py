"""One FSG worker's sampler: its state (RNG, counts, accepted grasps) and one batch of palm pose
candidates through steps 1–8 of the :mod:`augment.fsg` overview.

The steps themselves live in their modules (:mod:`~augment.fsg.candidates`,
:mod:`~augment.fsg.matching`, :mod:`~augment.fsg.contacts`, :mod:`~augment.fsg.checks`); this
module only strings them together in the order that fixes the RNG draws (step 1's five draws,
then one permutation per further finger), so that a seed gives the same grasps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from augment.fsg.candidates import (
    Candidates,
    contact_faces_below_table,
    first_finger,
    links_below_table,
    palm_candidates,
)
from augment.fsg.checks import Dedup, EffortScore, PenetrationCheck, grasp_quality, link_penetrates
from augment.fsg.contacts import collect_contacts
from augment.fsg.matching import FingerIndex, match_fingers
from augment.fsg.params import FsgParams
from augment.fsg.result import FsgGrasp
from augment.fsg.table import TablePlane
from sim.grasp import Grasp
from sim.metrics.holding import HoldLoads
from sim.transforms import mat_to_quat

if TYPE_CHECKING:
    from augment.autows.cloud import FingerCloud, WorkspaceCloud
    from augment.object_cloud import ObjectCloud

__all__ = ["Sampler", "SamplerSetup"]


def _tip_skeleton(fc: FingerCloud) -> np.ndarray:
    """``fc``'s fingertip-link skeleton (N, J, 3); empty (N, 0, 3) where the cloud was made
    without one, as its docstring says of a skeleton not built."""
    if fc.tip_skeleton is not None:
        return fc.tip_skeleton
    return np.zeros((len(fc.skeleton), 0, 3), dtype=np.float32)


@dataclass(frozen=True)
class SamplerSetup:
    """Everything a worker needs, as plain picklable data (no MuJoCo objects).

    Attributes:
        hand: hand name.
        cloud: the object cloud; part_idx: indices of the sampled points (``cloud_part`` or
            all of ``cloud_full``).
        workspace: the hand's workspace clouds.
        fingers: active fingers at the start, priority order.
        nq: length of the hand's joint vector; finger_qadr: finger → its joints' indices in it.
        palm_center, palm_half: the palm box in ``frame_palm``, metres.
        table: the table plane in table mode, else None; finger_iteration: drop fingers on a
            poor round.
        link_penetration: the paper's eq. 3 on the link skeletons (step 6).
        exact_penetration: the caller's exact check that ends step 6, or ``None``.
        params: sampler parameters.
        hold: the loads the caller's validation will put on the object (each accepted grasp's
            grip ratio is computed from them), or ``None``.
        effort: the caller's actuator-effort score of each accepted grasp, or ``None``.
        idle_skeletons: per finger of the hand, its link skeleton (K,3, ``frame_palm``) at the
            zero joints a grasp leaves an unused finger at; table mode checks them.
    """

    hand: str
    cloud: ObjectCloud
    workspace: WorkspaceCloud
    part_idx: np.ndarray
    fingers: tuple[str, ...]
    nq: int
    finger_qadr: dict[str, np.ndarray]
    palm_center: np.ndarray
    palm_half: np.ndarray
    table: TablePlane | None
    finger_iteration: bool
    link_penetration: bool
    exact_penetration: PenetrationCheck | None
    params: FsgParams
    hold: HoldLoads | None = None
    effort: EffortScore | None = None
    idle_skeletons: dict[str, np.ndarray] = field(default_factory=dict)


class Sampler:
    """One worker: ``batch`` adds the grasps of a batch to ``accepted`` and counts what
    happened to every candidate in ``stats``."""

    def __init__(self, setup: SamplerSetup, seed: int, worker: int = 0) -> None:
        self.setup = setup
        self.params = setup.params
        self.rng = np.random.default_rng(seed)
        self.worker = worker
        self.points = np.asarray(setup.cloud.points)
        self.normals = np.asarray(setup.cloud.normals)
        self.obj_tree = cKDTree(self.points)
        self.clouds = {f: setup.workspace.finger(f) for f in setup.fingers}
        self.index = FingerIndex.build(self.clouds, self.params)
        self.stats: dict[str, int] = {k: 0 for k in (
            "candidates", "palm", "table", "no_match", "contacts", "depth", "link", "epsilon",
            "duplicate", "penetration", "effort", "accepted", "accepted_open", "relaxed")}
        self.accepted: list[FsgGrasp] = []
        #: grasps without force closure (ε ≤ ``min_epsilon``) are dropped until
        #: :func:`augment.fsg.run.run_rounds` relaxes this (``relax_closure``)
        self.require_closure = True
        self.dedup = Dedup(setup.nq, self.params)

    def batch(self, fingers: tuple[str, ...], n_outer: int) -> None:
        """``n_outer`` outer iterations (× ``inner`` candidates) with ``fingers``."""
        s = self.setup
        first = first_finger(fingers, self.clouds)
        cands = palm_candidates(self.rng, self.points, self.normals, s.part_idx,
                                self.clouds[first], n_outer, palm_center=s.palm_center,
                                palm_half=s.palm_half,
                                table=s.table,
                                params=self.params, stats=self.stats)
        if cands is None:
            return
        s_idx, chosen = match_fingers(self.rng, fingers, first, cands, s.part_idx, self.normals,
                                      self.clouds, self.index, self.params, self.stats)
        if not len(s_idx):
            return
        self._finish(fingers, s_idx, cands, chosen)

    def _in_table(self, fingers: tuple[str, ...], faces: list[tuple[FingerCloud, int]],
                  r: np.ndarray, t: np.ndarray) -> bool:
        """Table mode's checks once the fingers are matched: contact-face rims, then the links
        of used fingers at their workspace joints and of idle ones at zero."""
        s, p = self.setup, self.params
        # table mode only: a setup with a table, whose clouds carry their fingertip skeletons
        assert s.table is not None
        if contact_faces_below_table(faces, r, t, s.table, p.table_clearance_m):
            return True
        # the whole finger, fingertip link included (the link check leaves it to the contact)
        skeletons = [np.vstack([fc.skeleton[k], _tip_skeleton(fc)[k]]) for fc, k in faces]
        skeletons += [sk for f, sk in s.idle_skeletons.items() if f not in fingers]
        return links_below_table(skeletons, r, t, s.table, p.link_clearance_m + p.table_clearance_m)

    def _finish(self, fingers: tuple[str, ...], s_idx: np.ndarray, cands: Candidates,
                chosen: dict[str, np.ndarray]) -> None:
        """Steps 5–8 on the matched candidates ``s_idx``: the cheap checks first, then the
        de-duplication, the exact penetration check and the quality (the costly ones)."""
        p, s = self.params, self.setup
        for c in s_idx:
            r, t = cands.rot[c], cands.trans[c]
            picks = [int(chosen[f][c]) for f in fingers]
            faces = [(self.clouds[f], k) for f, k in zip(fingers, picks, strict=True)]
            reason, idx, finger_i = collect_contacts(faces, cands.full[c], self.normals @ r.T, p)
            if reason is not None:
                self.stats[reason] += 1
                continue
            if s.table is not None and self._in_table(fingers, faces, r, t):
                self.stats["table"] += 1
                continue
            if s.link_penetration and link_penetrates(
                    [fc.skeleton[k] for fc, k in faces], r, t, self.obj_tree, self.points,
                    self.normals, p.link_clearance_m):
                self.stats["link"] += 1
                continue
            # palm pose in the object frame: inverse of object → palm
            palm_rot = r.T
            palm_pos = -palm_rot @ t
            quat = mat_to_quat(palm_rot)
            q = np.zeros(s.nq)
            for f, k in zip(fingers, picks, strict=True):
                q[s.finger_qadr[f]] = self.clouds[f].joints[k]
            if self.dedup.is_duplicate(palm_pos, quat, q):
                self.stats["duplicate"] += 1
                continue
            grasp = Grasp(palm_pos, quat, q)
            # the exact check (≈ 2 ms) before the quality's hull (≈ 10 ms): a third of the
            # candidates that reach it put fingers into each other (sim.validate.batch)
            if s.exact_penetration is not None and s.exact_penetration(grasp):
                self.stats["penetration"] += 1
                continue
            cpts, cnrm = self.points[idx], self.normals[idx]
            m = grasp_quality(cpts, cnrm, s.cloud, p)
            closure = m.epsilon > p.min_epsilon
            if not closure and self.require_closure:
                self.stats["epsilon"] += 1
                continue
            ratio = (s.hold.grip_ratio(cpts, cnrm, finger_i) if s.hold is not None
                     else float("nan"))
            effort = s.effort(grasp) if s.effort is not None else float("nan")
            if effort > p.max_actuator_effort:   # the actuators cannot hold the loads here
                self.stats["effort"] += 1
                continue
            self.dedup.add(palm_pos, quat, q)
            self.stats["accepted"] += 1
            self.stats["accepted_open"] += int(not closure)
            self.accepted.append(FsgGrasp(
                grasp=grasp, fingers=fingers, contact_points=cpts.copy(),
                contact_normals=cnrm.copy(), contact_finger=finger_i,
                ws_index=tuple(picks),
                face_index=tuple(int(fc.face_index[k]) for fc, k in faces),
                epsilon=float(m.epsilon), volume=float(m.volume), worker=self.worker,
                grip_ratio=ratio, actuator_effort=effort))
