"""Hand descriptions read from ``configs/hands/<name>/hand.toml``.

Everything hand-specific (which bodies are fingertips, which joints form a finger, coupling,
fingertip vectors, palm frame, and how other tools' file formats see the hand) lives in these
files, so the rest of dexaug works for any hand MuJoCo can load. This module only parses and
checks the file on its own terms; ``sim.hand.model`` checks it against the model (and
:class:`augment.export.foreign.ForeignHand` a ``[formats.*]`` table, when a format is used).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sim.config import Section, load_toml
from sim.errors import ConfigError
from sim.paths import CONFIG_DIR

HANDS_DIR = CONFIG_DIR / "hands"
DEFAULT_HAND_FILE = HANDS_DIR / "default.toml"
POSTURES = ("open_pose", "preshape_pose", "close_pose")
#: the foreign formats a hand may declare as ``[formats.<name>]``: the FSG authors' HDF5
#: (``augment.export.fsg``), DexGraspBench's per-grasp files (``augment.export.bodex``) and the
#: FSG authors' keyframe text ``srh.txt`` (``dexaug demo import``); a name outside this list is
#: a typo, refused on load
HAND_FORMATS = ("bodex", "fsg", "srh_txt")


@dataclass(frozen=True)
class FingerConfig:
    """One finger: its chain of links (proximal to tip), joints and fingertip description.

    ``v_f`` (fingertip → pulp, the contact side) and ``v_u`` (along the finger toward its tip)
    are unit vectors in the fingertip body frame; ``tip_site_pos`` is the pulp point in metres
    in that frame. ``coupled_to`` maps a follower joint to the joint it copies (the paper's
    FJ1 = FJ2). ``ranges_rad`` holds the manual AutoWS ranges of the independent joints.
    """

    name: str
    tip_body: str
    tip_mesh: str
    links: tuple[str, ...]
    joints: tuple[str, ...]
    coupled_to: dict[str, tuple[str, float]]
    v_f: np.ndarray
    v_u: np.ndarray
    tip_site_pos: np.ndarray
    ranges_rad: dict[str, tuple[float, float]]

    @property
    def site_name(self) -> str:
        return f"dexaug_{self.name}_tip"

    @property
    def independent_joints(self) -> tuple[str, ...]:
        return tuple(j for j in self.joints if j not in self.coupled_to)


@dataclass(frozen=True)
class PalmConfig:
    """``frame_palm``: a body plus a fixed offset; +y points out of the palm face toward the
    object. The palm box (centre, half extents in metres, in frame_palm) is FSG's palm check."""

    body: str
    pos: np.ndarray
    quat_wxyz: np.ndarray
    box_center: np.ndarray
    box_half_extents: np.ndarray


@dataclass(frozen=True)
class Mount:
    """``[mount]``: where the hand sits on an arm. The pose (``pos`` metres, ``quat_wxyz``) of
    the hand model's base frame (the frame ``Hand.body_poses`` reports in) in a generic flange
    frame whose +z is the tool axis pointing out of the arm, so one hand config fits any arm
    whose flange site follows that convention (:mod:`sim.arm.scene`).

    ``ik_free_joints`` (optional) names the hand joints between the mount and the palm (a
    wrist) that the arm's IK may set at a grasp (:mod:`sim.arm.plan`): the fingers stay the
    grasp's and frame_palm is downstream of them, so the grasp is unchanged, but a palm facing
    down onto an object lying flat otherwise needs the forearm level with the table top
    (measured on the flat screwdriver: the UR5e's wrist held off the table), where a person
    bends the wrist and raises the forearm."""

    pos: np.ndarray
    quat_wxyz: np.ndarray
    ik_free_joints: tuple[str, ...] = ()


@dataclass(frozen=True)
class HandFormat:
    """``[formats.<name>]``: this hand as another tool's file format knows it. That tool's hand
    (``their_hand``, said in messages) is placed by the pose of our body ``body`` and lists the
    joints ``joint_order`` (names of our model's joints, radians) in that order; the joints of
    ours it lacks are dropped on export (:mod:`augment.export.foreign` says which may be).
    Why here: the order is a fact about this hand and that tool, not about the exporter, so a
    second hand in the same format is a table in its folder, not a new list in code."""

    name: str
    their_hand: str
    body: str
    joint_order: tuple[str, ...]


