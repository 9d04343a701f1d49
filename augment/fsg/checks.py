"""FSG steps 6–8: the checks of a candidate whose contacts are known — link penetration
(paper eq. 3), quality, de-duplication.

6. **Link penetration.** Each used finger's link skeleton (stored per workspace point,
   ``frame_palm``) is moved into the object frame; for consecutive skeleton points p_n, p_n+1
   with nearest ``cloud_full`` points q_n, q_n+1 and q_n's normal nor_n,
   ``[(p_n − q_n)·nor_n]·[(p_n+1 − q_n+1)·nor_n] < 0`` is a penetration (:func:`eq3_crossing`).
   Beyond the paper: a skeleton point closer than ``link_clearance_m`` (the hand's
   ``link_radius_m``, from its folder) to the nearest object point also counts: eq. 3 only sees
   the skeleton *cross* the surface, while links lie at their radius around the skeleton, so a
   link can sink into a convex object without its axis crossing it. Both are point-cloud
   approximations of the links, so step 6 ends with a :data:`PenetrationCheck` in the
   validator's MuJoCo scene, given by the caller (the only mesh collision FSG computes, once per
   candidate that passes the point-cloud checks and is no duplicate); it also refuses the hand's
   own links inside each other (each finger's posture comes from its own workspace cloud).
7. **Quality** (:func:`grasp_quality`): Q1 (ε) and volume via :func:`sim.metrics.gws.gws_metrics`
   (μ, ``n_edges`` cone edges, centre = centre of mass, torque / max radius) on the contacts
   with inward normals; ε ≤ ``min_epsilon`` is dropped (until relaxed, :mod:`augment.fsg.run`).
8. **De-duplication** (:class:`Dedup`): palm within ``dedup_pos_m``, ``|q·q'| > 1 −
   dedup_quat`` and every joint within ``dedup_joint_rad`` of an accepted grasp.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from augment.fsg.params import FsgParams
from sim.grasp import Grasp
from sim.metrics.gws import GwsMetrics, gws_metrics

if TYPE_CHECKING:
    from augment.object_cloud import ObjectCloud

__all__ = ["Dedup", "EffortScore", "PenetrationCheck", "eq3_crossing", "grasp_quality", "link_penetrates"]

#: The exact penetration check FSG is given (step 6): ``True`` when the grasp, placed in the
#: validator's MuJoCo scene, penetrates the object — or its own links each other — deeper than
#: the validator allows. It runs after de-duplication and before the quality. Injected
#: (a picklable callable, e.g. :class:`sim.validate.batch.ScenePenetration`) so that the
#: sampler never imports the physics validator.
PenetrationCheck = Callable[[Grasp], bool]

#: The actuator-effort score FSG may be given (step 7, dexaug): the least worst actuator effort,
#: as a fraction of the force limits, with which the hand could hold the validation's loads at
#: the grasp (e.g. :class:`sim.validate.batch.SceneEffort`); injected like the penetration check.
EffortScore = Callable[[Grasp], float]


def eq3_crossing(skeleton: np.ndarray, nearest: np.ndarray, nearest_normals: np.ndarray) -> bool:
    """Paper eq. 3: does the skeleton polyline ``skeleton`` (K,3) cross the object surface?
    ``nearest`` (K,3) are the object points nearest each skeleton point and
    ``nearest_normals`` (K,3) their outward normals (all in one frame, metres); a segment
    p_n p_n+1 crosses when ``[(p_n − q_n)·nor_n]·[(p_n+1 − q_n+1)·nor_n] < 0``."""
    qn = nearest_normals[:-1]
    a = np.einsum("ij,ij->i", skeleton[:-1] - nearest[:-1], qn)
    b = np.einsum("ij,ij->i", skeleton[1:] - nearest[1:], qn)
    return bool(np.any(a * b < 0))


def link_penetrates(skeletons: Sequence[np.ndarray], rot: np.ndarray, trans: np.ndarray,
                    tree: cKDTree, points: np.ndarray, normals: np.ndarray,
                    clearance_m: float) -> bool:
    """Step 6's point-cloud check. ``skeletons``: per used finger (K,3) link skeleton points in
    ``frame_palm``; ``rot``, ``trans``: the candidate's transform object → palm; ``tree`` over
    ``points`` (N,3, ``cloud_full``, object frame) with outward ``normals``."""
    for sk in skeletons:
        sk_obj = (np.asarray(sk, dtype=float) - trans) @ rot   # rot.T per row: palm → object
        dist, qi = tree.query(sk_obj)
        if np.any(dist < clearance_m):
            return True
        if eq3_crossing(sk_obj, points[qi], normals[qi]):
            return True
    return False


def grasp_quality(points: np.ndarray, normals: np.ndarray, cloud: ObjectCloud,
                  params: FsgParams) -> GwsMetrics:
    """Step 7: GWS Q1 and volume of contacts at ``points`` with OUTWARD ``normals`` (object
    frame) of ``cloud`` (its centre of mass and maximum radius set the torque scale)."""
    return gws_metrics(points, -normals, params.mu, params.n_edges, cloud.com_m,
                       torque_scale_m=cloud.max_radius_m)


class Dedup:
    """Step 8: the accepted grasps' palm positions (metres), quaternions (wxyz) and joint
    vectors (radians), and the test of a new grasp against them."""

    def __init__(self, nq: int, params: FsgParams) -> None:
        self.params = params
        self.pos = np.zeros((0, 3))
        self.quat = np.zeros((0, 4))
        self.q = np.zeros((0, nq))

    def is_duplicate(self, pos: np.ndarray, quat: np.ndarray, q: np.ndarray) -> bool:
        if not len(self.pos):
            return False
        p = self.params
        same = (np.linalg.norm(self.pos - pos, axis=1) < p.dedup_pos_m) & (
            np.abs(self.quat @ quat) > 1 - p.dedup_quat) & (
            np.abs(self.q - q).max(axis=1) < p.dedup_joint_rad)
        return bool(same.any())

    def add(self, pos: np.ndarray, quat: np.ndarray, q: np.ndarray) -> None:
        self.pos = np.vstack([self.pos, pos])
        self.quat = np.vstack([self.quat, quat])
        self.q = np.vstack([self.q, q])
