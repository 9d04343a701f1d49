"""AutoWS geometry: Poisson-disk sampling, hidden point removal and fingertip contact faces, on
analytic meshes (exact answers) and on the Shadow Hand fingertip mesh."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from augment.geometry.contact_face import contact_face, extra_faces
from augment.geometry.face import ContactFace, ContactFaceError
from augment.geometry.inscribed import inscribed_rect, rect_at_origin
from augment.geometry.pulp import viewpoint, visible_pulp_cloud, visible_pulp_indices
from augment.geometry.sampling import mesh_area_m2, poisson_disk_sample, poisson_radius_m
from augment.geometry.visibility import VisibilityError, hidden_point_removal
from sim.errors import DexaugError

SHADOW_DIR = Path("/work/shared/assets/menagerie/shadow_hand")
SHADOW_TIP = SHADOW_DIR / "assets" / "f_distal_pst.obj"
needs_shadow_tip = pytest.mark.skipif(not SHADOW_TIP.is_file(),
                                      reason=f"Shadow fingertip mesh missing: {SHADOW_TIP}")

# Shadow fingertip frame (rh_ffdistal body = OBJ frame scaled by 0.001): the finger runs along +z
# and flexes about +x towards -y, so the pulp faces -y (checked in test_shadow_directions).
V_F = np.array([0.0, -1.0, 0.0])
V_U = np.array([0.0, 0.0, 1.0])
BOX_EXTENTS = (0.020, 0.010, 0.006)  # metres; top face 20 x 10 mm at z = +3 mm


@pytest.fixture(scope="module")
def box() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=BOX_EXTENTS)


@pytest.fixture(scope="module")
def box_cloud(box: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, float]:
    points, normals = poisson_disk_sample(box.vertices, box.faces, density_per_m2=1e7, seed=3)
    return points, normals, poisson_radius_m(box.area, len(points))


@pytest.fixture(scope="module")
def tip_mesh() -> trimesh.Trimesh:
    if not SHADOW_TIP.is_file():
        pytest.skip(f"Shadow fingertip mesh missing: {SHADOW_TIP}")
    mesh = trimesh.load(SHADOW_TIP, force="mesh")
    return trimesh.Trimesh(mesh.vertices * 0.001, mesh.faces, process=False)


@pytest.fixture(scope="module")
def tip_cloud(tip_mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    return poisson_disk_sample(tip_mesh.vertices, tip_mesh.faces, density_per_m2=2e6, seed=0)


@pytest.fixture(scope="module")
def tip_pulp(tip_cloud: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    return visible_pulp_cloud(*tip_cloud, V_F, V_U)


def _planar_cloud(polygon: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Grid points (plane z = 0, normals +z) inside a convex polygon, plus its vertices, so
    that the convex hull of the cloud is exactly the polygon."""
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    xs, ys = np.arange(lo[0], hi[0] + step / 2, step), np.arange(lo[1], hi[1] + step / 2, step)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    edges = np.roll(polygon, -1, axis=0) - polygon
    cross = edges[:, 0] * (grid[:, None, 1] - polygon[:, 1]) - edges[:, 1] * (
        grid[:, None, 0] - polygon[:, 0])
    inside = np.all(cross >= -1e-12, axis=1)  # counter-clockwise polygon
    at_vertex = np.linalg.norm(grid[:, None] - polygon, axis=2).min(axis=1) < 1e-6 * step
    xy = np.vstack([grid[inside & ~at_vertex], polygon])
    points = np.column_stack([xy, np.zeros(len(xy))])
    return points, np.tile([0.0, 0.0, 1.0], (len(points), 1))


# ---------------------------------------------------------------------------------------------
# Poisson-disk sampling


def test_poisson_exact_count_spacing_and_coverage(box: trimesh.Trimesh) -> None:
    points, normals = poisson_disk_sample(box.vertices, box.faces, n_points=1024, seed=0)
    assert points.shape == normals.shape == (1024, 3)
    r = poisson_radius_m(box.area, 1024)
    nn, _ = cKDTree(points).query(points, k=2)
    assert nn[:, 1].min() >= 0.5 * r
    # coverage: every vertex and a dense surface sample lie within 2 r of a sample
    dense = np.vstack([box.vertices, box.sample(20000, seed=1)])
    gap, _ = cKDTree(points).query(dense)
    assert gap.max() <= 2.0 * r
    # on the surface: each point lies on one of the box faces
    half = np.asarray(BOX_EXTENTS) / 2
    assert np.all(np.isclose(np.abs(points), half, atol=1e-12).any(axis=1))


