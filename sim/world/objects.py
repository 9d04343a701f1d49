"""Graspable objects: YCB MJCF files and procedural primitives behind one ``ObjectAsset`` type.

``load_object`` turns an object name or file into an :class:`ObjectAsset`: a YCB-style XML is
repaired by :func:`sim.world.ycb_xml.prepare_ycb_xml`, a primitive comes from
:mod:`sim.world.primitives`, and both give a normalised ``mujoco.MjSpec`` (the layout and
contact parameters of :mod:`sim.world.object_spec`). The object is compiled once at load, so a
broken file raises an ``AssetError`` that names the file and quotes MuJoCo's message, and
missing textures are logged once per object.

Geometry is read back from the compiled model, in the object body frame (the object frame,
``frame_obj`` in DESIGN §3; see :mod:`sim.world.geom_mesh`). Units: metres, kilograms.
"""

from __future__ import annotations

import logging
import multiprocessing
from collections.abc import Callable, Iterable
from functools import cached_property
from pathlib import Path

import mujoco
import numpy as np
import trimesh

from sim.errors import AssetError
from sim.paths import ycb_root
from sim.world.geom_mesh import concatenate, geom_mesh
from sim.world.object_spec import BODY_NAME, FREE_JOINT_NAME, ContactParams, finish_spec
from sim.world.primitives import PRIMITIVES
from sim.world.ycb_xml import ObjectLoadError, diagnose_xml, prepare_ycb_xml

__all__ = ["ObjectAsset", "find_object_xml", "load_object", "load_object_xml", "load_primitive",
           "one_line", "ycb_folders"]

logger = logging.getLogger(__name__)

# Objects (resolved XML paths) whose missing textures were already logged: warn once per object.
_WARNED_TEXTURES: set[str] = set()


def one_line(message: str) -> str:
    """A (MuJoCo) message on one line: its non-empty lines joined by "; "."""
    return "; ".join(part.strip() for part in str(message).strip().splitlines() if part.strip())


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
            raise self._error(f"MuJoCo rejects the XML: {one_line(str(exc))}") from None
        return finish_spec(spec, contact or ContactParams())

    @cached_property
    def model(self) -> mujoco.MjModel:
        """The object alone, compiled with the default ``ContactParams`` (for geometry and mass)."""
        spec = self.spec()
        try:
            model = spec.compile()
        except Exception as exc:
            raise self._error(f"MuJoCo cannot compile the object: {one_line(str(exc))}"
                              f"{diagnose_xml(self.path)}") from None
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
        return concatenate([geom_mesh(self.model, g, hull=False) for g in ids])

    @cached_property
    def _collision(self) -> trimesh.Trimesh:
        return concatenate([geom_mesh(self.model, g, hull=True) for g in self._geom_ids[1]])

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


# ---------------------------------------------------------------------------------- loading


def find_object_xml(folder: Path) -> Path:
    """The one object XML in ``folder``; ``ObjectLoadError`` when there is none or several."""
    xmls = sorted(folder.glob("*.xml"))
    if len(xmls) != 1:
        found = ", ".join(x.name for x in xmls) or "none"
        raise ObjectLoadError(folder, f"expected exactly one object XML in the folder, found {found}")
    return xmls[0]


def load_object_xml(path: Path, name: str | None = None, *, log_warnings: bool = True) -> ObjectAsset:
    """The object of a YCB-style XML file, compiled once; named ``name``, else after its YCB
    folder or file. Its warnings (missing textures) are logged once per file unless
    ``log_warnings`` is False (they stay in ``asset.warnings`` either way)."""
    xml, warnings = prepare_ycb_xml(path)
    if name is None:   # a YCB folder (<id>_<name>) names its object; elsewhere the file does
        name = path.parent.name if path.parent.name[:3].isdigit() else path.stem
    asset = ObjectAsset(name, "ycb", path, lambda: mujoco.MjSpec.from_string(xml), warnings)
    _ = asset.model   # validate now: a broken object fails at load, not inside a scene
    key = str(path.resolve())
    if log_warnings and warnings and key not in _WARNED_TEXTURES:
        _WARNED_TEXTURES.add(key)
        # once per run: the process that runs the command warns; its worker processes (FSG,
        # validation), which load the same object, say it at DEBUG only
        level = logging.DEBUG if multiprocessing.parent_process() is not None else logging.WARNING
        for warning in warnings:
            logger.log(level, "%s: %s", path, warning)
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
    object and run (worker processes log it at DEBUG).
    """
    text = str(name_or_path)
    if text in PRIMITIVES:
        return load_primitive(text)
    path = Path(text).expanduser()
    looks_like_path = isinstance(name_or_path, Path) or text.endswith(".xml") or "/" in text
    if looks_like_path or path.exists():
        if path.is_dir():
            return load_object_xml(find_object_xml(path), path.name)
        if not path.is_file():
            raise AssetError(f"object file {path} does not exist")
        return load_object_xml(path)
    folder = _resolve_ycb(text)
    return load_object_xml(find_object_xml(folder), folder.name)
