"""Graspable objects: YCB MJCF files and procedural primitives behind one ``ObjectAsset`` type.

Why this module exists: the YCB MJCF packaging cannot be dropped into a scene as it is. Its geoms
sit directly in ``<worldbody>`` (no body, no free joint), every file hard-codes a friction of 0.1
and a very stiff ``solref`` (objects slip out of any grasp at a 2 ms step), most reference a
texture file that is absent, and a few do not load at all. ``load_object`` turns an object file
into a normalised ``mujoco.MjSpec`` (one body ``object`` with a free joint ``object_free`` at the
mesh origin, collision geoms in group 3 with the contact parameters of ``ContactParams``, visual
geoms in group 2 with no mass), drops missing textures with one warning per object, and turns
every other defect into an ``AssetError`` that names the file and quotes MuJoCo's message.

Geometry is read back from the compiled model, in the object body frame (the object frame,
``frame_obj`` in DESIGN §3): MuJoCo re-centres meshes on their centroid and moves the geom to
compensate, so vertices are taken from ``mesh_vert`` and placed with ``geom_pos``/``geom_quat``.
Units: metres, kilograms.
"""

from __future__ import annotations

import logging
import os
import re
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np
import trimesh

from sim.errors import AssetError
from sim.paths import ycb_root
from sim.world.primitives import PRIMITIVES

logger = logging.getLogger(__name__)

BODY_NAME = "object"
FREE_JOINT_NAME = "object_free"
VISUAL_GROUP = 2
COLLISION_GROUP = 3
FALLBACK_RGBA = "0.7 0.7 0.7 1"   # colour of a geom whose material was dropped with its texture

# Objects (resolved XML paths) whose missing textures were already logged: warn once per object.
_WARNED_TEXTURES: set[str] = set()

_FILE_ATTRS = {"mesh": ("file",), "hfield": ("file",), "skin": ("file",),
               "texture": ("file", "fileright", "fileleft", "fileup", "filedown", "filefront",
                           "fileback")}


@dataclass(frozen=True)
class ContactParams:
    """Contact parameters of the object's collision geoms (MuJoCo ``friction``, ``solref``,
    ``solimp``, ``condim``).

    The defaults replace the raw YCB values (friction 0.1, solref 0.001) that make grasps slip
    and contacts stiff enough to destabilise a 2–4 ms step. ``friction``: sliding, torsional,
    rolling coefficients; ``solref``: time constant (s) and damping ratio; ``solimp``: dmin,
    dmax, width (m).
    """

    friction: tuple[float, float, float] = (0.8, 0.005, 0.0001)
    solref: tuple[float, float] = (0.004, 1.0)
    solimp: tuple[float, float, float] = (0.95, 0.99, 0.001)
    condim: int = 4

    def __post_init__(self) -> None:
        if len(self.friction) != 3 or min(self.friction) < 0:
            raise ValueError(f"ContactParams.friction: expected 3 non-negative numbers, got {self.friction}")
        if len(self.solref) != 2:
            raise ValueError(f"ContactParams.solref: expected 2 numbers, got {self.solref}")
        if len(self.solimp) != 3:
            raise ValueError(f"ContactParams.solimp: expected 3 numbers, got {self.solimp}")
        if self.condim not in (1, 3, 4, 6):
            raise ValueError(f"ContactParams.condim: expected 1, 3, 4 or 6, got {self.condim}")


