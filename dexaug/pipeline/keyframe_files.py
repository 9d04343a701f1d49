"""Static grasp poses in files: the two keyframe formats ``dexaug demo import`` reads.

Each format is read into :class:`Keyframe` records — one grasp as the file states it, in the
world of the scene it was recorded in — so that the import (:mod:`dexaug.pipeline.demo_import`)
does not care which format it came from. Units: metres, radians, quaternions w x y z.

* ``dexaug-eval-keyframes-1`` JSON (``fsg_keyframes/keyframes_shared_frames.json``): under
  ``objects``, per object name, ``object_pos_m``/``object_quat_wxyz`` (our object's own frame in
  the world), ``<palm body>_pos_m``/``<palm body>_quat_wxyz`` (the hand's palm body in the
  world; the body's name tells which hand), ``joints_rad`` (joint name → angle) and optionally
  ``table_top_z_m`` (a horizontal table top at that height).
* The FSG authors' ``srh.txt``: per object five lines, objects separated by blank lines —
  ``ycb_<id>_<name>``; the object body's position; its quaternion; the scene keyframe's
  ``qpos`` (the palm body's position and quaternion, then the hand's joints in the format's
  order, optionally followed by the 7 numbers of the headset camera's free joint); the
  actuator targets (not where the fingers stopped: ignored). Its object poses are those of the
  authors' re-centred meshes, not of our objects' frames, so an import must be told the
  transform between the two (:attr:`Keyframe.foreign_object_frame`). Their table top is at
  z = 0.70 m (the scene's table box; ``fsg_keyframes/README.md``).

srh.txt names no hand and no joints: its 22 values are the FSG authors' Shadow Hand's finger
joints (no wrist) in their model's order. That is the hand's knowledge, so it is declared in the
hand's folder: ``[formats.srh_txt]`` (:data:`SRH_FORMAT`) in
the Shadow Hand's ``configs/hands/<hand>/hand.toml`` gives the body the qpos places and the joint order
(:func:`sim.hand.config.hand_format`); the hand that declares it is the one the import uses, and
a hand that declares none cannot take the file.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sim.demo import DemoError
from sim.hand.config import HandFormat, hand_format
from sim.hand.model import Hand

__all__ = ["FORMAT_JSON", "SRH_FORMAT", "SRH_TABLE_TOP_Z_M", "Keyframe", "joint_vector",
           "read_keyframes", "srh_format"]

FORMAT_JSON = "dexaug-eval-keyframes-1"
#: the hand folder's declaration of the srh.txt format: ``[formats.srh_txt]``
SRH_FORMAT = "srh_txt"
#: the table top of the FSG authors' scene (their table box's top face), metres
SRH_TABLE_TOP_Z_M = 0.70
#: numbers of a free joint's qpos (position + quaternion): the palm body's, the camera's
_FREE = 7


@dataclass(frozen=True)
class Keyframe:
    """One static grasp of a keyframe file, in that file's world.

    Attributes:
        object: the object's name as ``sim.world.objects.load_object`` takes it.
        object_pos_m, object_quat_wxyz: the file's object frame in the world.
        foreign_object_frame: True when that frame is not our object's own (srh.txt: the
            authors' re-centred mesh), so the import needs the object-frame transform.
        palm_body: the body whose pose is given (None: the body of the hand's declaration of
            the format, as srh.txt: :func:`srh_format`).
        palm_pos_m, palm_quat_wxyz: that body in the world.
        joints: joint name → angle (rad), or (srh.txt) the angles of the joints in the order
            the hand's ``[formats.srh_txt]`` declares, possibly followed by the camera's free
            joint.
        table_top_z_m: height of the horizontal table top the object stood on, or None.
        entry: which of the file's keyframes (``objects.024_bowl``, ``line 6``).
        where: the file and entry, for messages (``FILE: objects.024_bowl``, ``FILE:6``).
        format: the file's format name.
    """

    object: str
    object_pos_m: np.ndarray
    object_quat_wxyz: np.ndarray
    foreign_object_frame: bool
    palm_body: str | None
    palm_pos_m: np.ndarray
    palm_quat_wxyz: np.ndarray
    joints: dict[str, float] | tuple[float, ...]
    table_top_z_m: float | None
    entry: str
    where: str
    format: str


def numbers(value: Any, n: int, where: str, what: str) -> np.ndarray:
    """``value`` as ``n`` finite numbers, else a one-line error naming ``where`` and ``what``."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.empty(0)
    if a.shape != (n,) or not np.isfinite(a).all():
        raise DemoError(f"{where}: expected {what} ({n} finite numbers), got {value!r}")
    return a


def unit_quat(value: Any, where: str) -> np.ndarray:
    """A quaternion w x y z normalised, when it is one up to the files' rounding (±1 %)."""
    q = numbers(value, 4, where, "a unit quaternion w x y z")
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > 1e-2:
        raise DemoError(f"{where}: expected a unit quaternion w x y z, got norm {norm:.4f}")
    return q / norm


