"""Foxglove payloads of a session: ``/tf`` transforms, ``/markers`` scene entities, ``/view`` images.

Why apart from :mod:`teleop.record.schemas`: the schemas say *what* each channel holds; these
builders make the ``foxglove.*`` messages (FrameTransforms, SceneUpdate, CompressedImage) as the
official ``foxglove-sdk``'s own message classes (:mod:`foxglove.messages`), which the recorder
writes and the bridge's live server publishes, and callers may add to
(:meth:`teleop.record.recorder.SessionRecorder.write_markers`): contact spheres and force
arrows, the object model, the robot's and the operator's hand skeletons. Conventions: metres,
world frame unless a ``frame_id`` says otherwise; our quaternions are **wxyz**, Foxglove's
**xyzw** — the swap happens here, in :func:`pose`, and nowhere else. Times are ``log_time``
nanoseconds. The SDK's messages are write-only (no getters): what one holds is read back by
encoding it and decoding with :mod:`teleop.record.protobuf_payload`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import foxglove as fx
import numpy as np
from foxglove import messages as fm

from teleop import messages as hand_messages
from teleop.record.contact_record import ContactRecord
from teleop.record.schemas import FRAME_WORLD, ChannelSpec

__all__ = ["OPENXR_BONES", "FrameTransform", "arrow", "color", "compressed_image",
           "contact_entity", "cube", "frame_transforms", "hand_skeleton_entity", "line_list",
           "model", "pose", "scene_entity", "scene_update", "sdk_channel", "sphere", "time_dict",
           "timestamp"]


def time_dict(t_ns: int) -> dict[str, int]:
    """Foxglove ``time`` {sec, nsec} of a timestamp in nanoseconds (its JSON form)."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def timestamp(t_ns: int) -> fm.Timestamp:
    """The SDK's ``Timestamp`` of a time in nanoseconds."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return fm.Timestamp(sec, nsec)


def pose(pos_m: Any, quat_wxyz: Any) -> fm.Pose:
    """Foxglove ``Pose`` (position metres, orientation **xyzw**) from a wxyz quaternion."""
    px, py, pz = (float(v) for v in pos_m)
    qw, qx, qy, qz = (float(v) for v in quat_wxyz)
    return fm.Pose(position=fm.Vector3(x=px, y=py, z=pz),
                   orientation=fm.Quaternion(x=qx, y=qy, z=qz, w=qw))


def color(r: float, g: float, b: float, a: float = 1.0) -> fm.Color:
    """Foxglove ``Color``, components in [0, 1]."""
    return fm.Color(r=float(r), g=float(g), b=float(b), a=float(a))


@dataclass(frozen=True)
class FrameTransform:
    """A transform for ``/tf``: ``child`` frame pose in ``parent`` (metres, quaternion wxyz)."""

    parent: str
    child: str
    pos_m: Any
    quat_wxyz: Any


def frame_transforms(transforms: Iterable[FrameTransform], t_ns: int) -> fm.FrameTransforms:
    """A ``foxglove.FrameTransforms`` message (quaternions converted to xyzw)."""
    stamp = timestamp(t_ns)
    out = []
    for tf in transforms:
        px, py, pz = (float(v) for v in tf.pos_m)
        qw, qx, qy, qz = (float(v) for v in tf.quat_wxyz)
        out.append(fm.FrameTransform(timestamp=stamp, parent_frame_id=tf.parent,
                                     child_frame_id=tf.child,
                                     translation=fm.Vector3(x=px, y=py, z=pz),
                                     rotation=fm.Quaternion(x=qx, y=qy, z=qz, w=qw)))
    return fm.FrameTransforms(transforms=out)


_PRIMITIVES = ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models")


def scene_entity(entity_id: str, t_ns: int, *, frame_id: str = FRAME_WORLD,
                 frame_locked: bool = False, **primitives: Sequence[Any]) -> fm.SceneEntity:
    """A ``foxglove.SceneEntity`` that stays until replaced (same id) or deleted.
    ``primitives``: arrows=, cubes=, spheres=, lines=, models=, … (SDK primitive messages);
    ``frame_locked``: it moves with ``frame_id`` as later transforms arrive."""
    unknown = set(primitives) - set(_PRIMITIVES)
    if unknown:
        raise ValueError(f"unknown SceneEntity primitive list(s): {sorted(unknown)}")
    return fm.SceneEntity(timestamp=timestamp(t_ns), frame_id=frame_id, id=entity_id,
                          lifetime=fm.Duration(0, 0), frame_locked=frame_locked,
                          **{k: list(v) for k, v in primitives.items()})


def scene_update(entities: Sequence[fm.SceneEntity] = (),
                 deletions: Sequence[fm.SceneEntityDeletion] = ()) -> fm.SceneUpdate:
    """A ``foxglove.SceneUpdate`` message."""
    return fm.SceneUpdate(deletions=list(deletions), entities=list(entities))


def sphere(pos_m: Any, diameter_m: float, rgba: fm.Color) -> fm.SpherePrimitive:
    """A ``SpherePrimitive`` at ``pos_m`` (metres) of the given diameter (metres)."""
    d = float(diameter_m)
    return fm.SpherePrimitive(pose=pose(pos_m, (1.0, 0.0, 0.0, 0.0)),
                              size=fm.Vector3(x=d, y=d, z=d), color=rgba)


def cube(pos_m: Any, quat_wxyz: Any, size_m: Any, rgba: fm.Color) -> fm.CubePrimitive:
    """A ``CubePrimitive`` (a box of full extents ``size_m``, metres) at a pose."""
    sx, sy, sz = (float(v) for v in size_m)
    return fm.CubePrimitive(pose=pose(pos_m, quat_wxyz), size=fm.Vector3(x=sx, y=sy, z=sz),
                            color=rgba)


def arrow(tail_m: Any, direction: Any, length_m: float, rgba: fm.Color, *,
          shaft_diameter_m: float = 0.002) -> fm.ArrowPrimitive | None:
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
    return fm.ArrowPrimitive(pose=pose(tail_m, q), shaft_length=max(length_m - head, 0.0),
                             shaft_diameter=shaft_diameter_m, head_length=head,
                             head_diameter=2.5 * shaft_diameter_m, color=rgba)


def model(url: str, pos_m: Any, quat_wxyz: Any, *, scale: float = 1.0, media_type: str = "",
          rgba: fm.Color | None = None, data: bytes = b"") -> fm.ModelPrimitive:
    """A ``ModelPrimitive``: a mesh by URL (e.g. ``file:///…/textured.obj``), or embedded
    ``data`` of ``media_type`` (e.g. ``model/gltf-binary``) when ``url`` is empty; Foxglove loads
    glTF/GLB, STL, OBJ and DAE. ``rgba`` overrides the mesh's own colours."""
    return fm.ModelPrimitive(pose=pose(pos_m, quat_wxyz),
                             scale=fm.Vector3(x=scale, y=scale, z=scale),
                             color=rgba or color(0.7, 0.7, 0.7, 1.0), override_color=rgba is not None,
                             url=url, media_type=media_type, data=bytes(data))


def line_list(points_m: Any, rgba: fm.Color, *, thickness_m: float = 0.003) -> fm.LinePrimitive:
    """A ``LinePrimitive`` of type LINE_LIST (pairs of points, metres, in the entity's frame)."""
    pts = np.asarray(points_m, dtype=float).reshape(-1, 3)
    return fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineList,
                            pose=pose((0, 0, 0), (1, 0, 0, 0)), thickness=thickness_m,
                            scale_invariant=False,
                            points=[fm.Point3(x=p[0], y=p[1], z=p[2]) for p in pts.tolist()],
                            color=rgba)