def test_poisson_normals_unit_and_outward(box: trimesh.Trimesh) -> None:
    points, normals = poisson_disk_sample(box.vertices, box.faces, n_points=500, seed=1)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    assert np.all(np.einsum("ij,ij->i", normals, points) > 0)  # convex, centred at 0
    # a mesh wound inside-out still gets outward normals
    points, flipped = poisson_disk_sample(box.vertices, box.faces[:, ::-1], n_points=500, seed=1)
    assert np.all(np.einsum("ij,ij->i", flipped, points) > 0)


def test_poisson_deterministic_per_seed(box: trimesh.Trimesh) -> None:
    a = poisson_disk_sample(box.vertices, box.faces, n_points=300, seed=7)
    b = poisson_disk_sample(box.vertices, box.faces, n_points=300, seed=7)
    c = poisson_disk_sample(box.vertices, box.faces, n_points=300, seed=8)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])


@needs_shadow_tip
def test_poisson_shadow_fingertip_density(tip_mesh: trimesh.Trimesh,
                                          tip_cloud: tuple[np.ndarray, np.ndarray]) -> None:
    points, normals = tip_cloud
    area = mesh_area_m2(tip_mesh.vertices, tip_mesh.faces)
    assert area == pytest.approx(tip_mesh.area)
    assert len(points) == round(2e6 * area)
    r = poisson_radius_m(area, len(points))
    tree = cKDTree(points)
    nn, _ = tree.query(points, k=2)
    assert nn[:, 1].min() >= 0.5 * r
    gap, _ = tree.query(tip_mesh.vertices)
    assert gap.max() <= 2.0 * r
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    # outward: by the divergence theorem the mean of n·(p - c) over a uniform surface sample is
    # 3 V / A (positive for outward normals, negative for inward ones)
    flux = np.mean(np.einsum("ij,ij->i", normals, points - points.mean(axis=0)))
    assert flux == pytest.approx(3 * tip_mesh.volume / area, rel=0.05)


def test_poisson_rejects_bad_meshes(box: trimesh.Trimesh) -> None:
    with pytest.raises(ValueError, match="vertices"):
        poisson_disk_sample(np.zeros((0, 3)), box.faces, n_points=10, seed=0)
    with pytest.raises(ValueError, match="faces"):
        poisson_disk_sample(box.vertices, np.zeros((0, 3), int), n_points=10, seed=0)
    with pytest.raises(ValueError, match="out of range"):
        poisson_disk_sample(box.vertices, box.faces + 100, n_points=10, seed=0)
    line = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    with pytest.raises(ValueError, match="degenerate"):
        poisson_disk_sample(line, np.array([[0, 1, 2]]), n_points=10, seed=0)
    with pytest.raises(ValueError, match="exactly one"):
        poisson_disk_sample(box.vertices, box.faces, seed=0)
    with pytest.raises(ValueError, match="exactly one"):
        poisson_disk_sample(box.vertices, box.faces, n_points=5, density_per_m2=1e6, seed=0)
    with pytest.raises(ValueError, match="millimetres"):  # a mesh left in millimetres
        poisson_disk_sample(box.vertices * 1000, box.faces, density_per_m2=2e6, seed=0)


# ---------------------------------------------------------------------------------------------
# hidden point removal


@pytest.mark.parametrize("distance_radii", [3.0, 220.0])
def test_hpr_sphere_keeps_the_facing_side(distance_radii: float) -> None:
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.01)
    points, normals = poisson_disk_sample(sphere.vertices, sphere.faces, n_points=3000, seed=0)
    direction = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    eye = direction * distance_radii * 0.01
    kept = np.zeros(len(points), dtype=bool)
    kept[hidden_point_removal(points, eye)] = True
    to_eye = eye - points
    cos = np.einsum("ij,ij->i", normals, to_eye / np.linalg.norm(to_eye, axis=1)[:, None])
    assert kept[cos > 0.1].all()  # the visible cap is kept...
    assert not kept[cos < -0.1].any()  # ...the back side is removed
    assert cos[kept].min() > -0.1  # only a thin silhouette band is uncertain


