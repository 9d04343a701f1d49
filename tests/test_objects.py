"""Objects: procedural primitives and YCB files, loaded with real MuJoCo (no mocks).

Checks the normalised layout (one body ``object`` with a free joint, collision/visual groups),
the contact overrides of the raw YCB values, masses, geometry in the object frame, and that
every known asset defect either is repaired with one warning (missing textures) or raises an
``AssetError`` that names the file.
"""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from sim.errors import AssetError
from sim.paths import YCB_ENV, ycb_root
from sim.world.catalog import list_objects
from sim.world.object_spec import ContactParams
from sim.world.objects import ObjectAsset, load_object
from sim.world.primitives import PRIMITIVES
from tests.conftest import needs_ycb

pytestmark = pytest.mark.slow

# full AABB edge lengths (m) and masses (kg) the primitives are meant to have
INTENDED = {
    "box": ((0.06, 0.06, 0.10), 0.25),
    "cylinder": ((0.066, 0.066, 0.10), 0.35),
    "sphere": ((0.07, 0.07, 0.07), 0.15),
    "bowl": ((0.16, 0.16, 0.05), None),
}
BROKEN = {
    "072_b_toy_airplane": ("airplane_b.xml", "material 'b_toy_airplane_mat' not found"),
    "073_a_lego_duplo": ("lego_a.xml", "does not exist"),
    "073_b_lego_duplo": ("lego_b.xml", "mesh 'b_lego_duplo_collision_0' not found"),
}
# objects whose XML MuJoCo rejects as shipped and sim.world.ycb_xml repairs (one reading only),
# with a fragment of the repair's warning
REPAIRED = {
    "061_foam_brick": "geoms ask for mesh 'foam_brick'",
    "065_c_cups": "removed <geom class='ycb_col'>",
    **{f"073_{c}_lego_duplo": "removed <geom class='ycb_col'>" for c in "cdefg"},
}
CUBE_OBJ = """v -0.01 -0.01 -0.01
v 0.01 -0.01 -0.01
v 0.01 0.01 -0.01
v -0.01 0.01 -0.01
v -0.01 -0.01 0.01
v 0.01 -0.01 0.01
v 0.01 0.01 0.01
v -0.01 0.01 0.01
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
"""


def _layout_ok(obj: ObjectAsset) -> mujoco.MjModel:
    """The compiled spec has one top-level body ``object`` with the free joint, visual geoms in
    group 2 without mass or collisions, collision geoms in group 3."""
    spec = obj.spec()
    assert [b.name for b in spec.worldbody.bodies] == ["object"]
    model = spec.compile()
    body = model.body("object").id
    assert model.nbody == 2 and model.body_parentid[body] == 0
    joint = model.joint("object_free")
    assert joint.type[0] == mujoco.mjtJoint.mjJNT_FREE and joint.bodyid[0] == body
    collision = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    assert collision.any()
    assert np.all(model.geom_group[collision] == 3)
    assert np.all(model.geom_group[~collision] == 2)
    assert np.all(model.geom_contype[collision] == 1) and np.all(model.geom_conaffinity[collision] == 1)
    return model


def _visual_world_aabb(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """World AABB of the visual geoms' vertices, placed by MuJoCo (geom_xpos/xmat)."""
    points = []
    for g in np.flatnonzero((model.geom_contype == 0) & (model.geom_conaffinity == 0)):
        mesh = model.geom_dataid[g]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        vertices = model.mesh_vert[start:start + count].astype(np.float64)
        points.append(vertices @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g])
    points = np.concatenate(points)
    return np.array([points.min(axis=0), points.max(axis=0)])


# ------------------------------------------------------------------------------- primitives


