"""``dexaug demo import``: a static grasp pose from a keyframe file → a :class:`sim.demo.Demo`.

A keyframe (:mod:`dexaug.pipeline.keyframe_files`) says where the object, the palm body and the
joints are, not which fingers touch the object. So the grasp is placed in MuJoCo as the
validator places one (the object at home, frame_palm at the grasp's pose in the object frame),
and each fingertip's signed distance to the object is measured: the closest pair of the tip
body's and the object's collision geoms (``mujoco.mj_geomDistance``, negative = penetration, up
to :data:`FAR_M`). The fingers within ``tolerance_m`` are the demo's: their contact centroids in
the fingertip frames (:meth:`sim.validate.validator.Validator.fingertip_contacts` searching as
far as the tolerance; the closest point where that margin pass reports none) are what AutoWS
centres its faces on, and the closest object points are the demo's contact points. No
fingertip within the tolerance: refused, as the pose is not a grasp of that object.

Frames. ``object_transform`` is the pose of our object's frame in the file's object frame (the
srh.txt format's objects are the authors' re-centred meshes; identity otherwise): our object's
world pose is the file's composed with it. The palm body's world pose composed with the hand
config's palm offset is frame_palm in the world (as :mod:`sim.validate.dgb_reference` does),
then expressed in our object's frame. A table top in the file becomes :attr:`Demo.table`.

Nothing is written until every requested keyframe has become a demo (:func:`write_imported`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from dexaug.pipeline.keyframe_files import (
    SRH_FORMAT,
    Keyframe,
    joint_vector,
    numbers,
    read_keyframes,
    srh_format,
    unit_quat,
)
from sim.demo import Demo, DemoError, demo_to_json
from sim.errors import AssetError
from sim.grasp import Grasp
from sim.hand.config import hand_names, load_hand_config
from sim.hand.model import Hand
from sim.io import write_bytes_atomic
from sim.paths import REPO_ROOT
from sim.transforms import pose_inv, pose_mul, rotate
from sim.validate.config import ValidateConfig
from sim.validate.validator import Validator
from sim.world.objects import load_object
from sim.world.scene import HAND_PREFIX, Scene

__all__ = ["DEFAULT_TOLERANCE_M", "FAR_M", "IMPORTED_DEMOS_DIR", "ImportedDemo", "describe",
           "import_demos", "write_imported"]

#: fingertips this close to the object (signed distance, m) touch it; the FSG keyframes touch
#: within ±2 mm (``fsg_keyframes/README.md``)
DEFAULT_TOLERANCE_M = 0.003
#: distances are measured up to this (m); farther fingertips are reported as None
FAR_M = 0.05
#: where imported demonstrations go by default, and where ``dexaug bench paper`` looks first
IMPORTED_DEMOS_DIR = REPO_ROOT / "recordings" / "demos" / "human"


@dataclass(frozen=True)
class ImportedDemo:
    """A demo made from a keyframe, with what the committed file records of its making:
    ``tip_distance_m`` (finger → signed fingertip–object distance, None beyond :data:`FAR_M`)
    and ``provenance`` (plain data: file, format, entry, transform, tolerance, distances)."""

    demo: Demo
    tip_distance_m: dict[str, float | None]
    provenance: dict[str, Any]


def import_demos(path: Path | str, *, hand: str | None = None, object_name: str | None = None,
                 object_transform: Sequence[float] | None = None,
                 tolerance_m: float = DEFAULT_TOLERANCE_M, note: str = "") -> list[ImportedDemo]:
    """The demos of the keyframes in ``path`` (all, or the one of ``object_name``).

    ``hand``: the hand config (default: the one whose palm body and finger joints the file
    names; srh.txt, which names none: the hand whose folder declares ``[formats.srh_txt]``).
    ``object_transform``: [x, y, z, qw, qx, qy, qz], our object's frame in the file's (module
    docstring); required for srh.txt, for one object at a time. ``note`` (e.g. the source's
    authors and licence) is kept in the provenance. Raises :class:`DemoError` (one line: file,
    entry, field, what was expected; :class:`~sim.errors.ConfigError` for a hand that declares
    no srh.txt format)."""
    path = Path(path)
    if not (np.isfinite(tolerance_m) and 0.0 < tolerance_m < FAR_M):
        raise DemoError(f"tolerance: expected a distance in (0, {FAR_M * 1e3:g}) mm, got "
                        f"{tolerance_m * 1e3:g} mm")
    keyframes = _select(path, read_keyframes(path), object_name, object_transform)
    transform = None if object_transform is None else (
        numbers(object_transform[:3], 3, "object transform", "a position in m"),
        unit_quat(object_transform[3:], "object transform quaternion"))
    hands: dict[str, Hand] = {}
    return [_import_one(path, kf, _hand_for(kf, hand, hands), transform, tolerance_m, note)
            for kf in keyframes]


def _select(path: Path, keyframes: list[Keyframe], object_name: str | None,
            object_transform: Sequence[float] | None) -> list[Keyframe]:
    names = [kf.object for kf in keyframes]
    if object_name is not None:
        keyframes = [kf for kf in keyframes if kf.object == object_name]
        if not keyframes:
            raise DemoError(f"{path}: no keyframe of object {object_name!r}; it holds {names}")
    if object_transform is not None and len(keyframes) > 1:
        raise DemoError(f"{path}: an object transform is one object's; choose the object "
                        f"(--object, one of {names})")
    if object_transform is None and any(kf.foreign_object_frame for kf in keyframes):
        raise DemoError(f"{path}: its ({keyframes[0].format}) object poses are of another mesh "
                        f"frame than our objects'; give --object-transform X Y Z QW QX QY QZ "
                        f"(our object's frame in that one) and --object")
    if object_transform is not None and len(object_transform) != 7:
        raise DemoError(f"object transform: expected 7 numbers X Y Z QW QX QY QZ, got "
                        f"{len(object_transform)}")
    return keyframes


def _hand_for(kf: Keyframe, name: str | None, cache: dict[str, Hand]) -> Hand:
    """The named hand, else of the hands whose palm body is the keyframe's the one that shares
    most finger joint names with it (:func:`joint_vector` then names any it lacks); for a
    keyframe that names neither (srh.txt), the one hand whose folder declares its format."""
    if name is None and kf.palm_body is None:
        name = _declaring_hand(kf)
    if name is None:
        given = set(kf.joints)
        shared = {}
        for candidate in hand_names():
            cfg = load_hand_config(candidate)
            if cfg.palm.body == kf.palm_body:
                shared[candidate] = len(given & {j for f in cfg.fingers for j in f.joints})
        if not shared:
            raise DemoError(f"{kf.where}: no hand in configs/hands has the palm body "
                            f"{kf.palm_body!r} (give --hand)")
        name = max(shared, key=lambda k: shared[k])
    if name not in cache:
        cache[name] = Hand.load(name)
    hand = cache[name]
    body = kf.palm_body if kf.palm_body is not None else srh_format(kf, hand).body
    if body != hand.config.palm.body:
        raise DemoError(f"{kf.where}: pose of body {body!r}, but hand {hand.name!r} has "
                        f"the palm body {hand.config.palm.body!r}")
    return hand


def _declaring_hand(kf: Keyframe) -> str:
    """The hand whose folder declares the keyframe's format (``[formats.srh_txt]``): the file
    names no hand, so the declaration says whose it is; none or several: refused."""
    declaring = [h for h in hand_names() if SRH_FORMAT in load_hand_config(h).formats]
    if len(declaring) != 1:
        who = (f"the hands {declaring} all declare" if declaring
               else "no hand in configs/hands declares")
        raise DemoError(f"{kf.where}: a {kf.format} file names no hand, and {who} "
                        f"[formats.{SRH_FORMAT}] (give --hand)")
    return declaring[0]


def _import_one(path: Path, kf: Keyframe, hand: Hand,
                transform: tuple[np.ndarray, np.ndarray] | None, tolerance_m: float,
                note: str) -> ImportedDemo:
    q, left_out = joint_vector(kf, hand)
    try:
        obj = load_object(kf.object)
    except AssetError as exc:
        raise DemoError(f"{kf.where}: object {kf.object!r} is not installed here ({exc})") from None
    obj_world = (kf.object_pos_m, kf.object_quat_wxyz)
    if transform is not None:
        obj_world = pose_mul(*obj_world, *transform)
    cfg = hand.config.palm
    palm_world = pose_mul(kf.palm_pos_m, kf.palm_quat_wxyz, cfg.pos, cfg.quat_wxyz)
    world_to_obj = pose_inv(*obj_world)
    grasp = Grasp.from_arrays(*pose_mul(*world_to_obj, *palm_world), q)

    config = ValidateConfig.load()
    config = dataclasses.replace(config, common=dataclasses.replace(
        config.common, contact_search_m=tolerance_m))
    validator = Validator(hand, obj, config)
    centroids = validator.fingertip_contacts(grasp)
    scene = _placed(validator, grasp)
    distance: dict[str, float | None] = {}
    tips: dict[str, np.ndarray] = {}
    points: dict[str, np.ndarray] = {}
    for finger in hand.config.fingers:
        d, tip_local, obj_point = _closest(scene, finger.tip_body)
        distance[finger.name] = None if d >= FAR_M else d
        if d <= tolerance_m:
            found = centroids.get(finger.name)
            tips[finger.name] = tip_local if found is None else found
            points[finger.name] = obj_point[None]
    shown = ", ".join(f"{k} {_mm(v)}" for k, v in distance.items())
    if not tips:
        raise DemoError(f"{kf.where}: no fingertip within {tolerance_m * 1e3:g} mm of "
                        f"{obj.name} ({shown}); not a grasp of it")
    demo = Demo(id=f"{path.stem}@{obj.name}", hand=hand.name, object=obj.name, joints=q,
                palm_pos_m=grasp.palm_pos, palm_quat_wxyz=grasp.palm_quat_wxyz,
                tip_contacts=tips, contact_points_obj=points, source=path.resolve(), time_s=0.0,
                how="import", fingers=tuple(sorted(tips)),
                table=None if kf.table_top_z_m is None else _table(kf.table_top_z_m, obj_world))
    provenance = {
        "file": str(path.resolve()), "format": kf.format, "entry": kf.entry,
        "object_transform": None if transform is None else [*transform[0], *transform[1]],
        "tolerance_mm": tolerance_m * 1e3, "far_mm": FAR_M * 1e3,
        "tip_distance_mm": {k: None if v is None else round(v * 1e3, 3)
                            for k, v in distance.items()},
        "joints_left_out": left_out, "note": note}
    return ImportedDemo(demo, distance, provenance)


def _placed(validator: Validator, grasp: Grasp) -> Scene:
    """The validator's lift-drop scene with ``grasp`` placed as the validator places it
    (object at home, frame_palm at :meth:`Validator.palm_world`), kinematics only."""
    scene = validator.scene("lift-drop")
    scene.reset_with_grasp(*Validator.palm_world(grasp), grasp.joints)
    return scene


def _closest(scene: Scene, tip_body: str) -> tuple[float, np.ndarray, np.ndarray]:
    """Signed distance (m, capped at :data:`FAR_M`) of a tip body's collision geoms to the
    object's, and the closest points: on the tip (tip body frame), on the object (object frame)."""
    m, d = scene.model, scene.data
    body = m.body(HAND_PREFIX + tip_body).id
    collides = (m.geom_contype | m.geom_conaffinity) != 0
    best, pair, fromto = FAR_M, np.zeros(6), np.zeros(6)
    for g_tip in np.flatnonzero((m.geom_bodyid == body) & collides):
        for g_obj in np.flatnonzero(scene.obj_geom_mask & collides):
            dist = mujoco.mj_geomDistance(m, d, int(g_tip), int(g_obj), FAR_M, fromto)
            if dist < best:
                best, pair = dist, fromto.copy()
    tip_local = (pair[:3] - d.xpos[body]) @ d.xmat[body].reshape(3, 3)
    inv_p, inv_q = pose_inv(*scene.object_pose())
    return float(best), tip_local, inv_p + rotate(inv_q, pair[3:])


