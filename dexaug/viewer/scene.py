"""What the 3D grasp viewer shows, as plain data: the object, the hand at every grasp, the
contacts, the table, the palm cloud and the demonstration.

Why Python builds it and the page only draws: the hand's pose at a grasp is forward kinematics
of the same compiled MuJoCo model the validator simulates (:meth:`sim.hand.model.Hand.body_poses`,
placed so frame_palm lands on the dataset's ``palm_pose``), and the meshes are the model's own
visual geoms (``geom_mesh``, in their body frames), so what the page shows is the grasp that
was validated, not a re-implementation of it in JavaScript.

Everything is in the object frame (metres; the dataset's frame). The hand travels as one
triangle mesh per body, in the body frame, with one RGB colour per vertex (its geom's
material), and each grasp as the pose of those bodies (``body_pose``: (N, B, 7) x y z qw qx
qy qz). Arrays are little-endian and base64-encoded, so a page holds a dataset of a thousand
grasps in a few MB without a server. The page's format is :data:`SCENE_FORMAT`.
"""

from __future__ import annotations

import base64
import json
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from dexaug.viewer.mesh_lod import within_budget
from sim.transforms import pose_inv, pose_mul
from sim.world.geom_mesh import geom_mesh

if TYPE_CHECKING:
    from augment.dataset import ObjectTable
    from sim.demo import Demo
    from sim.hand.model import Hand
    from sim.world.objects import ObjectAsset

__all__ = ["SCENE_FORMAT", "ViewerLimits", "grasp_body_poses", "hand_meshes", "scene_json", "viewer_scene"]

log = logging.getLogger(__name__)

SCENE_FORMAT = 1
#: the object's colour (its scans' textures are not carried: one plain colour reads best)
OBJECT_RGB = (205, 160, 110)


@dataclass(frozen=True)
class ViewerLimits:
    """How much a page carries: at most ``max_grasps`` rows (the passed ones first, then the
    rejected, in the dataset's order), ``hand_faces`` triangles for the whole hand and
    ``object_faces`` for the object (:func:`dexaug.viewer.mesh_lod.within_budget`)."""

    max_grasps: int = 1000
    hand_faces: int = 60_000
    object_faces: int = 20_000


def _b64(a: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=np.dtype(dtype).newbyteorder("<"))
                            .tobytes()).decode("ascii")


def _mesh_json(vertices: np.ndarray, faces: np.ndarray, rgb: np.ndarray) -> dict[str, Any]:
    return {"nv": len(vertices), "nf": len(faces), "v": _b64(vertices, "f4"),
            "f": _b64(faces, "u4"), "c": _b64(rgb, "u1")}


def _visual_geoms(model: mujoco.MjModel) -> np.ndarray:
    """The geoms drawn: the visual ones (no collisions), or every geom when the model has
    none (a hand modelled with collision geometry only)."""
    vis = np.flatnonzero((model.geom_contype == 0) & (model.geom_conaffinity == 0))
    return vis if len(vis) else np.arange(model.ngeom)


def _geom_rgb(model: mujoco.MjModel, g: int) -> np.ndarray:
    mat = int(model.geom_matid[g])
    rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g]
    return np.round(np.clip(rgba[:3], 0.0, 1.0) * 255).astype(np.uint8)


