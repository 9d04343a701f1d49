"""FSG steps 1–2: palm pose candidates and the palm checks (palm box, table).

Step 1 pairs a random point of ``cloud_part`` with a random point of the smallest active
workspace cloud (moved to a uniform random point of its contact face), aligns them (positions
coincide, normals opposed) and rotates the object about that normal by ``2πi/inner``; step 2
drops the candidates that put more than ``max_palm_points`` object points in the palm box and,
in table mode, those whose palm box vertices (and, once the fingers are matched, contact-face
rims: :func:`contact_faces_below_table`, and every finger's link skeleton:
:func:`links_below_table`) come closer than ``table_clearance_m`` to the table (the paper's
horizontal plane through the object's lowest point, or the plane the object really rests on).
All arrays are batched over candidates: rotations (C,3,3) and translations (C,3) take object
coordinates into ``frame_palm`` (metres).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from augment.fsg.params import FsgParams
from augment.fsg.table import TablePlane
from sim.transforms import axis_angle_to_mat, perpendicular_basis, rotation_between

if TYPE_CHECKING:
    from augment.autows.cloud import FingerCloud

__all__ = ["Candidates", "contact_faces_below_table", "first_finger", "links_below_table",
           "palm_box_vertices", "palm_candidates"]


@dataclass(frozen=True)
class Candidates:
    """Palm pose candidates that passed step 2 (C of them).

    Attributes:
        rot, trans: (C,3,3), (C,3) the rigid transforms object → ``frame_palm``.
        full: (C,N,3) ``cloud_full`` in ``frame_palm`` under each transform.
        first_ws: (C,) the first finger's workspace point index.
        first_pos: (C,3) the first contact (the sampled face point), ``frame_palm``.
        first_nrm: (C,3) the object's outward normal there (= −the face normal), ``frame_palm``.
    """

    rot: np.ndarray
    trans: np.ndarray
    full: np.ndarray
    first_ws: np.ndarray
    first_pos: np.ndarray
    first_nrm: np.ndarray


def first_finger(fingers: Sequence[str], clouds: Mapping[str, FingerCloud]) -> str:
    """The finger whose workspace cloud is sampled in step 1: the smallest active one (the
    earlier finger on a tie)."""
    return min(fingers, key=lambda f: (clouds[f].n_points, fingers.index(f)))


def palm_box_vertices(centre: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(8,3) corners of the axis-aligned box ``centre ± half`` (``frame_palm``, metres)."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    return centre + signs * half


def palm_candidates(rng: np.random.Generator, points: np.ndarray, normals: np.ndarray,
                    part_idx: np.ndarray, fc0: FingerCloud, n_outer: int, *,
                    palm_center: np.ndarray, palm_half: np.ndarray, table: TablePlane | None,
                    params: FsgParams, stats: dict[str, int]) -> Candidates | None:
    """Steps 1 and 2 for ``n_outer`` outer iterations (``n_outer × inner`` candidates).

    Args:
        rng: the worker's generator (5 draws, in a fixed order).
        points, normals: (N,3) ``cloud_full`` and its outward normals, object frame.
        part_idx: indices of ``cloud_part`` into ``points``.
        fc0: the first finger's workspace cloud (:func:`first_finger`).
        palm_center, palm_half: the palm box in ``frame_palm``.
        table: the table plane (object frame) in table mode, else ``None``.
        stats: counts updated in place ("candidates"; "table": below the table, of all;
            "palm": too many object points in the palm box, of those above the table).

    Returns:
        The surviving candidates, or ``None`` when none survives.
    """
    p = params
    j0 = rng.choice(part_idx, n_outer)
    k0 = rng.integers(0, fc0.n_points, n_outer)
    fpos, fnrm = np.asarray(fc0.positions)[k0], np.asarray(fc0.normals)[k0]
    radius = np.asarray(fc0.radius)[k0]
    half = np.asarray(fc0.half_edges)[k0]
    # a uniform point of the contact face: circle (radius) or rectangle (half-edge vectors)
    e1, e2 = perpendicular_basis(fnrm)
    rr = np.nan_to_num(radius) * np.sqrt(rng.random(n_outer))
    th = rng.random(n_outer) * 2 * np.pi
    circ = rr[:, None] * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
    u = rng.uniform(-1, 1, (n_outer, 2))
    rect = np.nan_to_num(u[:, :1] * half[:, 0] + u[:, 1:] * half[:, 1])
    offset = np.where(np.isfinite(radius)[:, None], circ, rect)
    fpos = fpos + offset
    # align the pair, then the inner loop about the face normal
    r0 = rotation_between(normals[j0], -fnrm)
    angles = 2 * np.pi * np.arange(p.inner) / p.inner
    axis = np.repeat(fnrm, p.inner, axis=0)
    rot = axis_angle_to_mat(axis, np.tile(angles, n_outer)) @ np.repeat(r0, p.inner, axis=0)
    po = np.repeat(points[j0], p.inner, axis=0)
    pc = np.repeat(fpos, p.inner, axis=0)
    trans = pc - np.einsum("cij,cj->ci", rot, po)
    outer_id = np.repeat(np.arange(n_outer), p.inner)
    stats["candidates"] += len(rot)
    # step 2: the table (eight vertices a candidate) first, then the palm box over the whole cloud
    # for the candidates left: the same verdicts in either order, the cloud's transform is most of
    # the work and a table rejects about half of the candidates
    keep = np.arange(len(rot))
    if table is not None:
        verts = palm_box_vertices(palm_center, palm_half)     # palm frame
        v_obj = np.einsum("cji,cvj->cvi", rot, verts[None] - trans[:, None])
        low = table.elevation_m(v_obj).min(axis=1) < p.table_clearance_m
        stats["table"] += int(low.sum())
        keep = np.flatnonzero(~low)
    full = np.matmul(points[None], rot[keep].transpose(0, 2, 1))
    full += trans[keep, None]
    off = np.abs(full - palm_center)
    inside = ((off[..., 0] <= palm_half[0]) & (off[..., 1] <= palm_half[1])
              & (off[..., 2] <= palm_half[2])).sum(1)
    ok = inside <= p.max_palm_points
    stats["palm"] += int((~ok).sum())
    keep, full = keep[ok], full[ok]
    if not len(keep):
        return None
    outer_id = outer_id[keep]
    return Candidates(rot=rot[keep], trans=trans[keep], full=full, first_ws=k0[outer_id],
                      first_pos=pc[keep], first_nrm=-fnrm[outer_id])


def contact_faces_below_table(faces: Sequence[tuple[FingerCloud, int]], rot: np.ndarray,
                              trans: np.ndarray, table: TablePlane, clearance_m: float) -> bool:
    """Step 2 once the fingers are matched (paper: contact-face vertices closer than the
    clearance to the table). ``faces``: (finger cloud, workspace index) per used finger;
    ``rot``, ``trans``: one candidate's transform object → palm. The face rim's lowest point is
    the centre's height minus the face radius (or half-diagonal) times the in-plane extent
    along the vertical."""
    up_palm = rot @ table.up             # the table's normal expressed in the palm frame
    for fc, k in faces:
        centre_obj = rot.T @ (np.asarray(fc.positions[k]) - trans)
        n = np.asarray(fc.normals[k])
        tilt = math.sqrt(max(0.0, 1.0 - float(n @ up_palm) ** 2))
        size = (float(fc.radius[k]) if np.isfinite(fc.radius[k])
                else float(np.linalg.norm(np.asarray(fc.half_edges[k]).sum(axis=0))))
        if float(table.elevation_m(centre_obj)) - size * tilt < clearance_m:
            return True
    return False


def links_below_table(skeletons: Sequence[np.ndarray], rot: np.ndarray, trans: np.ndarray,
                      table: TablePlane, clearance_m: float) -> bool:
    """Beyond the paper, whose table check stops at the palm box and the contact faces: a
    finger link lying in the table makes the grasp impossible on a real table just the same
    (measured on a can lying on its side: a third of table-mode grasps put a phalanx or an idle
    straight finger into the table). ``skeletons``: (K,3) link skeleton points in
    ``frame_palm`` per finger, used fingers at the grasp and idle ones at their rest joints;
    ``clearance_m``: the link radius plus the table clearance. ``rot``, ``trans``: one
    candidate's transform object → palm."""
    pts = np.concatenate([np.asarray(sk, float).reshape(-1, 3) for sk in skeletons])
    return bool(table.elevation_m((pts - trans) @ rot).min(initial=np.inf) < clearance_m)
