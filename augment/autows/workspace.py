"""AutoWS fingertip workspace clouds (paper section 3.2; DESIGN §4).

A workspace cloud holds, per finger, every place the finger's contact faces can be put by a grid
of joint angles, in ``frame_palm``: each point carries the face centre position and normal, the
finger's joint angles that put it there, and the face shape. FSG samples these points directly,
so no inverse kinematics is ever solved.

How a cloud is built (:func:`build_workspace`):

* **Contact faces once per finger.** Faces live on the fingertip and do not depend on the joints:
  they are computed once in the tip body frame (:mod:`augment.autows.fingertip`; the query point is the
  demo's contact centroid on that fingertip, else the centroid of the pulp cloud), and carried
  into ``frame_palm`` by the tip body pose: ``p = t + R c``, ``n = R n_c``, half-edges ``R e``.
* **Joint grid.** Without a demo: the config's manual ranges (``ranges_deg``; the paper's Table 1
  for the Shadow Hand) on a grid of ``step_deg`` (10°) from the lower bound, the upper bound
  always included. With a demo: each independent joint at its demo angle ± ``demo_steps`` steps of
  ``demo_step_deg`` (± 2 × 5°, five values). Values are clipped to the joint limits (duplicates
  dropped). Coupled followers follow their leaders (``q_f = c·q_l``, the paper's FJ1 = FJ2); with
  a demo they keep the demo's own offset from that rule (``q_f = d_f + c·(q_l − d_l)``) so that the
  demonstrated pose itself is in the grid even when the simulated hand split a tendon-coupled
  pair unevenly. Every other joint of the hand is 0. All combinations of a finger go through
  :meth:`sim.hand.model.Hand.tip_frames_in_palm` as one batch.
* **Mean-normal filter** (paper): with ``nor_ave`` the finger's mean normal, points whose normal
  y has the opposite sign are removed with a ``±normal_band`` (0.001) band: ``y < −band`` goes
  when ``nor_ave.y > 0``, else ``y > band`` goes. The rule only compares signs, so it reads the
  same in the paper's palm frame and in dexaug's (+y out of the palm face toward the object).
* **Skeletons.** For every kept point, points every ``skeleton_spacing_m`` (5 mm) along the
  finger's links from the first link's origin to the fingertip body origin
  (:meth:`sim.hand.model.Hand.skeleton` without its last segment: the paper's ``cloud_link`` excludes
  the fingertip, which touches the object by design). Stored as float32, (N, K, 3) per finger.
* **Priority.** Fingers are kept in the hand config's order (thumb first).

Clouds are cached on disk (``sim.paths.cache_dir()/workspace``), keyed by a SHA-256 of the hand
model (MJCF bytes plus the compiled kinematic and tip-mesh arrays, which cover included files and
meshes), the hand config (TOML bytes and the parsed finger/palm fields), the joint grids, the
parameters and the demo. Files are ``.npz`` written atomically.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import mujoco
import numpy as np
from numpy.typing import ArrayLike

from augment.autows.fingertip import FingertipFaces, FingertipParams, hand_fingertip_faces
from sim.config import load_toml
from sim.demo import Demo
from sim.errors import ConfigError, DexaugError
from sim.hand.model import Hand
from sim.io import atomic_path
from sim.paths import CONFIG_DIR, cache_dir
from sim.transforms import quat_to_mat

__all__ = [
    "FACE_KINDS",
    "AutoWSParams",
    "DemoSeed",
    "FingerCloud",
    "WorkspaceCloud",
    "WorkspaceError",
    "build_workspace",
    "cache_path",
    "free_camera_projection",
    "joint_grids",
    "load_autows_params",
    "render_workspace_png",
    "summarise",
    "workspace_key",
]

log = logging.getLogger(__name__)

#: Bumped whenever the algorithm or the file layout changes: old cache files stop matching.
FORMAT_VERSION = 1
#: Face kinds as stored in ``FingerCloud.face_kind`` (index into this tuple).
FACE_KINDS = ("circle", "rect")
AUGMENT_TOML = CONFIG_DIR / "augment.toml"


class WorkspaceError(DexaugError, ValueError):
    """A workspace cloud cannot be built or read: empty or invalid joint ranges, a demo that does
    not fit the hand, a fingertip without a usable contact face, or a damaged cloud file."""


# ---------------------------------------------------------------------------------------------
# parameters


@dataclass(frozen=True)
class AutoWSParams:
    """AutoWS parameters (``[autows]`` of ``configs/augment.toml``).

    Attributes:
        step_deg: grid step of the manual joint ranges, degrees (paper: 10).
        demo_step_deg: grid step around a demo's joint angles, degrees (paper: 5).
        demo_steps: steps either side of the demo angle (paper: 2 → five values).
        normal_band: half-width of the mean-normal filter's band on the normal y (paper: 0.001).
        skeleton_spacing_m: spacing of the link skeleton points, metres (5 mm).
        fingertip: fingertip cloud and contact-face parameters.
    """

    step_deg: float = 10.0
    demo_step_deg: float = 5.0
    demo_steps: int = 2
    normal_band: float = 0.001
    skeleton_spacing_m: float = 0.005
    fingertip: FingertipParams = field(default_factory=FingertipParams)

    def __post_init__(self) -> None:
        for name in ("step_deg", "demo_step_deg", "skeleton_spacing_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        if self.demo_steps < 0:
            raise ValueError(f"demo_steps must be >= 0, got {self.demo_steps}")
        if not (math.isfinite(self.normal_band) and self.normal_band >= 0):
            raise ValueError(f"normal_band must be >= 0, got {self.normal_band}")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def load_autows_params(path: Path | str | None = None) -> AutoWSParams:
    """Read ``[autows]`` of ``configs/augment.toml`` (or ``path``); missing keys take the
    defaults of :class:`AutoWSParams`. Errors name the file and key."""
    root = load_toml(path or AUGMENT_TOML)
    sec = root.section("autows", {})
    tip_keys = {f.name for f in dataclasses.fields(FingertipParams)} - {"centre"}
    sec.reject_unknown({"step_deg", "demo_step_deg", "demo_steps", "normal_band",
                        "skeleton_spacing_m", "face_centre", *tip_keys})
    d_tip = FingertipParams()
    d = AutoWSParams()
    shape = sec.str("shape", d_tip.shape)
    if shape not in ("circle", "rect"):
        raise sec.error("shape", f"expected 'circle' or 'rect', got {shape!r}")
    centre = sec.str("face_centre", d_tip.centre)
    if centre not in ("point", "inscribed"):
        raise sec.error("face_centre", f"expected 'point' or 'inscribed', got {centre!r}")
    try:
        tip = FingertipParams(
            density_per_m2=sec.float("density_per_m2", d_tip.density_per_m2, min=1.0),
            seed=sec.int("seed", d_tip.seed, min=0),
            depth_m=sec.float("depth_m", d_tip.depth_m, min=1e-6),
            normal_dot=sec.float("normal_dot", d_tip.normal_dot, min=-1.0, max=0.999999),
            shape=shape,  # type: ignore[arg-type]
            centre=centre,  # type: ignore[arg-type]
            extra_faces=sec.bool("extra_faces", d_tip.extra_faces),
            extra_min_area_ratio=sec.float("extra_min_area_ratio", d_tip.extra_min_area_ratio,
                                           min=0.0),
            extra_offset_factor=sec.float("extra_offset_factor", d_tip.extra_offset_factor,
                                          min=1e-6),
            hpr_radius_factor=sec.float("hpr_radius_factor", d_tip.hpr_radius_factor,
                                        min=1.000001))
        return AutoWSParams(
            step_deg=sec.float("step_deg", d.step_deg, min=1e-6),
            demo_step_deg=sec.float("demo_step_deg", d.demo_step_deg, min=1e-6),
            demo_steps=sec.int("demo_steps", d.demo_steps, min=0),
            normal_band=sec.float("normal_band", d.normal_band, min=0.0),
            skeleton_spacing_m=sec.float("skeleton_spacing_m", d.skeleton_spacing_m, min=1e-5),
            fingertip=tip)
    except ValueError as exc:  # cross-field checks of the dataclasses
        raise ConfigError(f"{sec.where()}: {exc}") from None


# ---------------------------------------------------------------------------------------------
# demonstrations


@dataclass(frozen=True, eq=False)
class DemoSeed:
    """What AutoWS needs of a grasp demonstration.

    Attributes:
        joints: (nq,) the full hand joint vector at the grasp moment, radians (model order).
        contacts: finger name → (3,) centroid of that fingertip's contact points in its tip
            BODY frame, metres, or ``None`` when the finger did not touch (its face is then grown
            at the pulp cloud centroid). Fingers not named count as ``None``.
        id: identifier of the demonstration (provenance, cache key).
    """

    joints: np.ndarray
    contacts: Mapping[str, np.ndarray | None]
    id: str

    def __post_init__(self) -> None:
        q = np.array(self.joints, dtype=float)
        if q.ndim != 1 or not np.isfinite(q).all():
            raise WorkspaceError(f"demo {self.id!r}: joints must be a finite 1-D vector "
                                 f"(radians), got shape {q.shape}")
        q.flags.writeable = False
        object.__setattr__(self, "joints", q)
        contacts: dict[str, np.ndarray | None] = {}
        for finger, point in dict(self.contacts).items():
            if point is None:
                contacts[str(finger)] = None
                continue
            c = np.array(point, dtype=float)
            if c.shape != (3,) or not np.isfinite(c).all():
                raise WorkspaceError(f"demo {self.id!r}: contact of finger {finger!r} must be a "
                                     f"finite 3-vector in its tip frame (metres), got {point!r}")
            c.flags.writeable = False
            contacts[str(finger)] = c
        object.__setattr__(self, "contacts", contacts)

    @classmethod
    def from_demo(cls, demo: Demo) -> DemoSeed:
        """The seed of a demonstration: its joints and per-finger tip-frame contact centroids."""
        return cls(demo.joints, dict(demo.tip_contacts), demo.id)

    def contact(self, finger: str) -> np.ndarray | None:
        return self.contacts.get(finger)


def _check_demo(hand: Hand, demo: DemoSeed) -> None:
    if demo.joints.shape != (hand.nq,):
        raise WorkspaceError(f"demo {demo.id!r}: {demo.joints.shape[0]} joint values, hand "
                             f"{hand.name!r} has {hand.nq} ({', '.join(hand.joint_names)})")
    unknown = sorted(set(demo.contacts) - set(hand.finger_names))
    if unknown:
        raise WorkspaceError(f"demo {demo.id!r}: contacts for unknown finger(s) {unknown}; "
                             f"hand {hand.name!r} has {list(hand.finger_names)}")


# ---------------------------------------------------------------------------------------------
# joint grids


def _manual_values(lo: float, hi: float, step: float) -> np.ndarray:
    n = math.floor((hi - lo) / step + 1e-9)
    values = lo + step * np.arange(n + 1)
    if hi - values[-1] > 1e-9:
        values = np.append(values, hi)
    return values


def joint_grids(hand: Hand, params: AutoWSParams, demo: DemoSeed | None = None,
                ranges: Mapping[str, tuple[float, float]] | None = None,
                ) -> dict[str, dict[str, np.ndarray]]:
    """Per finger, the grid values (radians) of each independent joint, in the finger's order.

    Manual ranges come from the hand config (``ranges_deg``), overridden per joint by ``ranges``
    (radians). With a demo, ranges are centred on the demo angles instead (and ``ranges`` must
    not be given).

    Raises:
        WorkspaceError: ranges together with a demo, an empty (lo > hi) or non-finite range, a
            joint with no range and no demo, or a range for a joint that is not an independent
            finger joint.
    """
    overrides = dict(ranges or {})
    if overrides and demo is not None:
        raise WorkspaceError(f"demo {demo.id!r}: manual ranges apply without a demo only (a demo "
                             "centres the grids on its own joint angles)")
    known = {j for f in hand.config.fingers for j in f.independent_joints}
    bad = sorted(set(overrides) - known)
    if bad:
        raise WorkspaceError(f"hand {hand.name!r}: ranges given for {bad}, which are not "
                             f"independent finger joints ({sorted(known)})")
    step = math.radians(params.step_deg)
    dstep = math.radians(params.demo_step_deg)
    grids: dict[str, dict[str, np.ndarray]] = {}
    for finger in hand.config.fingers:
        per_joint: dict[str, np.ndarray] = {}
        for joint in finger.independent_joints:
            j = hand.joint_names.index(joint)
            lo_lim, hi_lim = hand.lower[j], hand.upper[j]
            if demo is not None:
                centre = float(demo.joints[j])
                values = centre + dstep * np.arange(-params.demo_steps, params.demo_steps + 1)
            else:
                if joint in overrides:
                    lo, hi = (float(v) for v in overrides[joint])
                elif joint in finger.ranges_rad:
                    lo, hi = finger.ranges_rad[joint]
                else:
                    raise WorkspaceError(f"{hand.config.file}: fingers '{finger.name}'.ranges_deg: "
                                         f"no range for joint {joint!r} (give one, or a demo)")
                if not (math.isfinite(lo) and math.isfinite(hi)):
                    raise WorkspaceError(f"hand {hand.name!r}, joint {joint!r}: range [{lo}, {hi}] "
                                         "is not finite")
                if lo > hi:
                    raise WorkspaceError(f"hand {hand.name!r}, finger {finger.name!r}, joint "
                                         f"{joint!r}: empty range [{math.degrees(lo):.3g}°, "
                                         f"{math.degrees(hi):.3g}°] (lower > upper)")
                values = _manual_values(lo, hi, step)
            clipped = np.unique(np.clip(values, lo_lim, hi_lim))
            # MJCF limits are often rounded (1.22173 for 70°): warn only beyond 1e-4 rad
            if demo is None and (values.min() < lo_lim - 1e-4 or values.max() > hi_lim + 1e-4):
                log.warning("hand %s, joint %s: range [%.1f°, %.1f°] exceeds the joint limits "
                            "[%.1f°, %.1f°]; grid clipped", hand.name, joint,
                            math.degrees(values.min()), math.degrees(values.max()),
                            math.degrees(lo_lim), math.degrees(hi_lim))
            per_joint[joint] = clipped
        grids[finger.name] = per_joint
    return grids


def _finger_q(hand: Hand, finger: str, grid: Mapping[str, np.ndarray],
              demo: DemoSeed | None) -> np.ndarray:
    """(B, nq) joint vectors of every combination of the finger's grid; other joints 0."""
    names = list(grid)
    mesh = np.meshgrid(*(grid[n] for n in names), indexing="ij")
    q = np.zeros((mesh[0].size, hand.nq))
    for name, values in zip(names, mesh, strict=True):
        q[:, hand.joint_names.index(name)] = values.ravel()
    cfg = hand.config.finger(finger)
    followers = [hand.joint_names.index(j) for j in cfg.coupled_to]
    if followers:
        filled = hand.fill_coupled(q)
        if demo is not None:
            offset = demo.joints - hand.fill_coupled(demo.joints)
            filled[:, followers] += offset[followers]
        q[:, followers] = filled[:, followers]
        q[:, followers] = np.clip(q[:, followers], hand.lower[followers], hand.upper[followers])
    return q