class ObjectLoadError(AssetError):
    """An object file that cannot be loaded; ``path`` and ``problem`` are kept apart so that a
    listing can show the problem without repeating the path."""

    def __init__(self, path: Path | str, problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = Path(path)
        self.problem = problem


def _one_line(message: str) -> str:
    return "; ".join(part.strip() for part in str(message).strip().splitlines() if part.strip())


def _is_collision(geom: mujoco.MjsGeom) -> bool:
    return geom.contype != 0 or geom.conaffinity != 0


def _finish(spec: mujoco.MjSpec, contact: ContactParams) -> mujoco.MjSpec:
    """Give collision geoms the contact parameters and group 3, visual geoms group 2 and no mass."""
    for geom in spec.geoms:
        if _is_collision(geom):
            geom.group = COLLISION_GROUP
            geom.friction = list(contact.friction)
            geom.solref = list(contact.solref)
            solimp = list(geom.solimp)
            solimp[:3] = contact.solimp
            geom.solimp = solimp
            geom.condim = contact.condim
        else:
            geom.group = VISUAL_GROUP
            geom.mass = 0.0
    return spec


class ObjectAsset:
    """One graspable object: where it came from and how to put it in a scene.

    ``spec(contact)`` gives a fresh ``MjSpec`` to attach (see ``sim.world.scene``); the compiled model
    and the meshes derived from it are computed once and cached. All geometry is in the object
    body frame (the mesh origin for YCB objects, the bounding-box centre for primitives), metres.
    """

    def __init__(self, name: str, source: str, path: Path | None,
                 build: Callable[[], mujoco.MjSpec], warnings: Iterable[str] = ()) -> None:
        self.name = name
        self.source = source            # "ycb" or "primitive"
        self.path = path                # the object XML, None for primitives
        self.warnings: list[str] = list(warnings)
        self._build = build

    def __repr__(self) -> str:
        where = f", path={str(self.path)!r}" if self.path else ""
        return f"ObjectAsset(name={self.name!r}, source={self.source!r}{where})"

    def _error(self, problem: str) -> ObjectLoadError:
        return ObjectLoadError(self.path or f"primitive {self.name!r}", problem)

    def spec(self, contact: ContactParams | None = None) -> mujoco.MjSpec:
        """A fresh spec whose worldbody holds one body ``object`` with the free joint
        ``object_free`` (at the object frame), collision geoms (group 3, ``contact`` applied,
        real masses) and visual geoms (group 2, contype = conaffinity = 0, mass 0)."""
        try:
            spec = self._build()
        except AssetError:
            raise
        except Exception as exc:   # MuJoCo reports XML problems as ValueError
            raise self._error(f"MuJoCo rejects the XML: {_one_line(str(exc))}") from None
        return _finish(spec, contact or ContactParams())

    @cached_property
    def model(self) -> mujoco.MjModel:
        """The object alone, compiled with the default ``ContactParams`` (for geometry and mass)."""
        spec = self.spec()
        try:
            model = spec.compile()
        except Exception as exc:
            raise self._error(f"MuJoCo cannot compile the object: {_one_line(str(exc))}"
                              f"{_diagnose(self.path)}") from None
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, BODY_NAME)
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, FREE_JOINT_NAME)
        if body != 1 or joint < 0 or model.jnt_type[joint] != mujoco.mjtJoint.mjJNT_FREE:
            raise self._error(f"expected one top-level body {BODY_NAME!r} with a free joint "
                              f"{FREE_JOINT_NAME!r}")
        if model.body_subtreemass[body] <= 0:
            raise self._error("the object has no mass (no collision geom with mass)")
        return model

    @property
    def body_id(self) -> int:
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, BODY_NAME)

    @property
    def mass_kg(self) -> float:
        """Total mass (kg): the sum of the collision geoms' masses."""
        return float(self.model.body_subtreemass[self.body_id])

    @property
    def com_m(self) -> np.ndarray:
        """Centre of mass (3,) in the object frame, metres."""
        return self.model.body_ipos[self.body_id].copy()

    @cached_property
    def _geom_ids(self) -> tuple[np.ndarray, np.ndarray]:
        m = self.model
        collision = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        ids = np.arange(m.ngeom)
        return ids[~collision], ids[collision]

    @cached_property
    def _surface(self) -> trimesh.Trimesh:
        visual, collision = self._geom_ids
        ids = visual if len(visual) else collision   # an XML without visual geoms shows its collision
        return _concatenate([_geom_mesh(self.model, g, hull=False) for g in ids])

    @cached_property
    def _collision(self) -> trimesh.Trimesh:
        return _concatenate([_geom_mesh(self.model, g, hull=True) for g in self._geom_ids[1]])

    def surface_mesh(self) -> trimesh.Trimesh:
        """The visual surface in the object frame (metres); a copy the caller may modify."""
        return self._surface.copy()

    def collision_mesh(self) -> trimesh.Trimesh:
        """What MuJoCo collides with, in the object frame (metres): the convex hull of every
        collision mesh and the primitive collision geoms, concatenated (pieces may overlap)."""
        return self._collision.copy()

    @cached_property
    def max_radius_m(self) -> float:
        """Largest distance (m) of a surface vertex from the centre of mass: the torque scale of
        grasp wrench metrics."""
        return float(np.linalg.norm(self._surface.vertices - self.com_m, axis=1).max())