def test_hpr_rejects_bad_input() -> None:
    pts = np.random.default_rng(0).normal(size=(20, 3))
    with pytest.raises(VisibilityError, match="at least 4"):
        hidden_point_removal(pts[:3], np.array([10.0, 0, 0]))
    with pytest.raises(VisibilityError, match="coincides"):
        hidden_point_removal(pts, pts[5])
    planar = np.column_stack([pts[:, :2], np.zeros(20)])
    with pytest.raises(VisibilityError, match="coplanar"):
        hidden_point_removal(planar, np.array([50.0, 0.0, 0.0]))
    assert issubclass(VisibilityError, ValueError) and issubclass(VisibilityError, DexaugError)


# ---------------------------------------------------------------------------------------------
# contact faces: exact answers on planar polygons and a box


def test_planar_triangle_incircle_and_rectangle() -> None:
    mm = 1e-3
    triangle = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]]) * mm  # legs 4 and 3 mm
    points, normals = _planar_cloud(triangle, 0.05 * mm)
    incentre = np.array([1.0, 1.0, 0.0]) * mm  # inradius (3 + 4 - 5) / 2 = 1 mm
    v_u = np.array([0.0, 1.0, 0.0])
    face = contact_face(points, normals, incentre, v_u=v_u)
    np.testing.assert_allclose(face.centre, incentre, atol=1e-12)
    assert face.radius == pytest.approx(1.0 * mm, rel=1e-9)
    np.testing.assert_allclose(face.normal, [0, 0, 1])
    np.testing.assert_allclose(face.basis[0], v_u)
    np.testing.assert_allclose(np.cross(*face.basis), face.normal, atol=1e-12)
    # the Chebyshev centre of the triangle is the incentre, wherever the query starts
    moved = contact_face(points, normals, [0.7 * mm, 0.5 * mm, 0.0], centre="inscribed")
    np.testing.assert_allclose(moved.centre, incentre, atol=1e-9)
    assert moved.radius == pytest.approx(1.0 * mm, rel=1e-6)
    # largest axis-aligned rectangle in a right triangle: half its area (3 mm²)
    rect = contact_face(points, normals, [1.0 * mm, 0.75 * mm, 0], shape="rect",
                        centre="inscribed", v_u=v_u)
    assert rect.area == pytest.approx(3.0 * mm * mm, rel=1e-4)
    assert rect.radius is None and rect.half_edges is not None


def test_planar_diamond_rectangle_centred_on_point() -> None:
    mm = 1e-3
    diamond = np.array([[2.0, 0.0], [0.0, 1.0], [-2.0, 0.0], [0.0, -1.0]]) * mm
    points, normals = _planar_cloud(diamond, 0.05 * mm)
    face = contact_face(points, normals, [0.0, 0.0, 0.0], shape="rect",
                        v_u=np.array([1.0, 0.0, 0.0]))
    # corners (±a, ±b) with a/2 + b <= 1 mm: the best is a = 1 mm, b = 0.5 mm (area 2 mm²)
    np.testing.assert_allclose(face.half_edges, [[1.0 * mm, 0, 0], [0, 0.5 * mm, 0]],
                               atol=1e-12)
    assert face.area == pytest.approx(2.0 * mm * mm)
    circle = contact_face(points, normals, [0.0, 0.0, 0.0])
    assert circle.radius == pytest.approx(2.0 / np.sqrt(5.0) * mm)  # distance to an edge