def _table(top_z_m: float, obj_world: tuple[np.ndarray, np.ndarray]) -> dict[str, np.ndarray]:
    """The horizontal table top in the object frame: the point under the object's origin and
    the upward normal."""
    inv_p, inv_q = pose_inv(*obj_world)
    foot = np.array([obj_world[0][0], obj_world[0][1], top_z_m])
    return {"point_m": inv_p + rotate(inv_q, foot), "normal": rotate(inv_q, np.array([0.0, 0.0, 1.0]))}


def _mm(distance_m: float | None) -> str:
    return f"> {FAR_M * 1e3:g} mm" if distance_m is None else f"{distance_m * 1e3:+.2f} mm"


def describe(imported: ImportedDemo) -> str:
    """One line: the demo, its fingers and every fingertip's distance."""
    demo = imported.demo
    dist = ", ".join(f"{k} {_mm(v)}" for k, v in imported.tip_distance_m.items())
    touch = "1 finger touches" if len(demo.fingers) == 1 else f"{len(demo.fingers)} fingers touch"
    return f"{demo.id}: {touch} ({', '.join(demo.fingers)}); {dist}"


def write_imported(imported: Sequence[ImportedDemo], out: Path | None = None, *,
                   force: bool = False) -> list[Path]:
    """Write each demo as ``sim.demo``'s JSON plus a ``provenance`` entry (which ``load_demo``
    ignores), atomically. ``out``: a ``.json`` file (one demo) or a folder (``<object>.json``
    each; default :data:`IMPORTED_DEMOS_DIR`). Every target is checked before any is written:
    an existing file without ``force``, or several demos for one file, writes nothing."""
    out = IMPORTED_DEMOS_DIR if out is None else Path(out)
    if out.suffix == ".json":
        if len(imported) != 1:
            raise DemoError(f"{out}: one file for {len(imported)} demos; give a folder or --object")
        targets = [out]
    else:
        targets = [out / f"{item.demo.object}.json" for item in imported]
        if len(set(targets)) != len(targets):
            raise DemoError(f"{out}: several demos of one object; choose one with --object")
    existing = [str(t) for t in targets if t.exists()]
    if existing and not force:
        raise DemoError(f"{', '.join(existing)}: exists; --force replaces it")
    for target, item in zip(targets, imported, strict=True):
        doc = demo_to_json(item.demo) | {"provenance": item.provenance}
        write_bytes_atomic(target, (json.dumps(doc, indent=1) + "\n").encode())
    return targets