# ---------------------------------------------------------------------------------------------
# data structure


@dataclass(frozen=True, eq=False)
class FingerCloud:
    """The workspace cloud of one finger (arrays in ``frame_palm``, metres, radians).

    Attributes:
        name: finger name.
        joint_names: the finger's joints (config order, coupled followers included).
        positions: (N,3) contact-face centres.
        normals: (N,3) unit face normals (out of the fingertip).
        joints: (N, len(joint_names)) joint angles that put the face there.
        face_index: (N,) int16, which contact face (0 = main, then the kept extra faces).
        face_kind: (N,) uint8, index into :data:`FACE_KINDS`.
        radius: (N,) circle radius (NaN for rectangles).
        half_edges: (N,2,3) rectangle half-edge vectors (NaN for circles).
        skeleton: (N,K,3) float32 link skeleton points (fingertip link excluded).
        tip_centres, tip_normals: (F,3) the faces in the tip body frame.
        tip_radius: (F,) radii (NaN for rectangles); tip_half_edges: (F,2,3) (NaN for circles).
        tip_area: (F,) face areas, square metres.
    """

    name: str
    joint_names: tuple[str, ...]
    positions: np.ndarray
    normals: np.ndarray
    joints: np.ndarray
    face_index: np.ndarray
    face_kind: np.ndarray
    radius: np.ndarray
    half_edges: np.ndarray
    skeleton: np.ndarray
    tip_centres: np.ndarray
    tip_normals: np.ndarray
    tip_radius: np.ndarray
    tip_half_edges: np.ndarray
    tip_area: np.ndarray

    ARRAYS = ("positions", "normals", "joints", "face_index", "face_kind", "radius", "half_edges",
              "skeleton", "tip_centres", "tip_normals", "tip_radius", "tip_half_edges", "tip_area")

    @property
    def n_points(self) -> int:
        return len(self.positions)

    @property
    def n_faces(self) -> int:
        return len(self.tip_centres)

    @property
    def nbytes(self) -> int:
        return sum(getattr(self, a).nbytes for a in self.ARRAYS)


