"""FSG steps 3–4: the other fingers' contacts, by k-d tree matching, with the paper's eq. 2
neighbour removal and the finger-crossing rule.

For each further finger in priority order, one ``cKDTree.query`` covers all live candidates'
transformed ``cloud_part`` points (those inside the finger cloud's bounding box grown by
``match_distance_m``). The trees are 6-D, over (position, λ·normal) with
λ = ``match_distance_m`` / √(2(1 + ``normal_dot``)), and are queried with (p_obj, −λ·n_obj): the
``k_neighbours`` nearest are then close in position *and* opposed in normal, where a 3-D
query's nearest neighbours often all face the wrong way; the paper's thresholds are applied
exactly afterwards (distance < ``match_distance_m``, ``⟨n_obj, n_fin⟩ < normal_dot``). A pair
is usable when its object point was not removed by an earlier contact (:func:`eq2_removed`)
and it keeps the crossing order (:func:`keeps_order`); one usable pair is drawn at random per
candidate, and candidates without one are dropped. All positions and normals are in
``frame_palm`` (metres).

Crossing groups (:func:`crossing_groups`): the active clouds are split in two by the sign of
their mean normal against the first finger's (thumb vs. the others); within a group they are
ordered along the group's spread axis, the principal direction of the clouds' mean positions
(the paper's "y axis" of its palm frame is the axis across the fingers; in dexaug's frame_palm
+y is the palm normal, so the axis is taken from the data), and contacts must keep that order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from augment.fsg.candidates import Candidates
from augment.fsg.params import FsgParams

if TYPE_CHECKING:
    from augment.autows.cloud import FingerCloud

__all__ = ["CrossingGroups", "FingerIndex", "crossing_groups", "eq2_removed", "keeps_order",
           "match_fingers"]

#: finger → (group id, order coordinate along the group axis, group axis (3,))
CrossingGroups = dict[str, tuple[int, float, np.ndarray]]


@dataclass(frozen=True)
class FingerIndex:
    """The matching structures of the active fingers, built once per worker.

    Attributes:
        lam: λ, the weight of the normal in the 6-D trees (metres per unit normal).
        bound: the query's distance bound, √2 · ``match_distance_m``.
        trees: finger → 6-D tree over (position, λ·normal) of its workspace cloud.
        boxes: finger → (lo, hi) the cloud's bounding box grown by ``match_distance_m``.
    """

    lam: float
    bound: float
    trees: dict[str, cKDTree]
    boxes: dict[str, tuple[np.ndarray, np.ndarray]]

    @classmethod
    def build(cls, clouds: Mapping[str, FingerCloud], params: FsgParams) -> FingerIndex:
        # lam makes the normal tolerance (chord √(2(1+normal_dot)) ≈ 0.2 for −0.98) weigh
        # like the distance tolerance
        chord = math.sqrt(max(2.0 * (1.0 + params.normal_dot), 1e-6))
        lam = params.match_distance_m / chord
        trees = {f: cKDTree(np.hstack([np.asarray(fc.positions), lam * np.asarray(fc.normals)]))
                 for f, fc in clouds.items()}
        boxes = {f: (np.asarray(fc.positions).min(axis=0) - params.match_distance_m,
                     np.asarray(fc.positions).max(axis=0) + params.match_distance_m)
                 for f, fc in clouds.items()}
        return cls(lam=lam, bound=math.sqrt(2.0) * params.match_distance_m, trees=trees,
                   boxes=boxes)


def crossing_groups(fingers: Sequence[str], clouds: Mapping[str, FingerCloud]) -> CrossingGroups:
    """finger → (group id, order coordinate, group axis): see the module docstring."""
    means_n = {f: np.asarray(clouds[f].normals).mean(axis=0) for f in fingers}
    means_p = {f: np.asarray(clouds[f].positions).mean(axis=0) for f in fingers}
    ref = means_n[fingers[0]]
    out: CrossingGroups = {}
    for gid in (0, 1):
        members = [f for f in fingers if (float(means_n[f] @ ref) > 0) == (gid == 0)]
        if not members:
            continue
        if len(members) == 1:
            out[members[0]] = (gid, 0.0, np.array([1.0, 0, 0]))
            continue
        mp = np.stack([means_p[f] for f in members])
        _, _, vt = np.linalg.svd(mp - mp.mean(axis=0))
        axis = vt[0]
        for f, m in zip(members, mp, strict=True):
            out[f] = (gid, float(m @ axis), axis)
    return out


def eq2_removed(x: np.ndarray, n: np.ndarray, con_pos: np.ndarray, con_nrm: np.ndarray,
                w_tip_m: float) -> np.ndarray:
    """Paper eq. 2, per row: object points ``x`` (B,3) with normals ``n`` (B,3) taken out by an
    earlier contact at ``con_pos`` with object normal ``con_nrm`` (B,3): within
    ``±w_tip·|n_x|/√(n_x² + n_z²)`` of it along the palm x axis and ``⟨n, n_con⟩ > 0``."""
    hw = w_tip_m * np.abs(con_nrm[:, 0]) / np.maximum(np.hypot(con_nrm[:, 0], con_nrm[:, 2]),
                                                      1e-12)
    return (np.abs(x[:, 0] - con_pos[:, 0]) <= hw) & (np.einsum("ij,ij->i", n, con_nrm) > 0)


def keeps_order(ws_pos: np.ndarray, con_pos: np.ndarray, axis: np.ndarray, order_f: float,
                order_g: float) -> np.ndarray:
    """The crossing rule, per row: finger f's face centre ``ws_pos`` (B,3) lies on the side of
    the earlier contact ``con_pos`` (B,3) of finger g (same group) that their clouds' order
    coordinates along the group ``axis`` say."""
    side = (ws_pos - con_pos) @ axis
    return np.sign(side) == np.sign(order_f - order_g)


def match_fingers(rng: np.random.Generator, fingers: Sequence[str], first: str,
                  cands: Candidates, part_idx: np.ndarray, normals: np.ndarray,
                  clouds: Mapping[str, FingerCloud], index: FingerIndex, params: FsgParams,
                  stats: dict[str, int]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Steps 3–4 on the candidates of one batch (one permutation draw per further finger).

    Args:
        first: the finger of step 1 (its contact comes with ``cands``).
        part_idx: indices of ``cloud_part``; normals: (N,3) ``cloud_full`` normals, object frame.
        stats: counts updated in place ("no_match", "pairs_<finger>", "usable_<finger>").

    Returns:
        (indices of the candidates with a usable pair for every finger, finger → (C,) chosen
        workspace point index per candidate, −1 where none).
    """
    p = params
    c_all = len(cands.rot)
    chosen: dict[str, np.ndarray] = {first: cands.first_ws}
    con_pos: dict[str, np.ndarray] = {first: cands.first_pos}
    con_nrm: dict[str, np.ndarray] = {first: cands.first_nrm}   # object normal at contact
    alive = np.ones(c_all, dtype=bool)
    groups = crossing_groups(fingers, clouds)
    part_full = cands.full[:, part_idx]
    part_nrm = np.matmul(normals[part_idx][None], cands.rot.transpose(0, 2, 1))
    n_part = len(part_idx)
    for f in fingers:
        if f == first:
            continue
        a_idx = np.flatnonzero(alive)
        if not len(a_idx):
            break
        fc = clouds[f]
        q_pts = (part_full if len(a_idx) == c_all else part_full[a_idx]).reshape(-1, 3)
        lo, hi = index.boxes[f]
        in_box = (q_pts >= lo) & (q_pts <= hi)
        near = np.flatnonzero(in_box[:, 0] & in_box[:, 1] & in_box[:, 2])
        q_nrm = part_nrm.reshape(-1, 3)[a_idx[near // n_part] * n_part + near % n_part]
        q6 = np.hstack([q_pts[near], -index.lam * q_nrm])
        dist, idx = index.trees[f].query(q6, k=p.k_neighbours, distance_upper_bound=index.bound)
        flat, kk = np.nonzero(np.isfinite(dist))
        wk = idx[flat, kk]
        flat = near[flat]
        cand = a_idx[flat // n_part]
        jj = flat % n_part
        close = np.linalg.norm(q_pts[flat] - np.asarray(fc.positions)[wk], axis=1)
        sel = close < p.match_distance_m
        flat, wk, cand, jj = flat[sel], wk[sel], cand[sel], jj[sel]
        n_obj = part_nrm[cand, jj]
        x_obj = part_full[cand, jj]
        good = np.einsum("ij,ij->i", n_obj, np.asarray(fc.normals)[wk]) < p.normal_dot
        stats[f"pairs_{f}"] = stats.get(f"pairs_{f}", 0) + int(good.sum())
        for g, gpos in con_pos.items():   # eq. 2 removal and crossing vs earlier fingers
            gp, gn = gpos[cand], con_nrm[g][cand]
            good &= ~eq2_removed(x_obj, n_obj, gp, gn, p.fingertip_width_m)
            gid_f, ord_f, ax = groups[f]
            gid_g, ord_g, _ = groups[g]
            if gid_f == gid_g and ord_f != ord_g:
                good &= keeps_order(np.asarray(fc.positions)[wk], gp, ax, ord_f, ord_g)
        stats[f"usable_{f}"] = stats.get(f"usable_{f}", 0) + int(good.sum())
        cand, jj, wk, x_obj, n_obj = cand[good], jj[good], wk[good], x_obj[good], n_obj[good]
        order = rng.permutation(len(cand))
        cand_o = cand[order]
        uniq, first_i = np.unique(cand_o, return_index=True)
        pick = order[first_i]
        alive_new = np.zeros(c_all, dtype=bool)
        alive_new[uniq] = True
        stats["no_match"] += int((alive & ~alive_new).sum())
        alive &= alive_new
        ch = np.full(c_all, -1)
        ch[uniq] = wk[pick]
        cp = np.zeros((c_all, 3))
        cp[uniq] = x_obj[pick]
        cn = np.zeros((c_all, 3))
        cn[uniq] = n_obj[pick]
        chosen[f], con_pos[f], con_nrm[f] = ch, cp, cn
    return np.flatnonzero(alive), chosen