def compressed_image(jpeg: bytes, t_ns: int, *, frame_id: str = "view",
                     image_format: str = "jpeg") -> fm.CompressedImage:
    """A ``foxglove.CompressedImage`` message (the JPEG bytes as they are)."""
    return fm.CompressedImage(timestamp=timestamp(t_ns), frame_id=frame_id, data=bytes(jpeg),
                              format=image_format)


#: Marker colours: thumb red, then the other fingers, grey for palm/link contacts.
_FINGER_RGBA = ((0.9, 0.2, 0.2), (0.2, 0.7, 0.2), (0.2, 0.4, 0.9), (0.9, 0.7, 0.1),
                (0.7, 0.3, 0.8), (0.2, 0.8, 0.8))
_OTHER_RGBA = (0.6, 0.6, 0.6)


def contact_entity(contacts: Sequence[ContactRecord], t_ns: int, *,
                   fingers: Sequence[str] = (), sphere_diameter_m: float = 0.006,
                   arrow_m_per_n: float = 0.01, arrow_length_m: float = 0.03) -> fm.SceneEntity:
    """The ``contacts`` SceneEntity (world frame): a sphere per contact coloured by finger (order
    of ``fingers``; grey when not a fingertip) and an arrow along the normal, into the object,
    ``arrow_m_per_n`` metres per newton of normal force (``arrow_length_m`` when the force is
    unknown)."""
    index = {f: i for i, f in enumerate(fingers)}
    spheres, arrows = [], []
    for c in contacts:
        i = index.get(c.finger) if c.finger is not None else None
        rgba = color(*(_FINGER_RGBA[i % len(_FINGER_RGBA)] if i is not None else _OTHER_RGBA))
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
                         rgba: fm.Color | None = None, frame_id: str = FRAME_WORLD
                         ) -> fm.SceneEntity:
    """The operator's tracked hand (raw input) as spheres at the valid joints (their radius)
    and lines along the bones, in ``frame_id`` (the tracking space's frame)."""
    rgba = rgba or color(1.0, 0.8, 0.6, 0.8)
    valid = np.asarray(hand.valid, dtype=bool)
    spheres = [sphere(hand.positions[i], 2.0 * float(hand.radii[i]), rgba)
               for i in np.flatnonzero(valid)]
    pts = [hand.positions[k] for a, b in OPENXR_BONES if valid[a] and valid[b] for k in (a, b)]
    lines = [line_list(np.array(pts), rgba)] if pts else []
    return scene_entity(entity_id, t_ns, frame_id=frame_id, spheres=spheres, lines=lines)


def sdk_channel(spec: ChannelSpec, context: fx.Context) -> fx.Channel:
    """The SDK channel of ``spec`` in ``context`` (the recorder's MCAP file, or the live
    WebSocket server): our schema as the file states it, messages logged as bytes."""
    return fx.Channel(spec.topic, message_encoding=spec.message_encoding,
                      schema=fx.Schema(name=spec.schema_name, encoding=spec.schema_encoding,
                                       data=spec.schema_data),
                      context=context, metadata={"description": spec.description})