@dataclass(frozen=True)
class HandConfig:
    name: str
    file: Path
    menagerie: str | None
    entry: str | None
    model_path: Path | None
    root_body: str | None
    palm: PalmConfig
    fingers: tuple[FingerConfig, ...]
    fingertip_width_m: float   # w_tip of the paper's eq. 2: contact width of one fingertip
    link_radius_m: float       # finger links' radius about their skeleton (FSG's link check)
    postures: dict[str, dict[str, float]] = field(default_factory=dict)
    #: ``[teleop] servo_kp_scale``: this hand's servo gain scale in the teleop bridge, over the
    #: bridge's own (None: the bridge's); a hand whose light links go unstable at the bridge's
    #: scale names a lower one here
    teleop_kp_scale: float | None = None
    #: ``[validate] servo_kp_scale``: this hand's servo gain scale in lift-drop and six-dir,
    #: over ``configs/validate.toml``'s (None: that one); a hand whose servos go numerically
    #: unstable at the protocol's scale names one here, with its reason in the model card
    validate_kp_scale: float | None = None
    #: ``[mount]``: the hand's pose on an arm's flange (None: the hand has no arm mount)
    mount: Mount | None = None
    #: ``[formats.<name>]``: the foreign formats this hand can be written in or read from
    formats: dict[str, HandFormat] = field(default_factory=dict)

    def finger(self, name: str) -> FingerConfig:
        for f in self.fingers:
            if f.name == name:
                return f
        raise ConfigError(f"{self.file}: no finger named {name!r}; fingers are "
                          f"{[f.name for f in self.fingers]}")


def _unit(sec: Section, key: str) -> np.ndarray:
    v = np.array(sec.floats(key, 3))
    n = np.linalg.norm(v)
    if n < 1e-9:
        raise sec.error(key, "expected a non-zero 3-vector")
    return v / n


def _unit_quat(sec: Section, key: str, default: list[float] | None = None) -> np.ndarray:
    quat = np.array(sec.floats(key, 4, default) if default is not None else sec.floats(key, 4))
    if abs(np.linalg.norm(quat) - 1.0) > 1e-6:
        raise sec.error(key, f"expected a unit quaternion (w, x, y, z), got norm {np.linalg.norm(quat)}")
    return quat / np.linalg.norm(quat)


def _mount(root: Section) -> Mount | None:
    """The optional ``[mount]`` table; both keys are required once the table is there (a
    half-given mount would silently put the hand at the flange origin)."""
    if "mount" not in root:
        return None
    sec = root.section("mount")
    sec.reject_unknown({"pos", "quat_wxyz", "ik_free_joints"})
    free = tuple(sec.strs("ik_free_joints", []))
    if len(set(free)) != len(free):
        raise sec.error("ik_free_joints", "expected each joint name once")
    return Mount(pos=np.array(sec.floats("pos", 3)), quat_wxyz=_unit_quat(sec, "quat_wxyz"),
                 ik_free_joints=free)


def _formats(root: Section) -> dict[str, HandFormat]:
    """The optional ``[formats.<name>]`` tables (:class:`HandFormat`), each checked on its own
    terms: a known format name, the three keys, a non-empty joint order without repeats."""
    formats = root.section("formats", {})
    formats.reject_unknown(set(HAND_FORMATS))
    out = {}
    for name in formats.data:
        sec = formats.section(name)
        sec.reject_unknown({"their_hand", "body", "joint_order"})
        order = tuple(sec.strs("joint_order"))
        repeated = sorted({j for j in order if order.count(j) > 1})
        if not order or repeated:
            raise sec.error("joint_order", "expected the format's joints in its order, each once; "
                            f"got {'none' if not order else f'{repeated} more than once'}")
        out[name] = HandFormat(name=name, their_hand=sec.str("their_hand"), body=sec.str("body"),
                               joint_order=order)
    return out