def hand_meshes(hand: Hand, max_faces: int) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Body id → (vertices in the body frame (V, 3), faces (F, 3), per-vertex RGB (V, 3)) of
    the hand's visual geoms, lightened to ``max_faces`` triangles in all (each geom gets a
    share in proportion to its own count)."""
    m = hand.model
    geoms = [int(g) for g in _visual_geoms(m)]
    pieces = {g: geom_mesh(m, g, hull=False) for g in geoms}
    total = sum(len(p.faces) for p in pieces.values()) or 1
    bodies: dict[int, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
    for g, mesh in pieces.items():
        if not len(mesh.faces):
            continue
        share = max(int(max_faces * len(mesh.faces) / total), 12)
        v, f = within_budget(mesh.vertices, mesh.faces, share)
        bodies.setdefault(int(m.geom_bodyid[g]), []).append(
            (v, f, np.repeat(_geom_rgb(m, g)[None], len(v), axis=0)))
    out = {}
    for body, parts in bodies.items():
        offsets = np.cumsum([0] + [len(v) for v, _, _ in parts[:-1]])
        out[body] = (np.vstack([v for v, _, _ in parts]),
                     np.vstack([f + o for (_, f, _), o in zip(parts, offsets, strict=True)]),
                     np.vstack([c for _, _, c in parts]))
    return out


def grasp_body_poses(hand: Hand, palm_pose: np.ndarray, joints: np.ndarray,
                     bodies: list[int]) -> np.ndarray:
    """(N, len(bodies), 7) poses (x y z qw qx qy qz, object frame) of ``bodies`` for grasps
    given as frame_palm poses (N, 7) and joint vectors (N, nq): T_body = T_palm ·
    T_base→palm(q)⁻¹ · T_base→body(q), batched forward kinematics of the hand model."""
    palm_pose = np.asarray(palm_pose, float).reshape(-1, 7)
    if not len(palm_pose):      # FSG found no grasp: a result, drawn as an object alone
        return np.zeros((0, len(bodies), 7))
    q = hand.check_q(np.asarray(joints, float).reshape(len(palm_pose), -1), "hand_pose")
    pos, quat = hand.body_poses(q)                         # base frame, (N, nbody, ·)
    ppos, pquat = hand.palm_pose(q)                        # base frame, (N, ·)
    ip, iq = pose_inv(ppos, pquat)
    bp, bq = pose_mul(palm_pose[:, :3], palm_pose[:, 3:], ip, iq)   # base in object frame
    wp, wq = pose_mul(bp[:, None], bq[:, None], pos[:, bodies], quat[:, bodies])
    return np.concatenate([wp, wq], axis=-1)


def _verdicts(cols: dict[str, np.ndarray]) -> list[str]:
    """"passed", "failed" or "not validated" per row (a row without a simulated displacement
    and without a failure reason was never simulated)."""
    n = len(cols["palm_pose"])
    passed = cols.get("passed", np.zeros(n, bool))
    failure = cols.get("failure", np.array([""] * n, object))
    moved = cols.get("displacement_m", np.full(n, np.nan))
    return ["passed" if p else ("failed" if (str(f) or np.isfinite(d)) else "not validated")
            for p, f, d in zip(passed, failure, moved, strict=True)]


def _finite(a: np.ndarray | None, n: int, scale: float = 1.0) -> list[float | None]:
    if a is None:
        return [None] * n
    return [float(x) * scale if np.isfinite(x) else None for x in np.asarray(a, float)]


def _grasps_json(hand: Hand, table: ObjectTable, bodies: list[int]) -> dict[str, Any]:
    cols = table.columns
    n = len(cols["palm_pose"])
    used = cols.get("fingers_used", np.zeros((n, len(table.finger_names)), bool))
    return {
        "n": n,
        "body_pose": _b64(grasp_body_poses(hand, cols["palm_pose"], cols["hand_pose"], bodies),
                          "f4"),
        "palm": _b64(cols["palm_pose"][:, :3], "f4"),
        "verdict": _verdicts(cols),
        "failure": [str(f) for f in cols.get("failure", [""] * n)],
        "fingers": [[f for f, on in zip(table.finger_names, row, strict=True) if on]
                    for row in used],
        "epsilon": _finite(cols.get("sim_epsilon"), n),
        "gws": _finite(cols.get("gws"), n),
        "displacement_mm": _finite(cols.get("displacement_m"), n, 1e3),
        "rotation_deg": _finite(cols.get("rotation_rad"), n, float(np.degrees(1.0))),
        "contact_offsets": [int(o) for o in cols["contact_offsets"]],
        "contact_points": _b64(cols["contact_points"], "f4"),
        "contact_normals": _b64(cols["contact_normals"], "f4"),
    }


def _head(table: ObjectTable, n: int) -> ObjectTable:
    """The first ``n`` rows of a table without side table (contacts cut at their offsets)."""
    import dataclasses

    cols = table.columns
    if len(cols["palm_pose"]) <= n:
        return table
    cut = int(cols["contact_offsets"][n])
    head = {k: (v[:cut] if k in ("contact_points", "contact_normals", "contact_finger")
                else v[:n + 1] if k == "contact_offsets" else v[:n]) for k, v in cols.items()}
    return dataclasses.replace(table, columns=head)


def viewer_scene(table: ObjectTable, hand: Hand, obj: ObjectAsset, *, demo: Demo | None = None,
                 title: str = "", limits: ViewerLimits | None = None) -> dict[str, Any]:
    """The page's data for one object's table (module docstring): JSON-serialisable."""
    from augment.dataset import with_rejected

    lim = limits or ViewerLimits()
    every = with_rejected(table)            # the passed rows, then the rejected ones
    total = len(every.columns["palm_pose"])
    if total > lim.max_grasps:
        log.info("viewer: showing the first %d of %d grasps", lim.max_grasps, total)
    rows = _head(every, lim.max_grasps)
    meshes = hand_meshes(hand, lim.hand_faces)
    bodies = sorted(meshes)
    surface = obj.surface_mesh()
    ov, of = within_budget(surface.vertices, surface.faces, lim.object_faces)
    return {
        "format": SCENE_FORMAT, "title": title or f"{obj.name} · {hand.name}",
        "object": {"name": obj.name,
                   "mesh": _mesh_json(ov, of, np.tile(np.array(OBJECT_RGB, np.uint8),
                                                      (len(ov), 1)))},
        "hand": {"name": hand.name, "bodies": [hand.model.body(b).name for b in bodies],
                 "meshes": [_mesh_json(*meshes[b]) for b in bodies]},
        "finger_names": list(table.finger_names),
        "grasps": _grasps_json(hand, rows, bodies),
        "grasps_in_table": total,
        "demo": None if demo is None else {"id": demo.id,
                                           "palm": [float(x) for x in demo.palm_pos_m]},
        "table": None if demo is None or demo.table is None else {
            "point": [float(x) for x in demo.table["point_m"]],
            "normal": [float(x) for x in demo.table["normal"]]},
    }


def scene_json(scene: dict[str, Any]) -> str:
    """The scene as JSON safe inside an HTML ``<script>`` element (no ``</`` sequence)."""
    return json.dumps(scene, separators=(",", ":")).replace("</", "<\\/")
