"""Foxglove payloads of a session: ``/tf`` transforms, ``/markers`` scene entities, ``/view`` images.

Why apart from :mod:`teleop.record.schemas`: the schemas say *what* each channel holds; these
builders make the three ``foxglove.*`` messages (FrameTransforms, SceneUpdate, CompressedImage;
field names from foxglove/schemas) that the recorder writes and callers may add to
(:meth:`teleop.record.recorder.SessionRecorder.write_markers`): contact spheres and force
arrows, the object model, the operator's hand skeleton. Conventions: metres, world frame unless
a ``frame_id`` says otherwise; our quaternions are **wxyz**, Foxglove's **xyzw** — the swap
happens here, in :func:`pose`, and nowhere else. Times are ``log_time`` nanoseconds.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from teleop import messages as hand_messages
from teleop.record.contact_record import ContactRecord
from teleop.record.schemas import FRAME_WORLD

__all__ = ["OPENXR_BONES", "FrameTransform", "arrow", "color", "compressed_image",
           "contact_entity", "frame_transforms", "hand_skeleton_entity", "line_list", "model",
           "pose", "scene_entity", "scene_update", "sphere", "time_dict"]


def time_dict(t_ns: int) -> dict[str, int]:
    """Foxglove ``time`` {sec, nsec} of a timestamp in nanoseconds."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def pose(pos_m: Any, quat_wxyz: Any) -> dict[str, Any]:
    """Foxglove ``Pose`` (position metres, orientation **xyzw**) from a wxyz quaternion."""
    px, py, pz = (float(v) for v in pos_m)
    qw, qx, qy, qz = (float(v) for v in quat_wxyz)
    return {"position": {"x": px, "y": py, "z": pz},
            "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}


def color(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    """Foxglove ``Color``, components in [0, 1]."""
    return {"r": float(r), "g": float(g), "b": float(b), "a": float(a)}


@dataclass(frozen=True)
class FrameTransform:
    """A transform for ``/tf``: ``child`` frame pose in ``parent`` (metres, quaternion wxyz)."""

    parent: str
    child: str
    pos_m: Any
    quat_wxyz: Any


def frame_transforms(transforms: Iterable[FrameTransform], t_ns: int) -> dict[str, Any]:
    """A ``foxglove.FrameTransforms`` payload (quaternions converted to xyzw)."""
    stamp = time_dict(t_ns)
    out = []
    for tf in transforms:
        p = pose(tf.pos_m, tf.quat_wxyz)
        out.append({"timestamp": stamp, "parent_frame_id": tf.parent,
                    "child_frame_id": tf.child, "translation": p["position"],
                    "rotation": p["orientation"]})
    return {"transforms": out}


def scene_entity(entity_id: str, t_ns: int, *, frame_id: str = FRAME_WORLD,
                 **primitives: list[dict[str, Any]]) -> dict[str, Any]:
    """A ``foxglove.SceneEntity`` with every primitive list present (empty unless given), so
    strict decoders never meet a missing field. ``primitives``: arrows=, spheres=, lines=, …"""
    kinds = ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models")
    unknown = set(primitives) - set(kinds)
    if unknown:
        raise ValueError(f"unknown SceneEntity primitive list(s): {sorted(unknown)}")
    entity: dict[str, Any] = {"timestamp": time_dict(t_ns), "frame_id": frame_id,
                              "id": entity_id, "lifetime": {"sec": 0, "nsec": 0},
                              "frame_locked": False, "metadata": []}
    for kind in kinds:
        entity[kind] = list(primitives.get(kind, ()))
    return entity


def scene_update(entities: Sequence[dict[str, Any]] = (),
                 deletions: Sequence[dict[str, Any]] = ()) -> dict[str, Any]:
    """A ``foxglove.SceneUpdate`` payload."""
    return {"deletions": list(deletions), "entities": list(entities)}


def sphere(pos_m: Any, diameter_m: float, rgba: dict[str, float]) -> dict[str, Any]:
    """A ``SpherePrimitive`` at ``pos_m`` (metres) of the given diameter (metres)."""
    return {"pose": pose(pos_m, (1.0, 0.0, 0.0, 0.0)),
            "size": {"x": diameter_m, "y": diameter_m, "z": diameter_m}, "color": rgba}


def arrow(tail_m: Any, direction: Any, length_m: float, rgba: dict[str, float], *,
          shaft_diameter_m: float = 0.002) -> dict[str, Any] | None:
    """An ``ArrowPrimitive`` from ``tail_m`` along ``direction`` (any length), ``length_m`` long;
    None when the direction is zero or not finite."""
    dx, dy, dz = (float(v) for v in direction)
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not math.isfinite(n) or n < 1e-12 or not math.isfinite(length_m) or length_m <= 0:
        return None
    dx, dy, dz = dx / n, dy / n, dz / n
    # shortest rotation taking +x (Foxglove's arrow axis) onto d: q ∝ (1 + x·d, x × d)
    w, ax, ay, az = 1.0 + dx, 0.0, -dz, dy
    qn = math.sqrt(w * w + ay * ay + az * az)
    q = (0.0, 0.0, 0.0, 1.0) if qn < 1e-9 else (w / qn, ax, ay / qn, az / qn)
    head = min(0.3 * length_m, 0.01)
    return {"pose": pose(tail_m, q), "shaft_length": max(length_m - head, 0.0),
            "shaft_diameter": shaft_diameter_m, "head_length": head,
            "head_diameter": 2.5 * shaft_diameter_m, "color": rgba}


def model(url: str, pos_m: Any, quat_wxyz: Any, *, scale: float = 1.0,
          media_type: str = "", rgba: dict[str, float] | None = None) -> dict[str, Any]:
    """A ``ModelPrimitive`` referencing a mesh by URL (e.g. ``file:///…/textured.obj`` or
    ``package://…``); Foxglove loads glTF/GLB, STL, OBJ and DAE."""
    return {"pose": pose(pos_m, quat_wxyz), "scale": {"x": scale, "y": scale, "z": scale},
            "color": rgba or color(0.7, 0.7, 0.7, 1.0), "use_embedded_materials": rgba is None,
            "url": url, "media_type": media_type, "data": ""}


def line_list(points_m: Any, rgba: dict[str, float], *, thickness_m: float = 0.003
              ) -> dict[str, Any]:
    """A ``LinePrimitive`` of type LINE_LIST (pairs of points, metres, world frame)."""
    pts = np.asarray(points_m, dtype=float).reshape(-1, 3)
    return {"type": 2, "pose": pose((0, 0, 0), (1, 0, 0, 0)), "thickness": thickness_m,
            "scale_invariant": False,
            "points": [{"x": p[0], "y": p[1], "z": p[2]} for p in pts.tolist()],
            "color": rgba, "colors": [], "indices": []}


def compressed_image(jpeg: bytes, t_ns: int, *, frame_id: str = "view",
                     image_format: str = "jpeg") -> dict[str, Any]:
    """A ``foxglove.CompressedImage`` payload (JSON encoding: data is base64)."""
    return {"timestamp": time_dict(t_ns), "frame_id": frame_id,
            "data": base64.b64encode(jpeg).decode("ascii"), "format": image_format}


#: Marker colours: thumb red, then the other fingers, grey for palm/link contacts.
_FINGER_COLORS = (color(0.9, 0.2, 0.2), color(0.2, 0.7, 0.2), color(0.2, 0.4, 0.9),
                  color(0.9, 0.7, 0.1), color(0.7, 0.3, 0.8), color(0.2, 0.8, 0.8))
_OTHER_COLOR = color(0.6, 0.6, 0.6)


def contact_entity(contacts: Sequence[ContactRecord], t_ns: int, *,
                   fingers: Sequence[str] = (), sphere_diameter_m: float = 0.006,
                   arrow_m_per_n: float = 0.01, arrow_length_m: float = 0.03) -> dict[str, Any]:
    """The ``contacts`` SceneEntity (world frame): a sphere per contact coloured by finger (order
    of ``fingers``; grey when not a fingertip) and an arrow along the normal, into the object,
    ``arrow_m_per_n`` metres per newton of normal force (``arrow_length_m`` when the force is
    unknown)."""
    index = {f: i for i, f in enumerate(fingers)}
    spheres, arrows = [], []
    for c in contacts:
        i = index.get(c.finger) if c.finger is not None else None
        rgba = _FINGER_COLORS[i % len(_FINGER_COLORS)] if i is not None else _OTHER_COLOR
        if not np.isfinite(np.asarray(c.pos_world_m, dtype=float)).all():
            continue
        spheres.append(sphere(c.pos_world_m, sphere_diameter_m, rgba))
        length = (min(max(arrow_m_per_n * c.force_n, 0.005), 0.1) if np.isfinite(c.force_n)
                  else arrow_length_m)
        a = arrow(c.pos_world_m, c.normal_world, length, rgba)
        if a is not None:
            arrows.append(a)
    return scene_entity("contacts", t_ns, spheres=spheres, arrows=arrows)


#: Bones of the OpenXR hand skeleton (joint index pairs) for :func:`hand_skeleton_entity`.
OPENXR_BONES: tuple[tuple[int, int], ...] = tuple(
    (hand_messages.JOINT_INDEX[a], hand_messages.JOINT_INDEX[b])
    for finger, chain in (("thumb", ("metacarpal", "proximal", "distal", "tip")),
                          ("index", ("metacarpal", "proximal", "intermediate", "distal", "tip")),
                          ("middle", ("metacarpal", "proximal", "intermediate", "distal", "tip")),
                          ("ring", ("metacarpal", "proximal", "intermediate", "distal", "tip")),
                          ("little", ("metacarpal", "proximal", "intermediate", "distal", "tip")))
    for a, b in zip(("wrist", *(f"{finger}_{j}" for j in chain[:-1])),
                    (f"{finger}_{j}" for j in chain), strict=True)
)


def hand_skeleton_entity(hand: hand_messages.HandState, t_ns: int, *, entity_id: str,
                         rgba: dict[str, float] | None = None) -> dict[str, Any]:
    """The operator's tracked hand (raw input) as spheres at the valid joints (their radius)
    and lines along the bones, world frame."""
    rgba = rgba or color(1.0, 0.8, 0.6, 0.8)
    valid = np.asarray(hand.valid, dtype=bool)
    spheres = [sphere(hand.positions[i], 2.0 * float(hand.radii[i]), rgba)
               for i in np.flatnonzero(valid)]
    pts = [hand.positions[k] for a, b in OPENXR_BONES if valid[a] and valid[b] for k in (a, b)]
    lines = [line_list(np.array(pts), rgba)] if pts else []
    return scene_entity(entity_id, t_ns, spheres=spheres, lines=lines)
