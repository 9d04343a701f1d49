"""Building AutoWS fingertip workspace clouds (paper section 3.2; DESIGN §4): :func:`build_workspace`.

The cloud itself is described in :mod:`augment.autows.cloud`. How it is built:

* **Contact faces once per finger.** Faces live on the fingertip and do not depend on the joints:
  they are computed once in the tip body frame (:mod:`augment.autows.fingertip`; the query point is the
  demo's contact centroid on that fingertip, else the centroid of the pulp cloud), and carried
  into ``frame_palm`` by the tip body pose: ``p = t + R c``, ``n = R n_c``, half-edges ``R e``.
* **Joint grid** (:mod:`augment.autows.grids`): the manual ranges, or the demo angles ± a few
  steps; coupled followers follow their leaders. All combinations of a finger go through
  :meth:`sim.hand.model.Hand.tip_frames_in_palm` as one batch.
* **Mean-normal filter** (paper): with ``nor_ave`` the finger's mean normal, points whose normal
  y has the opposite sign are removed with a ``±normal_band`` (0.001) band: ``y < −band`` goes
  when ``nor_ave.y > 0``, else ``y > band`` goes. The rule only compares signs, so it reads the
  same in the paper's palm frame and in dexaug's (+y out of the palm face toward the object).
* **Skeletons.** For every kept point, points every ``skeleton_spacing_m`` (5 mm) along the
  finger's links from the first link's origin to the fingertip body origin
  (:meth:`sim.hand.model.Hand.skeleton` without its last segment: the paper's ``cloud_link`` excludes
  the fingertip, which touches the object by design). Stored as float32, (N, K, 3) per finger;
  the rest, along the fingertip link to the pulp, apart (``tip_skeleton``: a table's check).
* **Priority.** Fingers are kept in the hand config's order (thumb first).
* **Cache.** Clouds are cached on disk (:mod:`augment.autows.cache`); files are ``.npz`` written
  atomically.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from augment.autows.cache import cache_path, workspace_key
from augment.autows.cloud import FACE_KINDS, FingerCloud, WorkspaceCloud, summarise
from augment.autows.fingertip import FingertipFaces, hand_fingertip_faces
from augment.autows.grids import grid_joint_vectors, joint_grids
from augment.autows.params import AutoWSParams, WorkspaceError, load_autows_params
from augment.autows.seed import DemoSeed, check_demo
from sim.hand.model import Hand
from sim.transforms import quat_to_mat

__all__ = ["build_workspace"]

log = logging.getLogger(__name__)


def _finger_cloud(hand: Hand, index: int, tip: FingertipFaces, q: np.ndarray,
                  params: AutoWSParams) -> FingerCloud:
    cfg = hand.config.fingers[index]
    faces = tip.faces
    n_faces = len(faces)
    kind = np.array([FACE_KINDS.index(f.shape) for f in faces], dtype=np.uint8)
    t_centres = np.stack([f.centre for f in faces])
    t_normals = np.stack([f.normal for f in faces])
    t_radius = np.array([np.nan if f.radius is None else f.radius for f in faces])
    t_half = np.stack([np.full((2, 3), np.nan) if f.half_edges is None else f.half_edges
                       for f in faces])
    t_area = np.array([f.area for f in faces])

    pos, quat = hand.tip_frames_in_palm(q)
    tip_pos, rot = pos[:, index], quat_to_mat(quat[:, index])          # (B,3), (B,3,3)
    positions = tip_pos[:, None] + np.einsum("bij,fj->bfi", rot, t_centres)
    normals = np.einsum("bij,fj->bfi", rot, t_normals)
    half = np.einsum("bij,fej->bfei", rot, t_half)
    n_combo = len(q)
    positions = positions.reshape(-1, 3)
    normals = normals.reshape(-1, 3)
    half = half.reshape(-1, 2, 3)
    combo = np.repeat(np.arange(n_combo), n_faces)
    face_index = np.tile(np.arange(n_faces, dtype=np.int16), n_combo)

    mean_y = float(normals[:, 1].mean())
    band = params.normal_band
    keep = normals[:, 1] >= -band if mean_y > 0 else normals[:, 1] <= band

    skel = hand.skeleton(q, cfg.name, params.skeleton_spacing_m)
    at_tip = np.flatnonzero(np.linalg.norm(skel[0] - tip_pos[0], axis=1) < 1e-9)
    tip_skel = skel[:, :0]
    if len(at_tip):
        skel, tip_skel = skel[:, :at_tip[-1] + 1], skel[:, at_tip[-1] + 1:]
    else:  # Hand.skeleton changed shape: keep all of it rather than guess
        log.warning("finger %s: no skeleton point at the fingertip body origin; keeping the "
                    "whole skeleton", cfg.name)
    combo = combo[keep]
    qadr = hand.finger_qadr[cfg.name]
    return FingerCloud(
        name=cfg.name, joint_names=tuple(cfg.joints),
        positions=positions[keep], normals=normals[keep], joints=q[combo][:, qadr],
        face_index=face_index[keep], face_kind=kind[face_index[keep]],
        radius=t_radius[face_index[keep]], half_edges=half[keep],
        skeleton=skel.astype(np.float32)[combo], tip_centres=t_centres, tip_normals=t_normals,
        tip_radius=t_radius, tip_half_edges=t_half, tip_area=t_area,
        tip_skeleton=tip_skel.astype(np.float32)[combo])


def build_workspace(hand: Hand, params: AutoWSParams | None = None,
                    demo: DemoSeed | None = None, *,
                    ranges: Mapping[str, tuple[float, float]] | None = None,
                    fingers: Sequence[str] | None = None,
                    cache: bool = True) -> WorkspaceCloud:
    """AutoWS workspace clouds of every finger of ``hand`` (see the module docstring).

    Args:
        hand: the hand.
        params: parameters (default: ``[autows]`` of ``configs/augment.toml``).
        demo: a demonstration to centre the joint grids and contact faces on; ``None`` uses the
            config's manual ranges and the pulp cloud centroids.
        ranges: manual ranges (radians) overriding the config's, per independent joint.
        fingers: build only these fingers (priority order is kept); default all.
        cache: read/write the disk cache (``sim.paths.cache_dir()/workspace``).

    Raises:
        WorkspaceError: bad ranges or demo, or a fingertip without a contact face (the message
            names the hand and finger).
    """
    params = params or load_autows_params()
    if demo is not None:
        check_demo(hand, demo)
    wanted = list(hand.finger_names) if fingers is None else list(fingers)
    unknown = sorted(set(wanted) - set(hand.finger_names))
    if unknown or not wanted:
        raise WorkspaceError(f"hand {hand.name!r}: unknown or no fingers {unknown or wanted}; "
                             f"fingers are {list(hand.finger_names)}")
    all_grids = joint_grids(hand, params, demo, ranges)
    grids = {f: all_grids[f] for f in hand.finger_names if f in wanted}
    key = workspace_key(hand, params, demo, grids)
    path = cache_path(hand, key) if cache else None
    if path is not None and path.is_file():
        t0 = time.perf_counter()
        try:
            cloud = WorkspaceCloud.load(path)
        except WorkspaceError as exc:
            log.warning("ignoring a damaged workspace cache file: %s", exc)
        else:
            log.info("workspace cloud of %s loaded from cache %s in %.1f ms", hand.name, path,
                     1e3 * (time.perf_counter() - t0))
            return dataclasses.replace(cloud, from_cache=True)

    t0 = time.perf_counter()
    clouds = []
    for index, finger in enumerate(hand.config.fingers):
        if finger.name not in grids:
            continue
        query = None if demo is None else demo.contact(finger.name)
        try:
            tip = hand_fingertip_faces(hand, finger.name, query, params.fingertip)
        except ValueError as exc:  # ContactFaceError included
            raise WorkspaceError(f"no contact face for finger {finger.name!r} of hand "
                                 f"{hand.name!r}: {exc}") from exc
        q = grid_joint_vectors(hand, finger.name, grids[finger.name], demo)
        clouds.append(_finger_cloud(hand, index, tip, q, params))
    provenance = {
        "mode": "manual" if demo is None else "demo",
        "demo_id": None if demo is None else demo.id,
        "demo_joints": None if demo is None else demo.joints.tolist(),
        "params": params.to_dict(),
        "grids_rad": {f: {j: v.tolist() for j, v in g.items()} for f, g in grids.items()},
        "key": key,
        "mujoco": mujoco.__version__,
    }
    cloud = WorkspaceCloud(hand=hand.name, fingers=tuple(clouds), provenance=provenance)
    log.info("workspace cloud of %s built in %.0f ms: %s", hand.name,
             1e3 * (time.perf_counter() - t0),
             ", ".join(f"{n} {p} pts/{k} faces" for n, p, k in summarise(cloud)))
    if path is not None:
        cloud.save(path)
    return cloud