def _finger(sec: Section) -> FingerConfig:
    sec.reject_unknown({"name", "tip_body", "tip_mesh", "links", "joints", "coupled_to", "v_f",
                        "v_u", "tip_site_pos", "ranges_deg"})
    joints = tuple(sec.strs("joints"))
    if not joints:
        raise sec.error("joints", "expected at least one joint")
    coupled_sec = sec.section("coupled_to", {})
    coupled: dict[str, tuple[str, float]] = {}
    for key, value in coupled_sec.data.items():
        if isinstance(value, str):
            coupled[key] = (value, 1.0)
        elif (isinstance(value, list) and len(value) == 2 and isinstance(value[0], str)
              and isinstance(value[1], int | float) and not isinstance(value[1], bool)):
            coupled[key] = (value[0], float(value[1]))
        else:
            raise coupled_sec.error(key, 'expected a leader joint name or [leader, coefficient], '
                                    f'got {value!r}')
    for follower, (leader, _) in coupled.items():
        if follower not in joints or leader not in joints:
            raise coupled_sec.error(follower, f"both {follower!r} and {leader!r} must be among "
                                    f"this finger's joints {list(joints)}")
    v_f, v_u = _unit(sec, "v_f"), _unit(sec, "v_u")
    if np.linalg.norm(np.cross(v_f, v_u)) < 1e-6:
        raise sec.error("v_u", "v_f and v_u are parallel; v_f must point to the pulp and v_u "
                        "along the finger")
    ranges_sec = sec.section("ranges_deg", {})
    ranges: dict[str, tuple[float, float]] = {}
    for joint in ranges_sec.data:
        lo, hi = ranges_sec.floats(joint, 2)
        if joint not in joints or joint in coupled:
            raise ranges_sec.error(joint, "range given for a joint that is not an independent "
                                   f"joint of this finger ({[j for j in joints if j not in coupled]})")
        if lo > hi:
            raise ranges_sec.error(joint, f"empty range [{lo}, {hi}]: expected lower <= upper")
        ranges[joint] = (float(np.deg2rad(lo)), float(np.deg2rad(hi)))
    links = tuple(sec.strs("links"))
    tip_body = sec.str("tip_body")
    if not links or links[-1] != tip_body:
        raise sec.error("links", f"expected the finger's link bodies ending with tip_body "
                        f"{tip_body!r}")
    return FingerConfig(
        name=sec.str("name"), tip_body=tip_body, tip_mesh=sec.str("tip_mesh"), links=links,
        joints=joints, coupled_to=coupled, v_f=v_f, v_u=v_u,
        tip_site_pos=np.array(sec.floats("tip_site_pos", 3)), ranges_rad=ranges)


def hand_dir(name: str) -> Path:
    """The folder of a hand (``configs/hands/<name>/``): everything dexaug knows about that
    hand lives there — ``hand.toml`` (model, palm frame, fingers, workspace ranges),
    ``retarget.toml`` (operator mapping), ``grasps.toml`` (reference grasps), ``README.md``
    (the model card)."""
    return HANDS_DIR / name


def hand_names() -> list[str]:
    """Every hand with a folder under ``configs/hands/`` (sorted)."""
    return sorted(p.parent.name for p in HANDS_DIR.glob("*/hand.toml"))


def default_hand_name() -> str:
    """The hand used wherever none is named: ``hand = "<name>"`` in ``configs/hands/default.toml``,
    checked against the hand folders (the one place a hand's name is chosen for the code)."""
    root = load_toml(DEFAULT_HAND_FILE)
    root.reject_unknown({"hand"})
    return named_hand(root)


def named_hand(sec: Section, key: str = "hand") -> str:
    """The hand a config names under ``key`` (``hand = "<name>"``), checked against the hand
    folders: a one-line error naming the file and key when there is no such folder."""
    name = sec.str(key)
    known = hand_names()
    if name not in known:
        raise sec.error(key, f"no hand folder {hand_dir(name)} with a hand.toml; known hands: "
                        f"{known}")
    return name


def hand_config_path(name_or_path: str | Path) -> Path:
    """The TOML file of a hand given by name (``configs/hands/<name>/hand.toml``) or by path."""
    path = Path(name_or_path)
    return path if path.suffix == ".toml" else hand_dir(str(name_or_path)) / "hand.toml"