def read_keyframes(path: Path | str) -> list[Keyframe]:
    """The keyframes of ``path``: ``.json`` is the dexaug keyframe JSON, anything else the
    srh.txt text format (module docstring). Errors name the file, the entry and the field."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise DemoError(f"{path}: cannot read the keyframe file ({exc})") from None
    keyframes = _read_json(path, text) if path.suffix == ".json" else _read_srh(path, text)
    if not keyframes:
        raise DemoError(f"{path}: holds no keyframe")
    return keyframes


def _read_json(path: Path, text: str) -> list[Keyframe]:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DemoError(f"{path}: not JSON ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT_JSON:
        raise DemoError(f"{path}: field 'format' must be {FORMAT_JSON!r}")
    objects = doc.get("objects")
    if not isinstance(objects, dict):
        raise DemoError(f"{path}: field 'objects' must map object names to keyframes")
    return [_json_keyframe(path, str(name), entry) for name, entry in objects.items()]


def _json_keyframe(path: Path, name: str, entry: Any) -> Keyframe:
    where = f"{path}: objects.{name}"
    if not isinstance(entry, dict):
        raise DemoError(f"{where}: expected an object of poses and joints")
    bodies = [k.removesuffix("_pos_m") for k in entry if k.endswith("_pos_m") and k != "object_pos_m"]
    if len(bodies) != 1:
        raise DemoError(f"{where}: expected one '<palm body>_pos_m' besides 'object_pos_m', got "
                        f"{bodies or 'none'}")
    body = bodies[0]
    joints = entry.get("joints_rad")
    if not isinstance(joints, dict) or not joints:
        raise DemoError(f"{where}.joints_rad: expected joint name → angle (rad)")
    angles = {str(k): float(numbers([v], 1, f"{where}.joints_rad.{k}", "an angle in radians")[0])
              for k, v in joints.items()}
    table = entry.get("table_top_z_m")
    return Keyframe(
        object=name,
        object_pos_m=numbers(entry.get("object_pos_m"), 3, f"{where}.object_pos_m", "a position in m"),
        object_quat_wxyz=unit_quat(entry.get("object_quat_wxyz"), f"{where}.object_quat_wxyz"),
        foreign_object_frame=False, palm_body=body,
        palm_pos_m=numbers(entry.get(f"{body}_pos_m"), 3, f"{where}.{body}_pos_m", "a position in m"),
        palm_quat_wxyz=unit_quat(entry.get(f"{body}_quat_wxyz"), f"{where}.{body}_quat_wxyz"),
        joints=angles,
        table_top_z_m=None if table is None else float(
            numbers([table], 1, f"{where}.table_top_z_m", "a height in m")[0]),
        entry=f"objects.{name}", where=where, format=FORMAT_JSON)


def _read_srh(path: Path, text: str) -> list[Keyframe]:
    """srh.txt: blocks of five non-blank lines (module docstring)."""
    blocks: list[list[tuple[int, str]]] = [[]]
    for n, line in enumerate(text.splitlines(), 1):
        if line.strip():
            blocks[-1].append((n, line.strip()))
        elif blocks[-1]:
            blocks.append([])
    out = []
    for block in (b for b in blocks if b):
        first = block[0][0]
        if len(block) != 5:
            raise DemoError(f"{path}:{first}: expected 5 lines per object (name, position, "
                            f"quaternion, qpos, ctrl), got {len(block)}")
        (_, name), (n_pos, pos), (n_quat, quat), (n_qpos, qpos_line) = block[:4]
        fields = qpos_line.split()
        qpos = numbers(fields, len(fields), f"{path}:{n_qpos}", "qpos")
        if len(qpos) <= _FREE:
            raise DemoError(f"{path}:{n_qpos}: expected qpos = the palm body's position and "
                            f"quaternion, then the finger joints; got {len(qpos)} numbers")
        out.append(Keyframe(
            object=name.removeprefix("ycb_"),
            object_pos_m=numbers(pos.split(), 3, f"{path}:{n_pos}", "the object position in m"),
            object_quat_wxyz=unit_quat(quat.split(), f"{path}:{n_quat}"),
            foreign_object_frame=True, palm_body=None,
            palm_pos_m=qpos[:3], palm_quat_wxyz=unit_quat(qpos[3:_FREE], f"{path}:{n_qpos}"),
            joints=tuple(float(v) for v in qpos[_FREE:]), table_top_z_m=SRH_TABLE_TOP_Z_M,
            entry=f"line {first}", where=f"{path}:{first}", format="srh.txt"))
    return out


def srh_format(keyframe: Keyframe, hand: Hand) -> HandFormat:
    """``hand``'s declaration of the srh.txt format (:data:`SRH_FORMAT`): the body its qpos
    places and its joint order; a hand that declares none is refused in one line."""
    return hand_format(hand.config, SRH_FORMAT, hand.joint_names,
                       f"take the {keyframe.format} keyframe {keyframe.where}")


def joint_vector(keyframe: Keyframe, hand: Hand) -> tuple[np.ndarray, list[str]]:
    """The hand's full joint vector (model order, rad) of ``keyframe``, and the joints the file
    leaves out (set to 0). Every finger joint must be given; a joint that is no finger's (a
    wrist) may be left out, as the FSG authors' hand has no wrist joints."""
    finger_joints = [j for j in hand.joint_names
                     if any(j in f.joints for f in hand.config.fingers)]
    if isinstance(keyframe.joints, tuple):
        values, order = keyframe.joints, srh_format(keyframe, hand).joint_order
        if len(values) not in (len(order), len(order) + _FREE):
            raise DemoError(f"{keyframe.where}: qpos holds {_FREE + len(values)} numbers; hand "
                            f"{hand.name!r} needs {_FREE} (palm body pose) + {len(order)} "
                            f"(its [formats.{SRH_FORMAT}] joints) [+ {_FREE} (camera free joint)]")
        named = dict(zip(order, values, strict=False))
    else:
        named = keyframe.joints
    field = f"{keyframe.where}.joints_rad"
    unknown = sorted(set(named) - set(hand.joint_names))
    if unknown:
        raise DemoError(f"{field}: {unknown} are not joints of hand {hand.name!r} (its joints: "
                        f"{', '.join(hand.joint_names)})")
    missing = [j for j in finger_joints if j not in named]
    if missing:
        raise DemoError(f"{field}: no angle for the finger joints {missing} of hand {hand.name!r}")
    left_out = [j for j in hand.joint_names if j not in named]
    return np.array([named.get(j, 0.0) for j in hand.joint_names]), left_out