def _concatenate(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    if not meshes:
        return trimesh.Trimesh()
    return meshes[0] if len(meshes) == 1 else trimesh.util.concatenate(meshes)


def _geom_mesh(model: mujoco.MjModel, g: int, *, hull: bool) -> trimesh.Trimesh:
    """Geom ``g`` as a triangle mesh in its body frame (metres)."""
    kind, size = model.geom_type[g], model.geom_size[g]
    t = mujoco.mjtGeom
    if kind == t.mjGEOM_MESH:
        mid = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        vertices = model.mesh_vert[v0:v0 + nv].astype(np.float64)
        if hull:
            mesh = trimesh.convex.convex_hull(vertices)
        else:
            mesh = trimesh.Trimesh(vertices, model.mesh_face[f0:f0 + nf].copy(), process=True)
    elif kind == t.mjGEOM_BOX:
        mesh = trimesh.creation.box(extents=2 * size)
    elif kind == t.mjGEOM_SPHERE:
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=size[0])
    elif kind == t.mjGEOM_ELLIPSOID:
        mesh = trimesh.creation.icosphere(subdivisions=3)
        mesh.apply_scale(size)
    elif kind == t.mjGEOM_CYLINDER:
        mesh = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=64)
    elif kind == t.mjGEOM_CAPSULE:
        mesh = trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[32, 32])
    else:
        raise AssetError(f"geom {g} of the object has type {t(kind).name}, which has no surface mesh")
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[g])
    transform = np.eye(4)
    transform[:3, :3] = rot.reshape(3, 3)
    transform[:3, 3] = model.geom_pos[g]
    mesh.apply_transform(transform)
    return mesh


# ---------------------------------------------------------------------------------- YCB XML


def _remove(parent: ET.Element, child: ET.Element, note: str) -> None:
    """Replace ``child`` by a comment with the same tail and line count (so MuJoCo's line numbers
    still point into the original file)."""
    lines = ET.tostring(child, encoding="unicode").count("\n") - (child.tail or "").count("\n")
    comment = ET.Comment(f" dexaug: {note.replace('--', '- -')} " + "\n" * lines)
    comment.tail = child.tail
    parent[list(parent).index(child)] = comment


def _resolve_dirs(root: ET.Element, xml_dir: Path) -> tuple[Path, Path, bool]:
    """Absolute mesh and texture folders from ``<compiler>``; the XML's folder by default."""
    attrs: dict[str, str] = {}
    for compiler in root.iter("compiler"):
        attrs.update(compiler.attrib)
    asset_dir = attrs.get("assetdir", "")
    mesh_dir = xml_dir / attrs.get("meshdir", asset_dir)
    texture_dir = xml_dir / attrs.get("texturedir", asset_dir)
    return mesh_dir, texture_dir, attrs.get("strippath", "false").lower() == "true"


def _default_name(element: ET.Element, attr: str = "file") -> str:
    """An asset's name: its ``name`` or, as MuJoCo does, its file name without extension."""
    return element.get("name") or Path(element.get(attr, "")).stem


