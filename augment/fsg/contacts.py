"""FSG step 5: the contacts of one candidate, on the contact faces rebuilt at the chosen
workspace points.

Each used finger's face (centre, normal, circle radius or rectangle half-edges, all stored in
its workspace cloud, ``frame_palm``) is rebuilt; the points of ``cloud_full`` whose projection
lies in the face, within ``contact_plane_m`` of its plane and facing it (``⟨n_obj, n_face⟩ <
0``) are that finger's contacts, at most ``max_contacts_per_finger`` of them (nearest the plane
first: a cap on the Qhull cost). Every used finger needs ≥ 1 contact (a finger that claims to
grasp must touch) and the grasp ≥ ``min_contacts``. Beyond the paper: object points in the
footprint deeper than ``max_face_depth_m`` behind the face plane (and less than
4 · ``contact_plane_m``) mean the fingertip is buried in the object, which the MuJoCo validator
rejects as penetration; such candidates are dropped here ("depth").
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from augment.fsg.params import FsgParams

if TYPE_CHECKING:
    from augment.autows.cloud import FingerCloud

__all__ = ["collect_contacts", "face_footprint"]


def face_footprint(points: np.ndarray, fc: FingerCloud, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Where ``points`` (N,3, ``frame_palm``) lie relative to the contact face of workspace
    point ``k`` of ``fc``: (N,) heights above the face plane along its normal (metres) and
    (N,) whether their projection falls inside the face (circle or rectangle)."""
    centre, n = np.asarray(fc.positions[k]), np.asarray(fc.normals[k])
    d = points - centre
    h = d @ n
    inplane = d - h[:, None] * n
    if np.isfinite(fc.radius[k]):
        inside = np.einsum("ij,ij->i", inplane, inplane) <= fc.radius[k] ** 2
    else:
        he = np.asarray(fc.half_edges[k])
        ln = np.linalg.norm(he, axis=1)
        inside = np.all(np.abs(inplane @ (he / ln[:, None]).T) <= ln, axis=1)
    return h, inside


def collect_contacts(faces: Sequence[tuple[FingerCloud, int]], points: np.ndarray,
                     normals: np.ndarray, params: FsgParams
                     ) -> tuple[str | None, np.ndarray, np.ndarray]:
    """Step 5 for one candidate.

    Args:
        faces: (finger cloud, chosen workspace index) per used finger, in finger order.
        points, normals: (N,3) ``cloud_full`` and its outward normals in ``frame_palm``.

    Returns:
        (rejection reason, contact indices into ``points``, index into ``faces`` of the finger
        of each contact); the reason is ``None`` for a usable candidate, else ``"depth"`` or
        ``"contacts"`` (and the arrays are then empty).
    """
    p = params
    contacts_i, finger_i = [], []
    for fi, (fc, k) in enumerate(faces):
        h, inside = face_footprint(points, fc, k)
        facing = normals @ np.asarray(fc.normals[k]) < 0
        foot = inside & facing
        if np.any(foot & (h < -p.max_face_depth_m) & (h > -4 * p.contact_plane_m)):
            return "depth", np.zeros(0, int), np.zeros(0, int)
        sel = np.flatnonzero(foot & (np.abs(h) <= p.contact_plane_m))
        if not len(sel):
            return "contacts", np.zeros(0, int), np.zeros(0, int)
        sel = sel[np.argsort(np.abs(h[sel]), kind="stable")][:p.max_contacts_per_finger]
        contacts_i.append(sel)
        finger_i.append(np.full(len(sel), fi))
    idx = np.concatenate(contacts_i)
    if len(idx) < p.min_contacts:
        return "contacts", np.zeros(0, int), np.zeros(0, int)
    return None, idx, np.concatenate(finger_i)