@pytest.mark.parametrize("name", list(PRIMITIVES))
def test_primitive_compiles_with_intended_size_and_mass(name: str) -> None:
    obj = load_object(name)
    assert obj.source == "primitive" and obj.path is None and obj.warnings == []
    _layout_ok(obj)
    extents, mass = INTENDED[name]
    assert obj.mass_kg > 0.05
    if mass is not None:
        assert obj.mass_kg == pytest.approx(mass)
    bounds = obj.surface_mesh().bounds
    np.testing.assert_allclose(bounds[1] - bounds[0], extents, atol=2e-3)
    np.testing.assert_allclose(bounds.mean(axis=0), 0.0, atol=1e-9)   # frame: AABB centre
    np.testing.assert_allclose(obj.collision_mesh().bounds, bounds, atol=2e-3)
    half = (bounds[1] - bounds[0]) / 2
    assert half.max() - 2e-3 <= obj.max_radius_m <= np.linalg.norm(half) + 1e-9


def test_box_radius_and_com() -> None:
    box = load_object("box")
    np.testing.assert_allclose(box.com_m, 0.0, atol=1e-12)
    assert box.max_radius_m == pytest.approx(np.linalg.norm([0.03, 0.03, 0.05]))


def test_bowl_is_concave_from_convex_pieces() -> None:
    bowl = load_object("bowl")
    model = bowl.model
    assert int(((model.geom_contype != 0)).sum()) == 25          # bottom + 24 wall pieces
    surface = bowl.surface_mesh()
    assert surface.is_watertight and surface.volume > 0
    assert surface.volume < 0.2 * surface.convex_hull.volume     # thin walls, open top
    assert 0.12 < bowl.mass_kg < 0.2
    # the centre of mass sits low (heavy bottom), inside the hollow
    assert bowl.com_m[2] < -0.005
    # rays from the middle of the cavity meet the inner bottom (4 mm above the outer bottom) and
    # the inner wall faces (4 mm inside the 8 cm outer faces, whose centres lie at 7.5° + k·15°)
    model = bowl.spec().compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    collision_only = np.array([0, 0, 0, 1, 0, 0], np.uint8)
    geom = np.zeros(1, np.int32)
    face = np.deg2rad(7.5 + 15 * np.arange(24))
    rays = [([0.002, 0.003, 0.0], [0.0, 0.0, -1.0], 0.021)]   # off the axis, where triangles meet
    rays += [([0.0, 0.0, 0.0], [np.cos(a), np.sin(a), 0.0], 0.076) for a in face]
    for start, direction, distance in rays:
        hit = mujoco.mj_ray(model, data, np.array(start), np.array(direction), collision_only, 1, -1, geom)
        assert hit == pytest.approx(distance, abs=1e-6), direction


def test_contact_params_reach_the_collision_geoms() -> None:
    contact = ContactParams(friction=(0.6, 0.01, 0.0002), solref=(0.01, 0.9),
                            solimp=(0.9, 0.95, 0.002), condim=6)
    model = load_object("cylinder").spec(contact).compile()
    collision = model.geom_contype != 0
    np.testing.assert_allclose(model.geom_friction[collision], [contact.friction])
    np.testing.assert_allclose(model.geom_solref[collision], [contact.solref])
    np.testing.assert_allclose(model.geom_solimp[collision][:, :3], [contact.solimp])
    assert np.all(model.geom_condim[collision] == 6)


def test_spec_is_fresh_and_meshes_are_copies() -> None:
    box = load_object("box")
    first = box.spec()
    first.body("object").add_geom(size=[0.5, 0.5, 0.5])
    assert len(box.spec().geoms) == 2
    mesh = box.surface_mesh()
    mesh.apply_translation([1.0, 0.0, 0.0])
    np.testing.assert_allclose(box.surface_mesh().bounds.mean(axis=0), 0.0, atol=1e-9)


def test_contact_params_are_checked() -> None:
    with pytest.raises(ValueError, match="friction"):
        ContactParams(friction=(0.8, 0.1))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="condim"):
        ContactParams(condim=2)


# --------------------------------------------------------------------- user XML in tmp_path