@dataclass(frozen=True, eq=False)
class WorkspaceCloud:
    """AutoWS workspace clouds of a hand: one :class:`FingerCloud` per finger, in priority
    order (the hand config's finger order), plus provenance (mode, demo id, parameters, grids,
    cache key). ``from_cache`` says whether this object was read from the disk cache."""

    hand: str
    fingers: tuple[FingerCloud, ...]
    provenance: dict[str, Any]
    from_cache: bool = False

    @property
    def finger_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fingers)

    def finger(self, name: str) -> FingerCloud:
        for f in self.fingers:
            if f.name == name:
                return f
        raise KeyError(f"no finger {name!r} in the workspace cloud of {self.hand!r} "
                       f"({list(self.finger_names)})")

    @property
    def nbytes(self) -> int:
        return sum(f.nbytes for f in self.fingers)

    def save(self, path: Path | str) -> None:
        """Write the cloud to ``path`` (``.npz``, uncompressed for fast loading) atomically."""
        arrays: dict[str, np.ndarray] = {}
        for i, f in enumerate(self.fingers):
            for a in FingerCloud.ARRAYS:
                arrays[f"f{i}_{a}"] = getattr(f, a)
        meta = {"format": FORMAT_VERSION, "hand": self.hand,
                "fingers": [{"name": f.name, "joint_names": list(f.joint_names)}
                            for f in self.fingers],
                "provenance": self.provenance}
        arrays["meta"] = np.array(json.dumps(meta))
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        with atomic_path(path) as tmp:
            tmp.write_bytes(buf.getbuffer())

    @classmethod
    def load(cls, path: Path | str) -> WorkspaceCloud:
        """Read a cloud written by :meth:`save`.

        Raises:
            WorkspaceError: the file is missing, damaged, of another format version, or not a
                workspace cloud.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"][()]))
                if meta.get("format") != FORMAT_VERSION:
                    raise WorkspaceError(f"{path}: workspace cloud format {meta.get('format')}, "
                                         f"expected {FORMAT_VERSION}")
                fingers = tuple(
                    FingerCloud(name=fm["name"], joint_names=tuple(fm["joint_names"]),
                                **{a: _readonly(z[f"f{i}_{a}"]) for a in FingerCloud.ARRAYS})
                    for i, fm in enumerate(meta["fingers"]))
        except WorkspaceError:
            raise
        except FileNotFoundError:
            raise WorkspaceError(f"{path}: no such workspace cloud file") from None
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise WorkspaceError(f"{path}: not a readable workspace cloud ({exc})") from None
        return cls(hand=meta["hand"], fingers=fingers, provenance=meta["provenance"])


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    a.flags.writeable = False
    return a


def summarise(cloud: WorkspaceCloud) -> list[tuple[str, int, int]]:
    """``(finger, number of points, number of contact faces)`` per finger, in priority order."""
    return [(f.name, f.n_points, f.n_faces) for f in cloud.fingers]


# ---------------------------------------------------------------------------------------------
# cache key


def _hash_array(h: Any, a: np.ndarray) -> None:
    a = np.ascontiguousarray(a)
    h.update(f"{a.dtype}{a.shape}".encode())
    h.update(a.tobytes())


def _model_digest(hand: Hand) -> str:
    """SHA-256 of what the clouds depend on in the hand model and config: the MJCF bytes, the
    compiled kinematic tree and tip-mesh arrays (these cover included files and mesh files
    without parsing the MJCF), and the config (TOML bytes plus parsed fields, so a config
    changed in code also changes the key)."""
    m = hand.model
    h = hashlib.sha256()
    h.update(hand.model_path.read_bytes())
    for name in ("body_parentid", "body_pos", "body_quat", "body_jntadr", "body_jntnum",
                 "jnt_type", "jnt_axis", "jnt_pos", "jnt_qposadr", "jnt_range", "jnt_limited",
                 "qpos0", "geom_bodyid", "geom_dataid", "geom_type", "geom_pos", "geom_quat"):
        _hash_array(h, getattr(m, name))
    for f in hand.config.fingers:
        mid = m.mesh(f.tip_mesh).id
        va, nv = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
        fa, nf = m.mesh_faceadr[mid], m.mesh_facenum[mid]
        _hash_array(h, m.mesh_vert[va:va + nv])
        _hash_array(h, m.mesh_face[fa:fa + nf])
    cfg = hand.config
    if cfg.file.is_file():
        h.update(cfg.file.read_bytes())
    fields = {"palm": [cfg.palm.body, cfg.palm.pos.tolist(), cfg.palm.quat_wxyz.tolist()],
              "fingers": [[f.name, f.tip_body, f.tip_mesh, list(f.links), list(f.joints),
                           sorted(f.coupled_to.items()), f.v_f.tolist(), f.v_u.tolist(),
                           f.tip_site_pos.tolist(), sorted(f.ranges_rad.items())]
                          for f in cfg.fingers]}
    h.update(json.dumps(fields, sort_keys=True, default=str).encode())
    return h.hexdigest()


def workspace_key(hand: Hand, params: AutoWSParams, demo: DemoSeed | None,
                  grids: Mapping[str, Mapping[str, np.ndarray]]) -> str:
    """Cache key of a build: hand model + config, parameters, joint grids and demo."""
    h = hashlib.sha256()
    h.update(f"dexaug-autows-v{FORMAT_VERSION}".encode())
    h.update(_model_digest(hand).encode())
    h.update(json.dumps(params.to_dict(), sort_keys=True).encode())
    for finger, grid in grids.items():
        h.update(finger.encode())
        for joint, values in grid.items():
            h.update(joint.encode())
            _hash_array(h, np.asarray(values, dtype=float))
    if demo is not None:
        h.update(demo.id.encode())
        _hash_array(h, demo.joints)
        for finger in sorted(demo.contacts):
            c = demo.contacts[finger]
            h.update(finger.encode())
            h.update(b"none" if c is None else c.tobytes())
    return h.hexdigest()


def cache_path(hand: Hand, key: str) -> Path:
    """Where the cloud of ``key`` is cached: ``cache_dir()/workspace/<hand>-<key[:24]>.npz``."""
    return cache_dir() / "workspace" / f"{hand.name}-{key[:24]}.npz"


# ---------------------------------------------------------------------------------------------
# building


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
    if len(at_tip):
        skel = skel[:, :at_tip[-1] + 1]
    else:  # Hand.skeleton changed shape: keep all of it rather than guess
        log.warning("finger %s: no skeleton point at the fingertip body origin; keeping the "
                    "whole skeleton", cfg.name)
    combo = combo[keep]
    qadr = hand.finger_qadr[cfg.name]
    return FingerCloud(
        name=cfg.name, joint_names=tuple(cfg.joints),
        positions=_readonly(positions[keep]), normals=_readonly(normals[keep]),
        joints=_readonly(q[combo][:, qadr]), face_index=_readonly(face_index[keep]),
        face_kind=_readonly(kind[face_index[keep]]),
        radius=_readonly(t_radius[face_index[keep]]), half_edges=_readonly(half[keep]),
        skeleton=_readonly(skel.astype(np.float32)[combo]),
        tip_centres=_readonly(t_centres), tip_normals=_readonly(t_normals),
        tip_radius=_readonly(t_radius), tip_half_edges=_readonly(t_half),
        tip_area=_readonly(t_area))


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
        _check_demo(hand, demo)
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
        q = _finger_q(hand, finger.name, grids[finger.name], demo)
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


# ---------------------------------------------------------------------------------------------
# rendering

_COLOURS_RGB = ((230, 60, 60), (60, 170, 240), (70, 200, 90), (240, 170, 40), (190, 90, 220),
                (40, 200, 200), (250, 110, 180), (150, 150, 150))


def free_camera_projection(model: mujoco.MjModel, data: mujoco.MjData, lookat: ArrayLike,
                           distance_m: float, azimuth_deg: float, elevation_deg: float,
                           width: int, height: int,
                           ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """World → pixel projection of the free camera that :func:`sim.world.render.render_scene` uses,
    read back from ``mjv_updateScene`` (no GL needed). Returns ``project(points (N,3)) ->
    (uv (N,2), depth (N,))``: pixel coordinates with (0, 0) at the centre of the top-left pixel
    (OpenCV's convention), and the depth along the view direction in metres (> 0 in front)."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = lookat
    cam.distance, cam.azimuth, cam.elevation = distance_m, azimuth_deg, elevation_deg
    scene = mujoco.MjvScene(model, maxgeom=max(1000, 4 * model.ngeom))
    mujoco.mjv_updateScene(model, data, mujoco.MjvOption(), None, cam,
                           int(mujoco.mjtCatBit.mjCAT_ALL), scene)
    # the scene holds a left/right eye pair (offset by the model's ipd); a mono rendering uses
    # their average
    gl = mujoco.mjv_averageCamera(scene.camera[0], scene.camera[1])
    fwd, up = np.array(gl.forward), np.array(gl.up)
    right = np.cross(fwd, up)
    origin = np.array(gl.pos)
    near, top, bottom = gl.frustum_near, gl.frustum_top, gl.frustum_bottom
    half_w = gl.frustum_width if gl.frustum_width > 0 else 0.5 * (top - bottom) * width / height
    left = gl.frustum_center - half_w

    def project(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rel = np.asarray(points, dtype=float) - origin
        depth = rel @ fwd
        z = np.maximum(depth, 1e-9)
        xs, ys = near * (rel @ right) / z, near * (rel @ up) / z
        u = (xs - left) / (2 * half_w) * width
        v = (top - ys) / (top - bottom) * height
        return np.stack([u, v], axis=1) - 0.5, depth

    return project


def render_workspace_png(hand: Hand, cloud: WorkspaceCloud, path: Path | str | None, *,
                         q: ArrayLike | None = None, width: int = 960, height: int = 720,
                         skeletons_per_finger: int = 12, point_radius_px: int = 2,
                         ) -> np.ndarray:
    """Draw the workspace clouds over an offscreen MuJoCo rendering of the hand (like the
    paper's Fig. 2 (h)–(j)) and write a PNG to ``path`` (skipped when ``None``).

    The hand is shown at ``q`` (default: the demo's joints for a demo cloud, else all zeros);
    the clouds are placed through its palm frame (they are relative to the palm, so the hand's
    pose does not change their shape). Points are coloured per finger; a few link skeletons per
    finger are drawn as thin polylines. Needs an OpenGL backend (``sim.world.render.gl_available``).

    Returns:
        the RGB image (H, W, 3) uint8.
    """
    from sim.world.render import render_scene, save_png

    if cloud.hand != hand.name:
        raise WorkspaceError(f"cloud of hand {cloud.hand!r} drawn over hand {hand.name!r}")
    if q is None:
        demo_q = cloud.provenance.get("demo_joints")
        q = np.zeros(hand.nq) if demo_q is None else np.asarray(demo_q, dtype=float)
    qv = hand.check_q(q, "render joint vector")
    model = hand.spec().compile()  # render_scene changes visual scales: keep hand.model intact
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    data = mujoco.MjData(model)
    data.qpos[:] = qv
    mujoco.mj_forward(model, data)
    ppos, pquat = hand.palm_pose(qv)
    rot = quat_to_mat(pquat[0])

    def to_world(p: np.ndarray) -> np.ndarray:
        return ppos[0] + np.asarray(p, dtype=float) @ rot.T

    pts = [to_world(f.positions) for f in cloud.fingers if f.n_points]
    links = [model.body(b).id for f in hand.config.fingers for b in f.links]
    everything = np.vstack([*pts, ppos, data.xpos[links]])
    lo, hi = everything.min(0), everything.max(0)
    lookat = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 0.03)
    fovy = math.radians(model.vis.global_.fovy)
    distance = 1.15 * radius / math.sin(0.5 * fovy)
    # look at the palm face (+y of frame_palm) from slightly beside and above
    eye_dir = rot @ np.array([0.35, 1.0, 0.3])
    forward = -eye_dir / np.linalg.norm(eye_dir)
    azimuth = math.degrees(math.atan2(forward[1], forward[0]))
    elevation = math.degrees(math.asin(float(np.clip(forward[2], -1.0, 1.0))))
    rgb = render_scene(model, data, lookat=lookat, distance_m=distance, azimuth_deg=azimuth,
                       elevation_deg=elevation, width=width, height=height, show_contacts=False)
    project = free_camera_projection(model, data, lookat, distance, azimuth, elevation, width,
                                     height)
    img = np.ascontiguousarray(rgb)
    rng = np.random.default_rng(0)
    for i, f in enumerate(cloud.fingers):
        colour = _COLOURS_RGB[i % len(_COLOURS_RGB)]
        dim = tuple(int(0.55 * c) for c in colour)
        if f.n_points and skeletons_per_finger > 0:
            pick = rng.choice(f.n_points, min(skeletons_per_finger, f.n_points), replace=False)
            for s in f.skeleton[pick]:
                uv, _ = project(to_world(s))
                cv2.polylines(img, [np.round(uv).astype(np.int32)], False, dim, 1, cv2.LINE_AA)
        if f.n_points:
            uv, depth = project(to_world(f.positions))
            for u, v in np.round(uv[depth > 0]).astype(int):
                cv2.circle(img, (int(u), int(v)), point_radius_px, colour, -1, cv2.LINE_AA)
        cv2.putText(img, f"{f.name}: {f.n_points} pts, {f.n_faces} faces", (12, 26 + 24 * i),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.6, colour, 2, cv2.LINE_AA)
    if path is not None:
        save_png(path, img)
    return img
