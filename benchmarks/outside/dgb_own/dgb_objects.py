"""A YCB MJCF object as DexGraspBench expects one: file-format glue for ``run_dgb.py``.

DGB (``util/hand_util.py: MjHO._add_object``) builds its object from every file in
``<obj_path>/urdf/meshes/`` (one convex mesh each, a collision geom and a visual geom per file,
MuJoCo's default contact parameters) and sets their density from
``<obj_path>/info/simplified.json`` so that the object weighs ``obj_mass`` (0.1 kg;
``task/eval_func/base.py``: density = obj_mass / (mass / (density · scale³) · obj_scale³)).
The shared YCB objects are MJCF files whose collision geoms are convex meshes
(``textured_collision_N.obj``) or, for 002–009, one primitive or one ``.msh`` mesh; this writes
each collision geom as an OBJ in the object frame (the MJCF's worldbody frame, which is the
frame the exported grasps use) and an ``info/simplified.json`` whose ``mass`` is the pieces'
volume at density 1000 kg/m³ (measured by MuJoCo itself, as DGB's model will compute it), so
that DGB's formula gives exactly 0.1 kg. A primitive becomes a mesh (DGB takes meshes only): a
box exactly, a cylinder as a 64-gon prism (radius error ≤ 0.05 mm for r = 4 cm), spheres,
ellipsoids and capsules as subdivided icospheres. A mesh geom keeps its vertices (MuJoCo
collides with their convex hull either way). Runs in DGB's side venv: imports nothing of dexaug.
Units: metres, kilograms.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import trimesh

__all__ = ["prepare_object", "ycb_xml"]

#: segments of the prism that stands in for a cylinder primitive
CYLINDER_SECTIONS = 64
#: the density the info file states; any value works, DGB only uses mass / density
INFO_DENSITY_KG_M3 = 1000.0


def ycb_xml(ycb_root: Path, name: str) -> Path:
    """The MJCF file of YCB object ``name`` (``<id>_<name>/<name>.xml``, or any single XML)."""
    folder = ycb_root / name
    files = sorted(folder.glob("*.xml"))
    if not files:
        raise SystemExit(f"run_dgb: no MJCF file for object {name!r} in {folder}")
    return files[0]


def _load_collision_model(xml: Path) -> mujoco.MjModel:
    """The object's MJCF compiled without textures and materials (only the geometry matters;
    several YCB files reference texture files that are absent) and with absolute mesh paths."""
    root = ET.parse(xml).getroot()
    for compiler in root.iter("compiler"):
        mesh_dir = xml.parent / compiler.get("meshdir", compiler.get("assetdir", ""))
        compiler.set("meshdir", str(mesh_dir.resolve()))
        compiler.attrib.pop("texturedir", None)
    if not list(root.iter("compiler")):
        ET.SubElement(root, "compiler", meshdir=str(xml.parent.resolve()))
    for asset in root.iter("asset"):
        for element in list(asset):
            if element.tag in ("texture", "material"):
                asset.remove(element)
    for element in root.iter():
        element.attrib.pop("material", None)
    return mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))


def _primitive(kind: int, size: np.ndarray) -> trimesh.Trimesh:
    """A mesh for a MuJoCo primitive of half-sizes ``size`` in its own frame."""
    g = mujoco.mjtGeom
    if kind == g.mjGEOM_BOX:
        return trimesh.creation.box(extents=2 * size[:3])
    if kind == g.mjGEOM_CYLINDER:
        return trimesh.creation.cylinder(radius=size[0], height=2 * size[1],
                                         sections=CYLINDER_SECTIONS)
    if kind == g.mjGEOM_CAPSULE:
        return trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[32, 32])
    if kind in (g.mjGEOM_SPHERE, g.mjGEOM_ELLIPSOID):
        sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
        radii = size[:3] if kind == g.mjGEOM_ELLIPSOID else np.full(3, size[0])
        sphere.apply_scale(radii)
        return sphere
    raise SystemExit(f"run_dgb: collision geom type {mujoco.mjtGeom(kind).name} has no mesh form")


def _collision_pieces(model: mujoco.MjModel) -> list[trimesh.Trimesh]:
    """Every collision geom (contype or conaffinity set) as a mesh in the object frame."""
    pieces = []
    for i in range(model.ngeom):
        if not (model.geom_contype[i] or model.geom_conaffinity[i]):
            continue
        if model.geom_bodyid[i] != 0:
            raise SystemExit("run_dgb: object geoms are expected in <worldbody> (the YCB layout)")
        if model.geom_type[i] == mujoco.mjtGeom.mjGEOM_MESH:
            m = model.geom_dataid[i]
            v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
            f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
            mesh = trimesh.Trimesh(model.mesh_vert[v0:v0 + nv].astype(float),
                                   model.mesh_face[f0:f0 + nf], process=False)
        else:
            mesh = _primitive(int(model.geom_type[i]), model.geom_size[i])
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[i])
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = rot.reshape(3, 3), model.geom_pos[i]
        mesh.apply_transform(pose)
        pieces.append(mesh)
    if not pieces:
        raise SystemExit("run_dgb: the object has no collision geom")
    return pieces


def _pieces_volume_m3(files: list[Path]) -> float:
    """The pieces' total volume as MuJoCo computes it for DGB's geoms (the mass at density 1)."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="object")
    body.add_freejoint()
    for k, f in enumerate(files):
        spec.add_mesh(name=f"piece{k}", file=str(f))
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"piece{k}", density=1.0)
    return float(spec.compile().body_mass[1])


def prepare_object(ycb_root: Path, name: str, out_root: Path) -> Path:
    """``out_root/<name>`` laid out as a DGB object folder (module docstring); its path."""
    folder = out_root / name
    meshes = folder / "urdf" / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    files = []
    for k, piece in enumerate(_collision_pieces(_load_collision_model(ycb_xml(ycb_root, name)))):
        files.append(meshes / f"convex_piece_{k:03d}.obj")
        piece.export(files[-1])
    volume = _pieces_volume_m3(files)
    info = {"mass": INFO_DENSITY_KG_M3 * volume, "density": INFO_DENSITY_KG_M3, "scale": 1.0}
    (folder / "info").mkdir(exist_ok=True)
    (folder / "info" / "simplified.json").write_text(json.dumps(info))
    return folder