def _write_object(folder: Path, worldbody: str, assets: str = "", defaults: str = "") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cube.obj").write_text(CUBE_OBJ)
    xml = folder / "thing.xml"
    xml.write_text(f'<mujoco model="thing">\n  <default>{defaults}</default>\n'
                   f'  <asset>{assets}</asset>\n'
                   f"  <worldbody>\n{worldbody}\n  </worldbody>\n</mujoco>\n")
    return xml


def test_user_xml_loads_from_any_cwd(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    xml = _write_object(tmp_path / "obj", '    <geom type="mesh" mesh="cube" mass="0.1"/>',
                        '<mesh name="cube" file="cube.obj"/>')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    obj = load_object(str(xml))
    assert obj.source == "ycb" and obj.path == xml and obj.mass_kg == pytest.approx(0.1)
    _layout_ok(obj)
    # no visual geom: the surface is the collision geom, in the frame of the OBJ file
    np.testing.assert_allclose(obj.surface_mesh().bounds, [[-0.01] * 3, [0.01] * 3], atol=1e-7)
    assert load_object(tmp_path / "obj").mass_kg == pytest.approx(0.1)   # a folder works too


@pytest.mark.parametrize(("worldbody", "assets", "expected"), [
    ('    <geom type="mesh" mesh="cube" mass="0.1">', '<mesh name="cube" file="cube.obj"/>',
     "not well-formed XML"),
    ('    <geom type="mesh" mesh="cube" mass="0.1"/>', '<mesh name="cube" file="absent.obj"/>',
     "absent.obj"),
    ('    <geom type="mesh" mesh="nope" mass="0.1"/>', '<mesh name="cube" file="cube.obj"/>',
     "mesh 'nope' not found"),
    ('    <geom type="box" size=".01 .01 .01" bogus="1"/>', "", "unrecognized attribute: 'bogus'"),
    ('    <site pos="0 0 0"/>', "", "mass"),
])
def test_broken_user_xml_names_file_and_problem(tmp_path: Path, worldbody: str, assets: str,
                                                expected: str) -> None:
    xml = _write_object(tmp_path, worldbody, assets)
    with pytest.raises(AssetError) as info:
        load_object(str(xml))
    message = str(info.value)
    assert str(xml) in message and expected in message
    assert "\n" not in message


def test_one_reading_slips_are_repaired_with_a_warning(tmp_path: Path) -> None:
    # a geom asks for a mesh no mesh is called, and one mesh has no name and no user
    obj = load_object(str(_write_object(tmp_path / "a", '    <geom type="mesh" mesh="thing" mass="0.1"/>',
                                        '<mesh file="cube.obj"/>')))
    assert obj.mass_kg == pytest.approx(0.1) and obj.model.nmesh == 1
    assert len(obj.warnings) == 1 and "geoms ask for mesh 'thing'" in obj.warnings[0]
    # class= on a geom inside <default>: dropped, the block's own settings apply
    obj = load_object(str(_write_object(
        tmp_path / "b", '    <geom class="col" type="mesh" mesh="cube"/>',
        '<mesh name="cube" file="cube.obj"/>',
        '<default class="col"><geom class="col" mass="0.2" condim="4"/></default>')))
    assert obj.mass_kg == pytest.approx(0.2)
    assert len(obj.warnings) == 1 and "default class 'col': removed <geom class='col'>" in obj.warnings[0]


@pytest.mark.parametrize(("worldbody", "assets"), [
    # two names wanted, one unnamed mesh: which is which is a guess
    ('    <geom type="mesh" mesh="a" mass="0.1"/>\n    <geom type="mesh" mesh="b" mass="0.1"/>',
     '<mesh file="cube.obj"/>'),
    # the unnamed mesh is in use under its file name: renaming it would break that geom
    ('    <geom type="mesh" mesh="a" mass="0.1"/>\n    <geom type="mesh" mesh="cube" mass="0.1"/>',
     '<mesh file="cube.obj"/>'),
])
def test_a_slip_with_two_readings_is_not_repaired(tmp_path: Path, worldbody: str, assets: str) -> None:
    with pytest.raises(AssetError, match="mesh 'a' not found"):
        load_object(str(_write_object(tmp_path, worldbody, assets)))


def test_unknown_and_ambiguous_names() -> None:
    with pytest.raises(AssetError, match="box, cylinder, sphere, bowl"):
        load_object("no_such_object")
    with pytest.raises(AssetError, match="does not exist"):
        load_object("/no/such/object.xml")


def test_list_objects_without_ycb_lists_primitives(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(YCB_ENV, str(tmp_path))
    statuses = list_objects()
    assert [s.name for s in statuses] == list(PRIMITIVES)
    assert all(s.ok and s.source == "primitive" and s.mass_kg for s in statuses)


# ---------------------------------------------------------------------------------------- YCB


@needs_ycb
@pytest.mark.parametrize(("name", "mass_kg"), [("004_sugar_box", 0.514), ("005", 0.349)])
def test_ycb_loads_with_overridden_contacts_and_file_mass(name: str, mass_kg: float) -> None:
    obj = load_object(name)
    assert obj.source == "ycb" and obj.name.startswith(name[:3]) and obj.warnings == []
    model = _layout_ok(obj)
    assert obj.mass_kg == pytest.approx(mass_kg)
    collision = model.geom_contype != 0
    defaults = ContactParams()
    np.testing.assert_allclose(model.geom_friction[collision], [defaults.friction])
    assert not np.any(np.isclose(model.geom_friction[collision, 0], 0.1))
    np.testing.assert_allclose(model.geom_solref[collision], [defaults.solref])
    np.testing.assert_allclose(model.geom_solimp[collision][:, :3], [defaults.solimp])
    assert np.all(model.geom_condim[collision] == defaults.condim)
    assert model.ntex >= 1   # these two ship their texture: kept


@needs_ycb
@pytest.mark.parametrize("name", ["004_sugar_box", "005_tomato_soup_can"])
def test_surface_mesh_is_where_mujoco_puts_the_geom(name: str) -> None:
    obj = load_object(name)
    model = obj.spec().compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)   # qpos0: object body at the identity pose
    surface = obj.surface_mesh()
    np.testing.assert_allclose(_visual_world_aabb(model, data), surface.bounds, atol=1e-6)
    # an arbitrary pose moves the surface rigidly
    pos, quat = np.array([0.1, -0.2, 0.3]), np.array([0.8, 0.2, -0.3, 0.4])
    quat /= np.linalg.norm(quat)
    data.qpos[:7] = np.concatenate([pos, quat])
    mujoco.mj_forward(model, data)
    rot = data.xmat[model.body("object").id].reshape(3, 3)
    placed = surface.vertices @ rot.T + pos
    np.testing.assert_allclose(_visual_world_aabb(model, data),
                               [placed.min(axis=0), placed.max(axis=0)], atol=1e-6)
    np.testing.assert_allclose(data.xipos[model.body("object").id], rot @ obj.com_m + pos, atol=1e-9)


@needs_ycb
def test_object_frame_is_the_mesh_file_origin() -> None:
    obj = load_object("004_sugar_box")
    lines = (obj.path.parent / "assets" / "textured.obj").read_text().splitlines()
    raw = np.array([[float(x) for x in line.split()[1:4]] for line in lines if line.startswith("v ")])
    surface = obj.surface_mesh()
    np.testing.assert_allclose(surface.bounds, [raw.min(axis=0), raw.max(axis=0)], atol=1e-6)
    assert obj.max_radius_m == pytest.approx(np.linalg.norm(raw - obj.com_m, axis=1).max(), abs=1e-6)


@needs_ycb
def test_missing_texture_is_dropped_with_one_warning(tmp_path: Path,
                                                     caplog: pytest.LogCaptureFixture) -> None:
    source = ycb_root() / "002_master_chef_can"
    assert not (source / "assets" / "002_master_chef_can.png").exists()
    copy = tmp_path / source.name          # a fresh path: not yet warned in this process
    shutil.copytree(source, copy)
    with caplog.at_level(logging.WARNING, logger="sim.world.objects"):
        obj = load_object(copy)
        again = load_object(str(copy / "master_chef_can.xml"))
    records = [r for r in caplog.records if r.name == "sim.world.objects"]
    assert len(records) == 1
    assert "master_chef_can.xml" in records[0].getMessage()
    assert "002_master_chef_can.png" in records[0].getMessage()
    assert len(obj.warnings) == 1 and again.warnings == obj.warnings
    model = _layout_ok(obj)
    assert model.ntex == 0 and model.nmat == 0
    visual = model.geom_contype == 0
    assert np.all(model.geom_rgba[visual, 3] == 1.0)
    assert obj.mass_kg == pytest.approx(0.414)


@needs_ycb
@pytest.mark.parametrize("name", list(BROKEN))
def test_broken_ycb_objects_raise_naming_the_file(name: str) -> None:
    xml_name, fragment = BROKEN[name]
    with pytest.raises(AssetError) as info:
        load_object(name)
    message = str(info.value)
    assert xml_name in message and fragment in message


@needs_ycb
@pytest.mark.parametrize("name", list(REPAIRED))
def test_repaired_ycb_objects_load_with_the_files_own_geoms_and_masses(name: str) -> None:
    obj = load_object(name)
    assert any(REPAIRED[name] in w for w in obj.warnings)
    model = _layout_ok(obj)
    # every geom of the file is there, with the masses it gives its collision geoms
    geoms = [line for line in obj.path.read_text().splitlines() if "<geom" in line]
    in_worldbody = [g for g in geoms if "mesh=" in g]
    assert model.ngeom == len(in_worldbody)
    masses = [float(g.split('mass="')[1].split('"')[0]) for g in in_worldbody if 'class="ycb_col"' in g]
    assert obj.mass_kg == pytest.approx(sum(masses), rel=1e-6)
    assert np.count_nonzero(model.geom_contype) == len(masses)


@needs_ycb
def test_error_line_numbers_point_into_the_original_file() -> None:
    with pytest.raises(AssetError, match=r"line (\d+)") as info:
        load_object("072_b_toy_airplane")
    line = int(info.value.args[0].split("line ")[1].split()[0])
    original = (ycb_root() / "072_b_toy_airplane" / "airplane_b.xml").read_text().splitlines()
    assert 'material="b_toy_airplane_mat"' in original[line - 1]


@needs_ycb
def test_name_resolution() -> None:
    assert load_object("004").name == "004_sugar_box"
    assert load_object("sugar_box").name == "004_sugar_box"
    with pytest.raises(AssetError, match="ambiguous"):
        load_object("065")


@needs_ycb
def test_list_objects_reports_broken_objects(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="sim.world.objects"):
        statuses = {s.name: s for s in list_objects()}
    assert not [r for r in caplog.records if r.name == "sim.world.objects"]   # returned, not logged
    folders = [p for p in ycb_root().iterdir() if p.is_dir()]
    assert len(statuses) == len(PRIMITIVES) + len(folders)
    for name in BROKEN:
        status = statuses[name]
        assert not status.ok and status.mass_kg is None
        assert status.problem and BROKEN[name][1] in status.problem
    for name in ("box", "bowl", "004_sugar_box", "024_bowl"):
        assert statuses[name].ok and statuses[name].problem is None
    assert statuses["004_sugar_box"].mass_kg == pytest.approx(0.514)
    assert statuses["004_sugar_box"].warnings == []
    assert statuses["012_strawberry"].ok and len(statuses["012_strawberry"].warnings) == 1
    # docs/assets.md's list of loaders that fail is complete: everything else loads
    broken = {n for n, s in statuses.items() if not s.ok}
    assert broken == set(BROKEN)
    assert all(statuses[n].ok and statuses[n].mass_kg for n in REPAIRED)