def hand_format(cfg: HandConfig, name: str, joint_names: Sequence[str], doing: str) -> HandFormat:
    """``cfg``'s ``[formats.<name>]``. A hand that declares none is refused in one line naming
    its file, a hand that does declare it and the joints of that declaration ours lacks
    (``joint_names``: this hand's model joints), so the reader sees whether copying that table
    would do or this hand is not that tool's hand at all. ``doing``: what was asked, for the
    message (``be written in the fsg layout``)."""
    fmt = cfg.formats.get(name)
    if fmt is not None:
        return fmt
    head = f"hand {cfg.name!r} cannot {doing}: {cfg.file} declares no [formats.{name}]"
    others = [h for h in hand_names() if h != cfg.name and name in load_hand_config(h).formats]
    if not others:
        raise ConfigError(f"{head}, and no hand under {HANDS_DIR} does")
    theirs = load_hand_config(others[0]).formats[name]
    missing = [j for j in theirs.joint_order if j not in joint_names]
    said = (f"{others[0]} declares it ({theirs.their_hand}: body {theirs.body!r}, the "
            f"{len(theirs.joint_order)} joints {theirs.joint_order[0]} … {theirs.joint_order[-1]})")
    more = f" and {len(missing) - 4} more" if len(missing) > 4 else ""
    raise ConfigError(f"{head}; {said}, and hand {cfg.name!r} lacks {', '.join(missing[:4])}{more}"
                      if missing else
                      f"{head}; {said}: copy that table if hand {cfg.name!r} is that hand")


def _kp_scale(sec: Section) -> float | None:
    """A ``servo_kp_scale`` table (``[teleop]``, ``[validate]``): the scale, or None when the
    table does not name one."""
    sec.reject_unknown({"servo_kp_scale"})
    return sec.float("servo_kp_scale", min=0.1, max=100.0) if "servo_kp_scale" in sec else None


def load_hand_config(name_or_path: str | Path) -> HandConfig:
    """Load ``configs/hands/<name>/hand.toml`` (or a TOML path) and check it is self-consistent."""
    path = hand_config_path(name_or_path)
    if Path(name_or_path).suffix != ".toml" and not path.is_file():
        known = hand_names()
        raise ConfigError(f"unknown hand {name_or_path!r}: no {path}; known hands: {known}")
    root = load_toml(path)
    # [power] overrides configs/augment.toml [power] for this hand; augment.power checks it
    root.reject_unknown({"model", "palm", "fingers", "grasp", "geometry", "teleop", "validate",
                         "mount", "power", "formats"})
    teleop_kp, validate_kp = (_kp_scale(root.section(name, {})) for name in ("teleop", "validate"))
    geometry = root.section("geometry")
    geometry.reject_unknown({"fingertip_width_m", "link_radius_m"})
    sizes = {k: geometry.float(k) for k in ("fingertip_width_m", "link_radius_m")}
    for key, value in sizes.items():
        if not (math.isfinite(value) and value > 0):
            raise geometry.error(key, f"expected a positive length in metres, got {value}")
    model = root.section("model")
    model.reject_unknown({"menagerie", "entry", "path", "root_body"})
    menagerie = model.str("menagerie", None)
    model_path = model.str("path", None)
    if (menagerie is None) == (model_path is None):
        raise model.error(None, "expected exactly one of 'menagerie' (a Menagerie robot name) "
                          "or 'path' (an MJCF file, relative to this config)")
    palm = root.section("palm")
    palm.reject_unknown({"body", "pos", "quat_wxyz", "box_center", "box_half_extents"})
    quat = _unit_quat(palm, "quat_wxyz", [1.0, 0.0, 0.0, 0.0])
    half = np.array(palm.floats("box_half_extents", 3))
    if (half <= 0).any():
        raise palm.error("box_half_extents", "expected three positive half extents (metres)")
    fingers = tuple(_finger(s) for s in root.sections("fingers"))
    if not fingers:
        raise root.error("fingers", "expected at least one [[fingers]] table")
    names = [f.name for f in fingers]
    if len(set(names)) != len(names):
        raise root.error("fingers", f"finger names must be unique, got {names}")
    grasp = root.section("grasp", {})
    grasp.reject_unknown(set(POSTURES))
    postures = {}
    for key in POSTURES:
        sec = grasp.section(key, {})
        postures[key] = {k: sec.float(k) for k in sec.data}
    return HandConfig(
        name=path.parent.name if path.name == "hand.toml" else path.stem, file=path,
        menagerie=menagerie, entry=model.str("entry", None),
        model_path=(path.parent / model_path).resolve() if model_path else None,
        root_body=model.str("root_body", None), **sizes,
        palm=PalmConfig(body=palm.str("body"), pos=np.array(palm.floats("pos", 3, [0.0] * 3)),
                        quat_wxyz=quat,
                        box_center=np.array(palm.floats("box_center", 3, [0.0] * 3)),
                        box_half_extents=half),
        fingers=fingers,
        postures=postures,
        teleop_kp_scale=teleop_kp,
        validate_kp_scale=validate_kp,
        mount=_mount(root),
        formats=_formats(root),
    )