def prepare_ycb_xml(path: Path) -> tuple[str, list[str]]:
    """The MJCF text of a YCB-style object file made loadable from anywhere, and its warnings.

    Geoms (and everything else) in ``<worldbody>`` are wrapped into ``<body name="object">`` with
    a free joint; mesh, texture and other file paths become absolute; a texture whose file is
    absent is dropped with the materials using it (their geoms get a plain ``rgba``). Contact
    parameters are set later, on the spec. Line numbers of the original file are preserved.
    Raises ``ObjectLoadError`` for XML that is not well-formed or has no ``<worldbody>``.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ObjectLoadError(path, f"cannot read the object file: {exc.strerror or exc}") from None
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    try:
        root = ET.fromstring(text, parser=parser)
    except ET.ParseError as exc:
        raise ObjectLoadError(path, f"not well-formed XML: {exc}") from None
    if root.tag != "mujoco":
        raise ObjectLoadError(path, f"not an MJCF file: root element is <{root.tag}>, expected <mujoco>")
    xml_dir = path.resolve().parent
    mesh_dir, texture_dir, strip = _resolve_dirs(root, xml_dir)
    compilers = list(root.iter("compiler"))
    if not compilers:
        compilers = [ET.Element("compiler")]
        compilers[0].tail = ""
        root.insert(0, compilers[0])
    for compiler in compilers:
        compiler.set("meshdir", str(mesh_dir))
        compiler.set("texturedir", str(texture_dir))
        compiler.attrib.pop("assetdir", None)
        compiler.set("strippath", "false")

    warnings: list[str] = []
    dropped_textures: set[str] = set()
    missing_files: list[str] = []
    for asset in root.iter("asset"):
        for element in list(asset):
            attrs = _FILE_ATTRS.get(element.tag if isinstance(element.tag, str) else "", ())
            base = texture_dir if element.tag == "texture" else mesh_dir
            for attr in attrs:
                if attr in element.attrib:
                    rel = Path(element.get(attr, ""))
                    file = base / (rel.name if strip else rel)
                    element.set(attr, str(file))
                    if element.tag == "texture" and not file.is_file():
                        dropped_textures.add(_default_name(element))
                        missing_files.append(str(file.relative_to(xml_dir)
                                                 if file.is_relative_to(xml_dir) else file))
            if element.tag == "texture" and _default_name(element) in dropped_textures:
                _remove(asset, element, f"texture {_default_name(element)!r} dropped, file missing")

    dropped_materials: dict[str, str | None] = {}
    if dropped_textures:
        for asset in root.iter("asset"):
            for element in list(asset):
                if element.tag != "material":
                    continue
                used = {element.get("texture")} | {layer.get("texture") for layer in element.iter("layer")}
                if used & dropped_textures:
                    dropped_materials[element.get("name", "")] = element.get("rgba")
                    _remove(asset, element, f"material {element.get('name')!r} dropped with its texture")
        for element in root.iter():
            material = element.get("material")
            if material is not None and material in dropped_materials:
                del element.attrib["material"]
                if element.tag == "geom" and "rgba" not in element.attrib:
                    element.set("rgba", dropped_materials[material] or FALLBACK_RGBA)
        warnings.append(f"texture file(s) missing ({', '.join(sorted(set(missing_files)))}): dropped "
                        f"texture(s) {sorted(dropped_textures)} and material(s) "
                        f"{sorted(dropped_materials)}; geoms keep a plain colour")

    worldbodies = root.findall("worldbody")
    if not worldbodies:
        raise ObjectLoadError(path, "no <worldbody>: the object has no geoms")
    world = worldbodies[0]
    children = [c for wb in worldbodies for c in wb]
    for extra in worldbodies[1:]:
        root.remove(extra)
    for child in children:   # the wrapper body brings the only free joint
        if child.tag == "body":
            for joint in list(child):
                if joint.tag == "freejoint" or (joint.tag == "joint" and joint.get("type") == "free"):
                    _remove(child, joint, "free joint replaced by object_free")
    for child in list(world):
        world.remove(child)
    body = ET.SubElement(world, "body", name=BODY_NAME)
    body.tail = ""
    free = ET.SubElement(body, "freejoint", name=FREE_JOINT_NAME)
    free.tail = ""
    body.extend(children)

    before_root = text[:m.start()] if (m := re.search(r"<mujoco[\s>/]", text)) else ""
    return "\n" * before_root.count("\n") + ET.tostring(root, encoding="unicode"), warnings


def _diagnose(path: Path | None) -> str:
    """Extra hints for an object that MuJoCo cannot compile: missing folders, names that no
    asset defines (MuJoCo reports only the first)."""
    if path is None:
        return ""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return ""
    hints: list[str] = []
    mesh_dir, _, _ = _resolve_dirs(root, path.resolve().parent)
    if not mesh_dir.is_dir():
        hints.append(f"mesh folder {mesh_dir} does not exist")
    defined = {tag: {_default_name(e) for e in root.iter(tag)} for tag in ("mesh", "material")}
    for tag in ("mesh", "material"):
        wanted = {g.get(tag) for g in root.iter("geom") if g.get(tag)}
        undefined = sorted(wanted - defined[tag])
        if undefined:
            hints.append(f"geoms reference undefined {tag}(es) {undefined[:4]}"
                         f"{' …' if len(undefined) > 4 else ''}; defined: {sorted(defined[tag])[:4]}"
                         f"{' …' if len(defined[tag]) > 4 else ''}")
    return f" ({'; '.join(hints)})" if hints else ""


# ---------------------------------------------------------------------------------- loading


def _find_xml(folder: Path) -> Path:
    xmls = sorted(folder.glob("*.xml"))
    if len(xmls) != 1:
        found = ", ".join(x.name for x in xmls) or "none"
        raise ObjectLoadError(folder, f"expected exactly one object XML in the folder, found {found}")
    return xmls[0]


def _load_xml(path: Path, name: str | None = None, *, log_warnings: bool = True) -> ObjectAsset:
    xml, warnings = prepare_ycb_xml(path)
    if name is None:   # a YCB folder (<id>_<name>) names its object; elsewhere the file does
        name = path.parent.name if path.parent.name[:3].isdigit() else path.stem
    asset = ObjectAsset(name, "ycb", path, lambda: mujoco.MjSpec.from_string(xml), warnings)
    _ = asset.model   # validate now: a broken object fails at load, not inside a scene
    key = str(path.resolve())
    if log_warnings and warnings and key not in _WARNED_TEXTURES:
        _WARNED_TEXTURES.add(key)
        for warning in warnings:
            logger.warning("%s: %s", path, warning)
    return asset


def load_primitive(name: str) -> ObjectAsset:
    """The procedural object ``name`` (see ``sim.world.primitives.PRIMITIVES``)."""
    if name not in PRIMITIVES:
        raise AssetError(f"unknown primitive {name!r}; available: {', '.join(PRIMITIVES)}")
    asset = ObjectAsset(name, "primitive", None, PRIMITIVES[name].build)
    _ = asset.model
    return asset


def ycb_folders(root: Path | None = None) -> list[Path]:
    """The object folders under the YCB root (``<id>_<name>``), sorted; none without a root."""
    root = root if root is not None else ycb_root(required=False)
    if root is None:
        return []
    return sorted(p for p in root.iterdir() if p.is_dir() and p.name[:3].isdigit())


def _resolve_ycb(name: str) -> Path:
    root = ycb_root(required=False)
    folders = ycb_folders(root)
    exact = [f for f in folders if f.name == name]
    if exact:
        return exact[0]
    matches = [f for f in folders if f.name.startswith(f"{name}_") or f.name[4:] == name]
    if len(matches) == 1:
        return matches[0]
    if len(matches) > 1:
        raise AssetError(f"object {name!r} is ambiguous: {', '.join(f.name for f in matches)}")
    if root is None:
        try:
            ycb_root(required=True)
        except AssetError as exc:  # says which variable/path is missing and what to do
            raise AssetError(f"object {name!r} is not a primitive ({', '.join(PRIMITIVES)}) "
                             f"and no YCB objects are available: {exc}") from None
    where = (f"YCB objects under {root}: {folders[0].name} … {folders[-1].name} "
             f"({len(folders)})" if folders else f"no YCB object folders under {root}")
    raise AssetError(f"unknown object {name!r}: expected a primitive ({', '.join(PRIMITIVES)}), "
                     f"a YCB id or folder name ({where}), or a path to an object XML")


def load_object(name_or_path: str | Path) -> ObjectAsset:
    """Load an object by primitive name (``box``, ``cylinder``, ``sphere``, ``bowl``), YCB folder
    name (``004_sugar_box``), unique YCB id or name (``004``, ``sugar_box``), or path to a
    YCB-style XML (or to a folder holding one).

    The object is compiled once here, so a broken file raises ``AssetError`` (naming the file and
    the problem) at load time. Missing texture files are dropped with one logged warning per
    object.
    """
    text = str(name_or_path)
    if text in PRIMITIVES:
        return load_primitive(text)
    path = Path(text).expanduser()
    looks_like_path = isinstance(name_or_path, Path) or text.endswith(".xml") or "/" in text
    if looks_like_path or path.exists():
        if path.is_dir():
            return _load_xml(_find_xml(path), path.name)
        if not path.is_file():
            raise AssetError(f"object file {path} does not exist")
        return _load_xml(path)
    folder = _resolve_ycb(text)
    return _load_xml(_find_xml(folder), folder.name)


@dataclass
class ObjectStatus:
    """One row of ``list_objects``: whether an object loads, and if not, why."""

    name: str
    source: str                     # "ycb" or "primitive"
    path: Path | None
    ok: bool
    problem: str | None = None
    mass_kg: float | None = None
    warnings: list[str] = field(default_factory=list)


def _status(name: str, source: str, load: Callable[[], ObjectAsset], path: Path | None) -> ObjectStatus:
    try:
        asset = load()
    except ObjectLoadError as exc:
        return ObjectStatus(name, source, exc.path if path is None else path, False, exc.problem)
    except Exception as exc:   # a listing reports every broken object instead of stopping
        return ObjectStatus(name, source, path, False, _one_line(str(exc)))
    return ObjectStatus(name, source, asset.path, True, None, asset.mass_kg, list(asset.warnings))


def _ycb_status(folder: Path) -> ObjectStatus:
    xmls = sorted(folder.glob("*.xml"))

    def load() -> ObjectAsset:
        return _load_xml(_find_xml(folder), folder.name, log_warnings=False)
    return _status(folder.name, "ycb", load, xmls[0] if len(xmls) == 1 else folder)


def list_objects(max_workers: int | None = None) -> list[ObjectStatus]:
    """Try to load every primitive and every YCB object under the YCB root; never raises.

    Compiling (mesh files, convex hulls) is nearly all of the cost, about 4 s for the 63 YCB
    objects on two cores; MuJoCo compiles outside the GIL, so objects are compiled on
    ``max_workers`` threads (default ``min(8, CPUs)``), which helps on machines with more cores.
    Warnings (missing textures) are returned in the statuses rather than logged.
    """
    start = time.perf_counter()
    statuses = [_status(name, "primitive", lambda n=name: load_primitive(n), None) for name in PRIMITIVES]
    folders = ycb_folders()
    workers = max_workers or min(8, os.cpu_count() or 1)
    if folders:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            statuses.extend(pool.map(_ycb_status, folders))
    logger.debug("list_objects: %d objects in %.1f s", len(statuses), time.perf_counter() - start)
    return statuses
