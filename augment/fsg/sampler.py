"""FSG: fingertip-contact-aware sampling-based grasp generation (paper section 4; DESIGN §4).

Inputs are an :class:`~augment.object_cloud.ObjectCloud` (``cloud_full`` and ``cloud_part``,
object frame) and an AutoWS :class:`~augment.autows.workspace.WorkspaceCloud` (per finger, fingertip
contact-face centres in ``frame_palm`` with the joint angles that put them there). No inverse
kinematics is ever computed and, up to the last check of step 6, no mesh collision: everything
is point-cloud arithmetic, vectorised over batches of palm pose candidates.

One batch (:meth:`_Sampler.batch`):

1. **Palm pose candidates.** ``outer_batch`` times: a random point of ``cloud_part`` and a random
   point of the *smallest* active workspace cloud, moved to a uniformly random point of that
   point's contact face (circle or rectangle). The object is placed so that both points coincide
   and the normals are opposed (object outward normal = −fingertip normal), then rotated about
   that normal by ``2πi/inner`` (i = 0..inner−1) → ``outer_batch × inner`` rigid transforms
   object → palm.
2. **Palm checks.** Candidates with more than ``max_palm_points`` (3) points of ``cloud_full``
   inside the palm box (hand config, ``frame_palm``) are dropped; with ``table=True`` also those
   whose palm box vertices come closer than ``table_clearance_m`` to the table (and, once the
   fingers are matched, those whose contact-face rims do). The table is the
   horizontal plane through the object's lowest surface point: dexaug objects are z-up in their
   frame (MuJoCo), where the paper's objects are y-up; the rule is the same.
3. **Other fingers** in priority order, one ``cKDTree.query`` per finger per batch (all
   candidates' transformed ``cloud_part`` points at once, after dropping those outside the
   finger cloud's bounding box grown by 8 mm). The trees are 6-D, over (position,
   λ·normal) with λ = ``match_distance_m`` / √(2(1 + ``normal_dot``)), queried with
   (p_obj, −λ·n_obj): the ``k_neighbours`` nearest are then close in position *and* opposed in
   normal, where a 3-D query's nearest neighbours often all face the wrong way; the paper's
   thresholds are applied exactly afterwards (distance < ``match_distance_m`` = 8 mm). A pair
   is usable when the normals are opposed (``⟨n_obj, n_fin⟩ < −0.98``), the object point was
   not removed by an earlier finger (paper eq. 2: within ``±w_tip·|n_x|/√(n_x²+n_z²)`` along
   the palm x axis of an earlier contact and with ``⟨n, n_con⟩ > 0``), and it does not cross
   an earlier finger of its group (below). One usable pair is picked at random per candidate;
   candidates without one are dropped.
4. **Finger crossing.** Active clouds are split in two groups by the sign of their mean normal
   against the first finger's (thumb vs. the others). Within a group the clouds are ordered by
   their mean position along the group's spread axis (the principal direction of the clouds'
   mean positions: the paper says "the y axis" of its palm frame, which is the axis across the
   fingers there; in dexaug's frame_palm, +y is the palm normal, so the axis is taken from the
   data), and contacts must keep that order.
5. **Contacts.** Each finger's contact face is rebuilt at its workspace point (centre, normal,
   radius or half-edges, all stored in the cloud); the points of ``cloud_full`` whose projection
   lies in the face, within ``contact_plane_m`` (5 mm) of its plane and facing it
   (``⟨n_obj, n_face⟩ < 0``) are the contacts, at most ``max_contacts_per_finger`` per finger
   (nearest the plane first; a cap on the Qhull cost). Every used finger needs ≥ 1 contact
   (a finger that claims to grasp must touch) and the grasp ≥ ``min_contacts`` (3). Beyond the
   paper: object points in the footprint deeper than ``max_face_depth_m`` behind the face plane
   mean the fingertip is buried in the object, which the MuJoCo validator rejects as penetration;
   such candidates are dropped here.
6. **Link penetration** (optional, paper eq. 3): each used finger's link skeleton (stored per
   workspace point) is moved into the object frame; for consecutive skeleton points p_n, p_n+1
   with nearest ``cloud_full`` points q_n, q_n+1 and q_n's normal nor_n,
   ``[(p_n − q_n)·nor_n]·[(p_n+1 − q_n+1)·nor_n] < 0`` is a penetration. Beyond the paper: a
   skeleton point closer than ``link_clearance_m`` (8 mm, about a Shadow link's radius) to the
   nearest object point also counts: eq. 3 only sees the skeleton *cross* the surface, while
   links lie at their radius around the skeleton, so a link can sink into a convex object
   without its axis crossing it (the validator then rejects the grasp as penetration).
   Both are point-cloud approximations of the hand's link volumes, so a grasp that passes
   them and every other check is finally placed in the validator's MuJoCo scene (one collision
   pass, no simulation) and dropped when the hand penetrates the object deeper than the
   validator allows (``max_penetration_m`` of ``configs/validate.toml``): the only mesh
   collision FSG computes, once per output grasp, so no output fails validation for a
   penetration the simulator sees (the point-cloud checks let through 1 of 163 accepted grasps
   on 005 and 5 of 134 on 043 in one measured run; without them 11 % and 30 % of outputs fail so).
7. **Quality.** Q1 (ε) and volume via :func:`sim.metrics.gws.gws_metrics` (μ = 0.5, 8 edges, centre =
   centre of mass, torque / max radius) on the contacts with inward normals; ε ≤ ``min_epsilon``
   (default 0: no force closure) is dropped.
8. **De-duplication** against the accepted grasps: palm within 5 mm, ``|q·q'| > 1 − 5e-3`` and
   every joint within 0.1 rad.

Finger iteration: a round is ``outer`` (200) outer iterations; when a round yields fewer than
``min_valid`` (10) grasps with the current fingers, the least important finger is dropped (down to
``min_fingers``, 2), and generation goes on within the same call until ``n`` grasps or the time
budget. Unused finger joints (and all non-finger joints, e.g. the wrist) are 0.

Parallelism: ``workers`` processes, worker k seeded with ``seed + k`` and asked for its share of
``n``; results are merged in worker order and de-duplicated again, so the output is deterministic
for a seed and worker count unless the time budget cuts a run short. The worker processes
are kept between calls (:func:`sim.pools.persistent_pool`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial import cKDTree

from sim.config import load_toml
from sim.errors import ConfigError, DexaugError
from sim.grasp import Grasp
from sim.metrics.gws import gws_metrics
from sim.paths import CONFIG_DIR
from sim.pools import persistent_pool
from sim.transforms import mat_to_quat

if TYPE_CHECKING:
    from augment.autows.workspace import WorkspaceCloud
    from augment.object_cloud import ObjectCloud
    from sim.hand.model import Hand
    from sim.world.objects import ObjectAsset

__all__ = ["FsgError", "FsgGrasp", "FsgParams", "FsgResult", "generate", "load_fsg_params"]

log = logging.getLogger(__name__)

AUGMENT_TOML = CONFIG_DIR / "augment.toml"

#: The exact penetration check FSG is given (step 6): ``True`` when the grasp, placed in the
#: validator's MuJoCo scene, penetrates the object deeper than the validator allows. Injected
#: (a picklable callable, e.g. :class:`sim.validate.batch.ScenePenetration`) so that the
#: sampler never imports the physics validator.
PenetrationCheck = Callable[[Grasp], bool]


class FsgError(DexaugError, ValueError):
    """FSG cannot run on these inputs (a workspace cloud of another hand, bad options)."""


@dataclass(frozen=True)
class FsgParams:
    """FSG parameters (``[fsg]`` of ``configs/augment.toml``); metres and radians.

    The defaults are the paper's / the authors' numbers where they exist (DESIGN §4); the
    others are marked "dexaug" in the config file.
    """

    outer: int = 200
    inner: int = 15
    outer_batch: int = 40
    max_palm_points: int = 3
    table_clearance_m: float = 0.005
    match_distance_m: float = 0.008
    normal_dot: float = -0.98
    k_neighbours: int = 4
    fingertip_width_m: float = 0.02
    contact_plane_m: float = 0.005
    min_contacts: int = 3
    max_contacts_per_finger: int = 4
    max_face_depth_m: float = 0.003
    link_clearance_m: float = 0.008
    mu: float = 0.5
    n_edges: int = 8
    min_epsilon: float = 0.0
    min_valid: int = 10
    min_fingers: int = 2
    dedup_pos_m: float = 0.005
    dedup_quat: float = 5e-3
    dedup_joint_rad: float = 0.1

    def __post_init__(self) -> None:
        for name in ("outer", "inner", "outer_batch", "k_neighbours", "min_contacts",
                     "max_contacts_per_finger", "n_edges", "min_fingers"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        for name in ("match_distance_m", "fingertip_width_m", "contact_plane_m", "mu"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v}")


def load_fsg_params(path: Path | str | None = None) -> FsgParams:
    """Read ``[fsg]`` of ``configs/augment.toml`` (or ``path``); missing keys (or a missing
    table) take the defaults of :class:`FsgParams`. Errors name the file and key."""
    root = load_toml(path or AUGMENT_TOML)
    sec = root.section("fsg", {})
    fields = {f.name: f for f in dataclasses.fields(FsgParams)}
    sec.reject_unknown(set(fields))
    d = FsgParams()
    kw: dict[str, Any] = {}
    for name in fields:
        default = getattr(d, name)
        kw[name] = (sec.int(name, default) if isinstance(default, int)
                    else sec.float(name, default))
    try:
        return FsgParams(**kw)
    except ValueError as exc:
        raise ConfigError(f"{sec.where()}: {exc}") from None


@dataclass(frozen=True, eq=False)
class FsgGrasp:
    """One generated grasp.

    Attributes:
        grasp: palm pose (frame_palm in the object frame, metres, wxyz) and full joint vector.
        fingers: fingers used, priority order.
        contact_points: (M,3) contacts on the object, object frame, metres.
        contact_normals: (M,3) the object's OUTWARD unit normals there (the GWS uses their
            negatives, the force directions).
        contact_finger: (M,) index into ``fingers`` of the finger touching each contact.
        ws_index: per used finger, the index of its workspace cloud point.
        face_index: per used finger, which contact face of the fingertip (into the finger
            cloud's ``tip_*`` arrays).
        epsilon, volume: GWS Q1 and hull volume of the contacts.
        worker: worker that generated it.
    """

    grasp: Grasp
    fingers: tuple[str, ...]
    contact_points: np.ndarray
    contact_normals: np.ndarray
    contact_finger: np.ndarray
    ws_index: tuple[int, ...]
    face_index: tuple[int, ...]
    epsilon: float
    volume: float
    worker: int = 0


@dataclass
class FsgResult:
    """Grasps (sorted by ε, best first) plus what happened: ``requested`` vs ``len(grasps)``
    (``shortfall``), ``stopped`` ("done", "time budget"), wall time, and counts summed over
    workers: candidates and where they were rejected (palm, table, no_match, contacts, depth,
    link, epsilon, duplicate), accepted, and per finger the k-d tree pairs with opposed normals
    (``pairs_<finger>``) and those left after eq. 2 and the crossing rule (``usable_<finger>``).
    ``finger_sets`` lists the finger sets finger iteration went through."""

    grasps: list[FsgGrasp]
    requested: int
    stopped: str
    elapsed_s: float
    stats: dict[str, int] = field(default_factory=dict)
    finger_sets: list[tuple[str, ...]] = field(default_factory=list)

    @property
    def shortfall(self) -> int:
        return max(self.requested - len(self.grasps), 0)


# ---------------------------------------------------------------------------------------------
# geometry helpers


def _align(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(B,3,3) rotations taking unit vectors a (B,3) onto unit vectors b (B,3)."""
    v = np.cross(a, b)
    c = np.einsum("ij,ij->i", a, b)
    vx = np.zeros((len(a), 3, 3))
    vx[:, 0, 1], vx[:, 0, 2] = -v[:, 2], v[:, 1]
    vx[:, 1, 0], vx[:, 1, 2] = v[:, 2], -v[:, 0]
    vx[:, 2, 0], vx[:, 2, 1] = -v[:, 1], v[:, 0]
    anti = c < -1 + 1e-9
    k = np.where(anti, 0.0, 1.0 / np.maximum(1.0 + c, 1e-12))
    r = np.eye(3) + vx + vx @ vx * k[:, None, None]
    if anti.any():  # a = −b: half turn about any axis perpendicular to a
        aa = a[anti]
        helper = np.where(np.abs(aa[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        ax = np.cross(aa, helper)
        ax /= np.linalg.norm(ax, axis=1, keepdims=True)
        r[anti] = 2 * ax[:, :, None] * ax[:, None, :] - np.eye(3)
    return r


def _axis_rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(B,3,3) rotations by ``angle`` (B,) radians about unit ``axis`` (B,3) (Rodrigues)."""
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    kx = np.zeros((len(axis), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2] = -axis[:, 2], axis[:, 1]
    kx[:, 1, 0], kx[:, 1, 2] = axis[:, 2], -axis[:, 0]
    kx[:, 2, 0], kx[:, 2, 1] = -axis[:, 1], axis[:, 0]
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


def _perp_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(n, e1)


def _box_vertices(centre: np.ndarray, half: np.ndarray) -> np.ndarray:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    return centre + signs * half


# ---------------------------------------------------------------------------------------------
# the sampler (one process)


@dataclass(frozen=True)
class _Setup:
    """Everything a worker needs, as plain picklable data (no MuJoCo objects)."""

    hand: str
    cloud: ObjectCloud
    workspace: WorkspaceCloud
    part_idx: np.ndarray
    fingers: tuple[str, ...]         # active fingers at the start, priority order
    nq: int
    finger_qadr: dict[str, np.ndarray]
    palm_center: np.ndarray
    palm_half: np.ndarray
    table: bool
    finger_iteration: bool
    link_penetration: bool           # the paper's eq. 3 on the link skeletons
    exact_penetration: PenetrationCheck | None
    params: FsgParams


class _Sampler:
    def __init__(self, setup: _Setup, seed: int, worker: int = 0) -> None:
        self.s = setup
        self.p = setup.params
        self.rng = np.random.default_rng(seed)
        self.worker = worker
        c = setup.cloud
        self.pts, self.nrm = np.asarray(c.points), np.asarray(c.normals)
        self.part = setup.part_idx
        self.obj_tree = cKDTree(self.pts)
        self.fc = {f: setup.workspace.finger(f) for f in setup.fingers}
        # 6-D trees over (position, lam·normal): one query finds pairs close in position AND
        # opposed in normal (the query uses −lam·n_obj); lam makes the normal tolerance
        # (chord √(2(1+normal_dot)) ≈ 0.2 for −0.98) weigh like the distance tolerance.
        chord = math.sqrt(max(2.0 * (1.0 + self.p.normal_dot), 1e-6))
        self.lam = self.p.match_distance_m / chord
        self.bound = math.sqrt(2.0) * self.p.match_distance_m
        self.trees = {f: cKDTree(np.hstack([np.asarray(self.fc[f].positions),
                                            self.lam * np.asarray(self.fc[f].normals)]))
                      for f in setup.fingers}
        self.boxes = {f: (np.asarray(self.fc[f].positions).min(axis=0) - self.p.match_distance_m,
                          np.asarray(self.fc[f].positions).max(axis=0) + self.p.match_distance_m)
                      for f in setup.fingers}
        self.stats: dict[str, int] = {k: 0 for k in (
            "candidates", "palm", "table", "no_match", "contacts", "depth", "link", "epsilon",
            "duplicate", "penetration", "accepted")}
        self.accepted: list[FsgGrasp] = []
        self._acc_pos = np.zeros((0, 3))
        self._acc_quat = np.zeros((0, 4))
        self._acc_q = np.zeros((0, setup.nq))

    # -- grouping for the finger-crossing rule
    def _groups(self, fingers: tuple[str, ...]) -> dict[str, tuple[int, float, np.ndarray]]:
        """finger → (group id, order coordinate, group axis)."""
        means_n = {f: np.asarray(self.fc[f].normals).mean(axis=0) for f in fingers}
        means_p = {f: np.asarray(self.fc[f].positions).mean(axis=0) for f in fingers}
        ref = means_n[fingers[0]]
        out: dict[str, tuple[int, float, np.ndarray]] = {}
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

    def run(self, n: int, deadline: float) -> tuple[str, list[tuple[str, ...]]]:
        fingers = self.s.fingers
        sets = [fingers]
        p = self.p
        while True:
            round_start = len(self.accepted)
            done_outer = 0
            while done_outer < p.outer:
                if len(self.accepted) >= n:
                    return "done", sets
                if time.monotonic() > deadline:
                    return "time budget", sets
                b = min(p.outer_batch, p.outer - done_outer)
                self.batch(fingers, b)
                done_outer += b
            if len(self.accepted) >= n:
                return "done", sets
            if (self.s.finger_iteration and len(self.accepted) - round_start < p.min_valid
                    and len(fingers) > p.min_fingers):
                fingers = fingers[:-1]
                sets.append(fingers)
                log.info("worker %d: %d grasps in a round; dropping finger, now %s", self.worker,
                         len(self.accepted) - round_start, ", ".join(fingers))

    def batch(self, fingers: tuple[str, ...], n_outer: int) -> None:
        p, rng = self.p, self.rng
        first = min(fingers, key=lambda f: (self.fc[f].n_points, fingers.index(f)))
        fc0 = self.fc[first]
        # 1. contact pairs: object point (object frame) and fingertip point (palm frame)
        j0 = rng.choice(self.part, n_outer)
        k0 = rng.integers(0, fc0.n_points, n_outer)
        fpos, fnrm = np.asarray(fc0.positions)[k0], np.asarray(fc0.normals)[k0]
        radius = np.asarray(fc0.radius)[k0]
        half = np.asarray(fc0.half_edges)[k0]
        e1, e2 = _perp_basis(fnrm)
        rr = np.nan_to_num(radius) * np.sqrt(rng.random(n_outer))
        th = rng.random(n_outer) * 2 * np.pi
        circ = rr[:, None] * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
        u = rng.uniform(-1, 1, (n_outer, 2))
        rect = np.nan_to_num(u[:, :1] * half[:, 0] + u[:, 1:] * half[:, 1])
        offset = np.where(np.isfinite(radius)[:, None], circ, rect)
        fpos = fpos + offset
        r0 = _align(self.nrm[j0], -fnrm)
        angles = 2 * np.pi * np.arange(p.inner) / p.inner
        axis = np.repeat(fnrm, p.inner, axis=0)
        rot = _axis_rot(axis, np.tile(angles, n_outer)) @ np.repeat(r0, p.inner, axis=0)
        po = np.repeat(self.pts[j0], p.inner, axis=0)
        pc = np.repeat(fpos, p.inner, axis=0)
        trans = pc - np.einsum("cij,cj->ci", rot, po)
        outer_id = np.repeat(np.arange(n_outer), p.inner)
        self.stats["candidates"] += len(rot)
        # 2. palm box (and table)
        full = np.matmul(self.pts[None], rot.transpose(0, 2, 1)) + trans[:, None]
        inside = np.all(np.abs(full - self.s.palm_center) <= self.s.palm_half, axis=2).sum(1)
        ok = inside <= p.max_palm_points
        self.stats["palm"] += int((~ok).sum())
        if self.s.table:
            verts = _box_vertices(self.s.palm_center, self.s.palm_half)     # palm frame
            v_obj = np.einsum("cji,cvj->cvi", rot, verts[None] - trans[:, None])
            low = v_obj[..., 2].min(axis=1) < self.s.cloud.z_min_m + p.table_clearance_m
            self.stats["table"] += int((ok & low).sum())
            ok &= ~low
        keep = np.flatnonzero(ok)
        rot, trans, outer_id, full = rot[keep], trans[keep], outer_id[keep], full[keep]
        if not len(keep):
            return
        c_all = len(keep)
        # chosen per finger: ws index, contact position and normal (palm frame) of the obj point
        chosen: dict[str, np.ndarray] = {first: k0[outer_id]}
        con_pos: dict[str, np.ndarray] = {first: pc[keep]}
        con_nrm: dict[str, np.ndarray] = {first: -fnrm[outer_id]}   # object normal at contact
        alive = np.ones(c_all, dtype=bool)
        groups = self._groups(fingers)
        part_full = full[:, self.part]
        part_nrm = np.matmul(self.nrm[self.part][None], rot.transpose(0, 2, 1))
        for f in fingers:
            if f == first:
                continue
            a_idx = np.flatnonzero(alive)
            if not len(a_idx):
                break
            fc = self.fc[f]
            q_pts = part_full[a_idx].reshape(-1, 3)
            q_nrm = part_nrm[a_idx].reshape(-1, 3)
            lo, hi = self.boxes[f]
            near = np.flatnonzero(np.all((q_pts >= lo) & (q_pts <= hi), axis=1))
            q6 = np.hstack([q_pts[near], -self.lam * q_nrm[near]])
            dist, idx = self.trees[f].query(q6, k=p.k_neighbours,
                                            distance_upper_bound=self.bound)
            flat, kk = np.nonzero(np.isfinite(dist))
            wk = idx[flat, kk]
            flat = near[flat]
            cand = a_idx[flat // len(self.part)]
            jj = flat % len(self.part)
            close = np.linalg.norm(q_pts[flat] - np.asarray(fc.positions)[wk], axis=1)
            sel = close < p.match_distance_m
            flat, wk, cand, jj = flat[sel], wk[sel], cand[sel], jj[sel]
            n_obj = part_nrm[cand, jj]
            x_obj = part_full[cand, jj]
            good = np.einsum("ij,ij->i", n_obj, np.asarray(fc.normals)[wk]) < p.normal_dot
            self.stats[f"pairs_{f}"] = self.stats.get(f"pairs_{f}", 0) + int(good.sum())
            for g, gpos in con_pos.items():   # eq. 2 removal and crossing vs earlier fingers
                gp, gn = gpos[cand], con_nrm[g][cand]
                hw = p.fingertip_width_m * np.abs(gn[:, 0]) / np.maximum(
                    np.hypot(gn[:, 0], gn[:, 2]), 1e-12)
                removed = (np.abs(x_obj[:, 0] - gp[:, 0]) <= hw) & (
                    np.einsum("ij,ij->i", n_obj, gn) > 0)
                good &= ~removed
                gid_f, ord_f, ax = groups[f]
                gid_g, ord_g, _ = groups[g]
                if gid_f == gid_g and ord_f != ord_g:
                    side = (np.asarray(fc.positions)[wk] - gp) @ ax
                    good &= np.sign(side) == np.sign(ord_f - ord_g)
            self.stats[f"usable_{f}"] = self.stats.get(f"usable_{f}", 0) + int(good.sum())
            cand, jj, wk, x_obj, n_obj = cand[good], jj[good], wk[good], x_obj[good], n_obj[good]
            order = rng.permutation(len(cand))
            cand_o = cand[order]
            uniq, first_i = np.unique(cand_o, return_index=True)
            pick = order[first_i]
            alive_new = np.zeros(c_all, dtype=bool)
            alive_new[uniq] = True
            self.stats["no_match"] += int((alive & ~alive_new).sum())
            alive &= alive_new
            ch = np.full(c_all, -1)
            ch[uniq] = wk[pick]
            cp = np.zeros((c_all, 3))
            cp[uniq] = x_obj[pick]
            cn = np.zeros((c_all, 3))
            cn[uniq] = n_obj[pick]
            chosen[f], con_pos[f], con_nrm[f] = ch, cp, cn
        s_idx = np.flatnonzero(alive)
        if not len(s_idx):
            return
        self._finish(fingers, s_idx, rot, trans, full, chosen)

    def _finish(self, fingers: tuple[str, ...], s_idx: np.ndarray, rot: np.ndarray,
                trans: np.ndarray, full: np.ndarray, chosen: dict[str, np.ndarray]) -> None:
        p = self.p
        for c in s_idx:
            nfull_c = self.nrm @ rot[c].T
            contacts_i, finger_i = [], []
            ok = True
            for fi, f in enumerate(fingers):
                fc = self.fc[f]
                k = int(chosen[f][c])
                centre, n = np.asarray(fc.positions[k]), np.asarray(fc.normals[k])
                d = full[c] - centre
                h = d @ n
                inplane = d - h[:, None] * n
                if np.isfinite(fc.radius[k]):
                    inside = np.einsum("ij,ij->i", inplane, inplane) <= fc.radius[k] ** 2
                else:
                    he = np.asarray(fc.half_edges[k])
                    ln = np.linalg.norm(he, axis=1)
                    inside = np.all(np.abs(inplane @ (he / ln[:, None]).T) <= ln, axis=1)
                facing = nfull_c @ n < 0
                foot = inside & facing
                if np.any(foot & (h < -p.max_face_depth_m) & (h > -4 * p.contact_plane_m)):
                    self.stats["depth"] += 1
                    ok = False
                    break
                sel = np.flatnonzero(foot & (np.abs(h) <= p.contact_plane_m))
                if not len(sel):
                    self.stats["contacts"] += 1
                    ok = False
                    break
                sel = sel[np.argsort(np.abs(h[sel]), kind="stable")][:p.max_contacts_per_finger]
                contacts_i.append(sel)
                finger_i.append(np.full(len(sel), fi))
            if not ok:
                continue
            idx = np.concatenate(contacts_i)
            if len(idx) < p.min_contacts:
                self.stats["contacts"] += 1
                continue
            r, t = rot[c], trans[c]
            if self.s.table and self._below_table(fingers, chosen, c, r, t):
                self.stats["table"] += 1
                continue
            if self.s.link_penetration and self._penetrates(fingers, chosen, c, r, t):
                self.stats["link"] += 1
                continue
            cpts, cnrm = self.pts[idx], self.nrm[idx]
            m = gws_metrics(cpts, -cnrm, p.mu, p.n_edges, self.s.cloud.com_m,
                            torque_scale_m=self.s.cloud.max_radius_m)
            if not m.epsilon > p.min_epsilon:
                self.stats["epsilon"] += 1
                continue
            # palm pose in the object frame: inverse of object → palm
            palm_rot = r.T
            palm_pos = -palm_rot @ t
            quat = mat_to_quat(palm_rot)
            q = np.zeros(self.s.nq)
            for f in fingers:
                q[self.s.finger_qadr[f]] = self.fc[f].joints[int(chosen[f][c])]
            if self._duplicate(palm_pos, quat, q):
                self.stats["duplicate"] += 1
                continue
            grasp = Grasp(palm_pos, quat, q)
            if self.s.exact_penetration is not None and self.s.exact_penetration(grasp):
                self.stats["penetration"] += 1
                continue
            self._acc_pos = np.vstack([self._acc_pos, palm_pos])
            self._acc_quat = np.vstack([self._acc_quat, quat])
            self._acc_q = np.vstack([self._acc_q, q])
            self.stats["accepted"] += 1
            self.accepted.append(FsgGrasp(
                grasp=grasp, fingers=fingers, contact_points=cpts.copy(),
                contact_normals=cnrm.copy(), contact_finger=np.concatenate(finger_i),
                ws_index=tuple(int(chosen[f][c]) for f in fingers),
                face_index=tuple(int(self.fc[f].face_index[int(chosen[f][c])]) for f in fingers),
                epsilon=float(m.epsilon), volume=float(m.volume), worker=self.worker))

    def _below_table(self, fingers: tuple[str, ...], chosen: dict[str, np.ndarray], c: int,
                     r: np.ndarray, t: np.ndarray) -> bool:
        """Paper: contact-face vertices closer than the clearance to the table. The face rim's
        lowest point is the centre's height minus the face radius (or half-diagonal) times the
        in-plane extent along the vertical."""
        up_palm = r[:, 2]                  # object +z expressed in the palm frame
        floor = self.s.cloud.z_min_m + self.p.table_clearance_m
        for f in fingers:
            fc, k = self.fc[f], int(chosen[f][c])
            centre_obj = r.T @ (np.asarray(fc.positions[k]) - t)
            n = np.asarray(fc.normals[k])
            tilt = math.sqrt(max(0.0, 1.0 - float(n @ up_palm) ** 2))
            size = (float(fc.radius[k]) if np.isfinite(fc.radius[k])
                    else float(np.linalg.norm(np.asarray(fc.half_edges[k]).sum(axis=0))))
            if centre_obj[2] - size * tilt < floor:
                return True
        return False

    def _penetrates(self, fingers: tuple[str, ...], chosen: dict[str, np.ndarray], c: int,
                    r: np.ndarray, t: np.ndarray) -> bool:
        for f in fingers:
            sk = np.asarray(self.fc[f].skeleton[int(chosen[f][c])], dtype=float)   # palm frame
            sk_obj = (sk - t) @ r          # r.T applied to each row: palm → object frame
            dist, qi = self.obj_tree.query(sk_obj)
            if np.any(dist < self.p.link_clearance_m):
                return True
            qn = self.nrm[qi[:-1]]
            a = np.einsum("ij,ij->i", sk_obj[:-1] - self.pts[qi[:-1]], qn)
            b = np.einsum("ij,ij->i", sk_obj[1:] - self.pts[qi[1:]], qn)
            if np.any(a * b < 0):
                return True
        return False

    def _duplicate(self, pos: np.ndarray, quat: np.ndarray, q: np.ndarray) -> bool:
        if not len(self._acc_pos):
            return False
        p = self.p
        same = (np.linalg.norm(self._acc_pos - pos, axis=1) < p.dedup_pos_m) & (
            np.abs(self._acc_quat @ quat) > 1 - p.dedup_quat) & (
            np.abs(self._acc_q - q).max(axis=1) < p.dedup_joint_rad)
        return bool(same.any())


def _worker_run(setup: _Setup, seed: int, worker: int, n: int, budget_s: float,
                ) -> tuple[list[FsgGrasp], dict[str, int], str, list[tuple[str, ...]]]:
    sampler = _Sampler(setup, seed, worker)
    stopped, sets = sampler.run(n, time.monotonic() + budget_s)
    return sampler.accepted, sampler.stats, stopped, sets


# ---------------------------------------------------------------------------------------------
# public entry point


def generate(hand: Hand, obj: ObjectAsset | ObjectCloud, workspace: WorkspaceCloud, *,
             n: int = 10, fingers: int | None = None,
             finger_names: Sequence[str] | None = None, table: bool = False,
             use_affordance: bool = True, finger_iteration: bool = True,
             link_penetration: bool = False,
             exact_penetration: PenetrationCheck | None = None, seed: int = 0,
             time_budget_s: float = 60.0, workers: int = 1,
             params: FsgParams | None = None) -> FsgResult:
    """Generate up to ``n`` grasps of ``obj`` with ``hand`` from ``workspace`` (module docstring).

    Args:
        hand: the hand (for the joint vector layout and the palm box).
        obj: the object, or its prepared :class:`~augment.object_cloud.ObjectCloud`.
        workspace: AutoWS clouds of this hand.
        n: grasps wanted.
        fingers: use at most this many fingers (the most important ones); default all.
        finger_names: use only these fingers (kept in priority order): with a demonstration,
            the fingers that touched in it — the paper's augmented grasps "involve only those
            fingers", and the others' demo-centred clouds rarely reach the object.
        table: reject palms (and fingertips' faces) below the table plane.
        use_affordance: ``True`` samples ``cloud_part`` (affordance annotation, else the
            curvature filter; the paper's "+Aff"); ``False`` samples the whole ``cloud_full``
            (the paper's plain "FSG").
        finger_iteration: drop fingers when a round yields fewer than ``min_valid`` grasps.
        link_penetration: the paper's eq. 3 check of the link skeletons (module docstring,
            step 6).
        exact_penetration: the exact check in the validator's scene that ends step 6 (given by
            the caller; ``None``: the point-cloud checks only).
        seed: worker k uses ``seed + k``.
        time_budget_s: wall-clock limit; on expiry the grasps found so far are returned and the
            shortfall is logged (``FsgResult.stopped == "time budget"``).
        workers: processes (1: in this process).
        params: sampler parameters (default ``[fsg]`` of ``configs/augment.toml``).

    Raises:
        FsgError: a workspace cloud of another hand, or bad options.
    """
    from augment.object_cloud import ObjectCloud, object_cloud

    t0 = time.monotonic()
    params = params or load_fsg_params()
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
    palm = hand.config.palm
    setup = _Setup(hand=hand.name, cloud=cloud, workspace=workspace, part_idx=part_idx,
                   fingers=tuple(active),
                   nq=hand.nq, finger_qadr={f: np.asarray(hand.finger_qadr[f]) for f in active},
                   palm_center=np.asarray(palm.box_center, float),
                   palm_half=np.asarray(palm.box_half_extents, float), table=table,
                   finger_iteration=finger_iteration, link_penetration=link_penetration,
                   exact_penetration=exact_penetration,
                   params=dataclasses.replace(params, min_fingers=max(params.min_fingers, 2)))
    budget = time_budget_s - (time.monotonic() - t0)
    if workers == 1:
        outs = [_worker_run(setup, seed, 0, n, budget)]
    else:
        share = math.ceil(n / workers)
        pool = persistent_pool(workers, preload=(__name__,))
        futs = [pool.submit(_worker_run, setup, seed + k, k, share, budget)
                for k in range(workers)]
        outs = [f.result() for f in futs]
    merged = _Sampler.__new__(_Sampler)
    merged.p = setup.params
    merged._acc_pos, merged._acc_quat, merged._acc_q = (np.zeros((0, 3)), np.zeros((0, 4)),
                                                        np.zeros((0, hand.nq)))
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
            if not merged._duplicate(g.grasp.palm_pos, g.grasp.palm_quat_wxyz, g.grasp.joints):
                merged._acc_pos = np.vstack([merged._acc_pos, g.grasp.palm_pos])
                merged._acc_quat = np.vstack([merged._acc_quat, g.grasp.palm_quat_wxyz])
                merged._acc_q = np.vstack([merged._acc_q, g.grasp.joints])
                grasps.append(g)
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
