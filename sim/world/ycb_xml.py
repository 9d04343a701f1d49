"""The repairs that make a packaged YCB MJCF file loadable: :func:`prepare_ycb_xml`.

Why this module exists: the YCB MJCF packaging cannot be dropped into a scene as it is. Its geoms
sit directly in ``<worldbody>`` (no body, no free joint), most files reference a texture file
that is absent, paths are relative to the file, and a few do not load at all. The XML is
rewritten here, before MuJoCo sees it: the worldbody is wrapped into the object body layout of
:mod:`sim.world.object_spec`, file paths become absolute, missing textures are dropped (with
their materials) and reported as warnings, and line numbers of the original file are kept so
MuJoCo's messages still point into it.

Two packaging slips that have exactly one reading are repaired too, each with a warning that
names it (:func:`_drop_classes_inside_defaults`, :func:`_name_the_unnamed_mesh`): a ``class=``
on an element inside a ``<default>`` (MuJoCo's schema has no such attribute there; 065_c and
073_b…g of the shared YCB set) and a geom asking for a mesh name that no mesh has while exactly
one mesh has no name and no user (061). Anything that needs a guess — a mesh file that is not
there, geoms naming another object's assets — stays an :class:`ObjectLoadError` naming the
file; :func:`diagnose_xml` adds hints to a file that MuJoCo cannot compile.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

from sim.errors import AssetError
from sim.world.object_spec import BODY_NAME, FREE_JOINT_NAME

__all__ = ["ObjectLoadError", "diagnose_xml", "prepare_ycb_xml"]

FALLBACK_RGBA = "0.7 0.7 0.7 1"   # colour of a geom whose material was dropped with its texture

_FILE_ATTRS = {"mesh": ("file",), "hfield": ("file",), "skin": ("file",),
               "texture": ("file", "fileright", "fileleft", "fileup", "filedown", "filefront",
                           "fileback")}


class ObjectLoadError(AssetError):
    """An object file that cannot be loaded; ``path`` and ``problem`` are kept apart so that a
    listing can show the problem without repeating the path."""

    def __init__(self, path: Path | str, problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = Path(path)
        self.problem = problem


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


def _drop_classes_inside_defaults(root: ET.Element) -> list[str]:
    """Remove ``class`` attributes from the elements inside ``<default>`` blocks; one warning per
    class block. MuJoCo rejects the file with them ("unrecognized attribute: 'class'"): a
    default's settings belong to the block they sit in, so the attribute can only restate that
    block or name another one, and it is dropped. Where it named another block (065_c's visual
    class names the collision one), the settings it may have meant to borrow are ones the block
    sets itself for the physics (contype/conaffinity, mass): what could differ is a visual
    geom's group and colour."""
    warnings = []
    for block in root.iter("default"):
        dropped = []
        for element in block:
            if isinstance(element.tag, str) and element.tag != "default" and "class" in element.attrib:
                dropped.append(f"<{element.tag} class={element.attrib.pop('class')!r}>")
        if dropped:
            warnings.append(f"default class {block.get('class', 'main')!r}: removed "
                            f"{', '.join(dropped)} (an element inside <default> takes its block's "
                            "class; MuJoCo rejects the attribute there)")
    return warnings


def _name_the_unnamed_mesh(root: ET.Element) -> list[str]:
    """Give the one mesh without a ``name`` and without a user the one mesh name that geoms ask
    for and no mesh has (061: ``<mesh file="textured.obj"/>``, which MuJoCo calls "textured",
    and ``<geom mesh="foam_brick">``); a warning says so. Anything less clear-cut is left for
    MuJoCo to reject."""
    meshes = [m for asset in root.iter("asset") for m in asset if m.tag == "mesh"]
    defined = {_default_name(m) for m in meshes}
    wanted = {name for g in root.iter("geom") if (name := g.get("mesh"))}
    missing = sorted(wanted - defined)
    unnamed = [m for m in meshes if "name" not in m.attrib and _default_name(m) not in wanted]
    if len(missing) != 1 or len(unnamed) != 1:
        return []
    unnamed[0].set("name", missing[0])
    return [f"mesh file {Path(unnamed[0].get('file', '')).name!r} has no name and no geom uses "
            f"it, and geoms ask for mesh {missing[0]!r}, which no mesh is called: named it so"]


def prepare_ycb_xml(path: Path) -> tuple[str, list[str]]:
    """The MJCF text of a YCB-style object file made loadable from anywhere, and its warnings.

    Geoms (and everything else) in ``<worldbody>`` are wrapped into ``<body name="object">`` with
    a free joint; mesh, texture and other file paths become absolute; a texture whose file is
    absent is dropped with the materials using it (their geoms get a plain ``rgba``); the two
    one-reading slips of the module docstring are repaired. Contact parameters are set later,
    on the spec. Line numbers of the original file are preserved.
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

    warnings = _drop_classes_inside_defaults(root) + _name_the_unnamed_mesh(root)
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


def diagnose_xml(path: Path | None) -> str:
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
        wanted = {name for g in root.iter("geom") if (name := g.get(tag))}
        undefined = sorted(wanted - defined[tag])
        if undefined:
            hints.append(f"geoms reference undefined {tag}(es) {undefined[:4]}"
                         f"{' …' if len(undefined) > 4 else ''}; defined: {sorted(defined[tag])[:4]}"
                         f"{' …' if len(defined[tag]) > 4 else ''}")
    return f" ({'; '.join(hints)})" if hints else ""