@pytest.mark.parametrize("half_mm", [(1.0, 1.0), (2.0, 1.0)], ids=["square", "2:1"])
def test_rect_face_of_a_rectangle_cloud(half_mm: tuple[float, float]) -> None:
    """shape="rect" on a planar cloud filling [-A, A] x [-B, B] (z = 0, normals +z): the face is
    that rectangle, half-edge A along v_u (+x) and B across it (n × v_u = +y), centred at the
    origin, whether centred on the query point there or found anywhere from an off-centre query
    ("inscribed"); centred on an off-centre point, the x half-edge is the distance to the nearer
    side. With v_u along +y the axes swap (first half-edge B along +y, second A along −x)."""
    mm = 1e-3
    a, b = half_mm[0] * mm, half_mm[1] * mm
    points, normals = _planar_cloud(np.array([[-a, -b], [a, -b], [a, b], [-a, b]]), 0.1 * mm)
    face = contact_face(points, normals, [0.0, 0.0, 0.0], shape="rect", v_u=[1.0, 0.0, 0.0])
    assert face.shape == "rect" and face.radius is None
    np.testing.assert_allclose(face.centre, [0.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(face.half_edges, [[a, 0, 0], [0, b, 0]], atol=1e-12)
    assert face.area == pytest.approx(4 * a * b, rel=1e-9)
    assert face.extent_along([1.0, 0.0, 0.0]) == pytest.approx(a, rel=1e-9)
    assert face.extent_along([0.0, 1.0, 0.0]) == pytest.approx(b, rel=1e-9)
    across = contact_face(points, normals, [0.0, 0.0, 0.0], shape="rect", v_u=[0.0, 1.0, 0.0])
    np.testing.assert_allclose(across.half_edges, [[0, b, 0], [-a, 0, 0]], atol=1e-12)

    off = [0.5 * mm, 0.0, 0.0]  # a grid point
    at_point = contact_face(points, normals, off, shape="rect", v_u=[1.0, 0.0, 0.0])
    np.testing.assert_allclose(at_point.centre, off, atol=1e-12)
    np.testing.assert_allclose(at_point.half_edges, [[a - 0.5 * mm, 0, 0], [0, b, 0]], atol=1e-12)
    moved = contact_face(points, normals, off, shape="rect", v_u=[1.0, 0.0, 0.0],
                         centre="inscribed")
    # the LPs work in metres and HiGHS's feasibility tolerance is 1e-7 absolute: the inscribed
    # rectangle may overshoot the hull by about 0.1 µm
    np.testing.assert_allclose(moved.centre, [0.0, 0.0, 0.0], atol=2e-4 * mm)
    np.testing.assert_allclose(moved.half_edges, [[a, 0, 0], [0, b, 0]], atol=2e-4 * mm)


def test_inscribed_rectangles_from_edges() -> None:
    """The polygon given directly as edge normals / offsets ({x: n_i·x <= h_i})."""
    normals = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    # [-2, 2] x [-1, 1]: centred at the origin, the rectangle itself
    assert rect_at_origin(normals, np.array([2.0, 2.0, 1.0, 1.0])) == pytest.approx((2.0, 1.0))
    # [1, 3] x [0, 4] (origin outside): anywhere, the rectangle itself, centre (2, 2)
    xy, a, b = inscribed_rect(normals, np.array([3.0, -1.0, 4.0, 0.0]), 2.0, 4.0)
    np.testing.assert_allclose(xy, [2.0, 2.0], atol=1e-6)
    assert (a, b) == pytest.approx((1.0, 2.0), rel=1e-6)
    # the diamond |x| + |y| <= 1: the best centred rectangle is the square a = b = 1/2
    diamond = np.array([[1.0, 1.0], [-1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]]) / np.sqrt(2.0)
    assert rect_at_origin(diamond, np.full(4, 1 / np.sqrt(2.0))) == pytest.approx((0.5, 0.5))


def test_box_top_face_circle_and_rectangle(box_cloud: tuple[np.ndarray, np.ndarray, float],
                                           ) -> None:
    points, normals, r = box_cloud
    top_centre = np.array([0.0, 0.0, BOX_EXTENTS[2] / 2])
    face = contact_face(points, normals, top_centre)
    np.testing.assert_allclose(face.normal, [0, 0, 1], atol=1e-12)
    assert np.linalg.norm(face.centre - top_centre) < r
    assert 0.005 - 2 * r < face.radius <= 0.005  # inscribed circle of the 20 x 10 mm face
    inscribed = contact_face(points, normals, top_centre, centre="inscribed")
    assert 0.005 - r < inscribed.radius <= 0.005
    assert inscribed.radius >= face.radius
    with pytest.raises(ValueError, match="read-only"):
        face.centre[0] = 1.0

    rect = contact_face(points, normals, top_centre, shape="rect", v_u=[1.0, 0.0, 0.0])
    assert rect.half_edges is not None
    np.testing.assert_allclose(rect.basis[0], [1, 0, 0], atol=1e-12)
    a, b = np.linalg.norm(rect.half_edges, axis=1)
    assert 0.010 - 2 * r < a <= 0.010 and 0.005 - 2 * r < b <= 0.005
    assert rect.area == pytest.approx(4 * a * b)
    assert rect.area > 0.8 * 0.020 * 0.010
    # points of the face are contained, points off the plane or outside are not
    assert face.contains(top_centre, plane_tol_m=1e-4).all()
    assert not face.contains(top_centre + np.array([0, 0, 0.001]), plane_tol_m=1e-4).any()
    assert not face.contains(top_centre + np.array([0.009, 0, 0]), plane_tol_m=1e-4).any()
    assert rect.contains(top_centre + np.array([0.009, 0, 0]), plane_tol_m=1e-4).all()


def test_box_extra_faces() -> None:
    """Top face 40 x 20 mm. A 10 mm circle at x = -10 mm leaves room for an equal face above it
    (+x, centred at x = +10 mm); the side queries (±y, 10 mm beyond the top face's long edges)
    snap to points on the box's rim, where only tiny faces fit, and are dropped."""
    box = trimesh.creation.box(extents=(0.040, 0.020, 0.006))
    points, normals = poisson_disk_sample(box.vertices, box.faces, density_per_m2=3e6, seed=0)
    r = poisson_radius_m(box.area, len(points))
    v_f, v_u = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    main = contact_face(points, normals, [-0.010, 0.0, 0.003], v_u=v_u)
    assert main.radius is not None and 0.010 - 2 * r < main.radius <= 0.010
    extras = extra_faces(points, normals, main, v_f, v_u)
    assert len(extras) == 1
    upper = extras[0]
    np.testing.assert_allclose(upper.normal, [0, 0, 1], atol=1e-12)
    assert np.linalg.norm(upper.centre - (main.centre + np.array([2 * main.radius, 0, 0]))) < r
    assert upper.area >= 0.25 * main.area
    rim = extra_faces(points, normals, main, v_f, v_u, min_area_ratio=0.0)[1:]
    assert all(face.area < 0.05 * main.area for face in rim)
    # a smaller first face (6 mm across) fits a side neighbour on the top face as well
    small = contact_face(points, normals, [0.0, 0.0, 0.003], v_u=v_u, depth_m=0.003)
    small = ContactFace(centre=small.centre, normal=small.normal, shape="circle", radius=0.003,
                        half_edges=None, area=np.pi * 0.003**2, basis=small.basis,
                        centre_index=small.centre_index)
    around = extra_faces(points, normals, small, v_f, v_u)
    assert len(around) == 3
    left = np.cross(v_u, v_f)  # -y here
    for face, direction in zip(around, (v_u, left, -left), strict=True):
        offset = face.centre - small.centre
        assert offset @ direction > 0.004  # queried 6 mm away, snapped within one spacing
        np.testing.assert_allclose(face.normal, [0, 0, 1], atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Shadow fingertip


@needs_shadow_tip
def test_shadow_directions(tip_mesh: trimesh.Trimesh) -> None:
    """The chosen v_u / v_f match the model: the mesh is long along +z, and the distal joint
    flexes the tip towards -y (so the pulp, the contact side, faces -y)."""
    extent = np.ptp(tip_mesh.vertices, axis=0)
    assert np.argmax(extent) == 2 and tip_mesh.centroid[2] > 0
    xml = SHADOW_DIR / "right_hand.xml"
    if not xml.is_file():
        pytest.skip("Shadow MJCF missing")
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(xml))
    joint = model.joint("rh_FFJ1")
    axis, (lo, hi) = model.jnt_axis[joint.id], model.jnt_range[joint.id]
    np.testing.assert_allclose(axis, [1, 0, 0])
    assert lo >= 0 and hi > 0
    tip = np.array([0.0, 0.0, 1.0])
    flexed = tip * np.cos(hi) + np.cross(axis, tip) * np.sin(hi)  # Rodrigues, axis ⟂ tip
    assert flexed @ V_F > 0.9


@needs_shadow_tip
def test_shadow_pulp_cloud_drops_the_nail_side(tip_cloud: tuple[np.ndarray, np.ndarray],
                                               tip_pulp: tuple[np.ndarray, np.ndarray]) -> None:
    points, normals = tip_cloud
    pulp_points, pulp_normals = tip_pulp
    assert 0.2 * len(points) < len(pulp_points) < 0.6 * len(points)
    assert (pulp_normals @ V_F).min() > -0.5
    assert (pulp_normals @ V_F).mean() > 0.5
    # HPR alone (no culling) already removes all but a few rim points of the nail side
    hpr_only = visible_pulp_indices(points, normals, V_F, V_U, cull_backfaces=False)
    nail = normals @ V_F < -0.5
    assert np.sum(normals[hpr_only] @ V_F < -0.5) < 0.02 * nail.sum()
    eye = viewpoint(points, V_F, V_U)
    diag = np.linalg.norm(np.ptp(points, axis=0))
    np.testing.assert_allclose(eye, points.mean(0) + 100 * diag * V_F + 50 * diag * V_U)


@needs_shadow_tip
@pytest.mark.parametrize("shape", ["circle", "rect"])
def test_shadow_contact_faces(tip_pulp: tuple[np.ndarray, np.ndarray], shape: str) -> None:
    points, normals = tip_pulp
    main = contact_face(points, normals, shape=shape, v_u=V_U)  # no demo: cloud centroid
    assert isinstance(main, ContactFace)
    assert main.normal @ V_F > 0.7
    assert 20e-6 < main.area < 400e-6  # a fingertip pad: tens to a few hundred mm²
    np.testing.assert_allclose(main.centre, points[main.centre_index])
    demo = contact_face(points, normals, [0.0, -0.008, 0.026], shape=shape, v_u=V_U)
    assert demo.normal @ V_F > 0 and demo.centre[2] > main.centre[2]
    extras = extra_faces(points, normals, main, V_F, V_U)
    assert 1 <= len(extras) <= 3
    for face in extras:
        assert face.normal @ V_F > 0
        assert face.area >= 0.25 * main.area
        assert face.shape == shape
    centres = {main.centre_index, *(f.centre_index for f in extras)}
    assert len(centres) == 1 + len(extras)


# ---------------------------------------------------------------------------------------------
# bad input


def test_direction_errors() -> None:
    pts = np.random.default_rng(0).normal(size=(30, 3))
    with pytest.raises(ValueError, match=r"v_f.*v_u.*parallel"):
        viewpoint(pts, [0, 0, 1], [0, 0, 2])
    with pytest.raises(ValueError, match="v_f"):
        viewpoint(pts, [0, 0, 0], [0, 0, 1])
    with pytest.raises(ValueError, match="v_u"):
        visible_pulp_cloud(pts, pts, [0, 1, 0], [np.nan, 0, 0])


def test_empty_and_degenerate_clouds() -> None:
    empty = np.zeros((0, 3))
    with pytest.raises(ContactFaceError, match="empty"):
        contact_face(empty, empty, [0.0, 0.0, 0.0])
    with pytest.raises(ContactFaceError, match="empty"):
        viewpoint(empty, V_F, V_U)
    # a line of points with a common normal: no area
    line = np.column_stack([np.linspace(0, 0.01, 20), np.zeros(20), np.zeros(20)])
    up = np.tile([0.0, 0.0, 1.0], (20, 1))
    with pytest.raises(ContactFaceError, match="degenerate"):
        contact_face(line, up, [0.005, 0.0, 0.0])
    # two points only
    with pytest.raises(ContactFaceError, match=">= 3"):
        contact_face(line[:2], up[:2], [0.0, 0.0, 0.0])
    # the centre on the rim of its neighbourhood: zero-size face
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * 1e-3
    pts, nrm = _planar_cloud(square, 1e-4)
    with pytest.raises(ContactFaceError, match="zero size"):
        contact_face(pts, nrm, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="shape"):
        contact_face(pts, nrm, [0.0, 0.0, 0.0], shape="hexagon")  # type: ignore[arg-type]


def test_nothing_facing_the_viewpoint() -> None:
    """A flat patch whose normals point away from the pulp side: HPR sees every point, and
    back-face culling then leaves none."""
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * 1e-2
    points, normals = _planar_cloud(square, 1e-3)
    with pytest.raises(ContactFaceError, match="no fingertip point is visible"):
        visible_pulp_cloud(points, -normals, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    kept, _ = visible_pulp_cloud(points, normals, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    assert len(kept) == len(points)
