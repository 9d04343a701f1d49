"""Grasp wrench space metrics (sim.metrics.gws): friction cones, wrenches, Q1 (ε) and volume.

The central check is a closed-form ε for a symmetric cube grasp, cross-checked against an
independent linear program (no Qhull), plus the force-closure conventions (ε = −1 when the origin
is outside or on the boundary), invariances and degenerate inputs.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from sim.metrics.gws import (
    DEGENERATE,
    NO_FORCE_CLOSURE,
    GwsMetrics,
    benchmark,
    contact_wrenches,
    friction_cone_edges,
    gws_metrics,
    gws_metrics_batch,
    tangent_basis,
    wrench_hull_metrics,
)

AXES = np.vstack([np.eye(3), -np.eye(3)])  # outward face normals of a cube: +x +y +z -x -y -z


def ray_gauge(wrenches: np.ndarray, u: np.ndarray) -> float:
    """Distance from the origin to the hull boundary along unit direction ``u``, by LP (no Qhull):
    max t such that t·u = Σ λ_i w_i, Σ λ_i = 1, λ ≥ 0. ε is the minimum of this over directions,
    attained along the nearest facet's normal."""
    m = len(wrenches)
    c = np.zeros(m + 1)
    c[-1] = -1.0
    a_eq = np.zeros((7, m + 1))
    a_eq[:6, :m] = wrenches.T
    a_eq[:6, -1] = -u
    a_eq[6, :m] = 1.0
    b_eq = np.zeros(7)
    b_eq[6] = 1.0
    res = linprog(c, A_eq=a_eq, b_eq=b_eq, bounds=[(0, None)] * m + [(None, None)], method="highs")
    assert res.status == 0, res.message
    return float(res.x[-1])


def random_unit(rng: np.random.Generator, n: int, dim: int) -> np.ndarray:
    v = rng.normal(size=(n, dim))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def sphere_grasp(rng: np.random.Generator, n: int, radius_m: float = 0.04) -> tuple[np.ndarray, np.ndarray]:
    """``n`` contacts on a sphere about the origin, normals pointing roughly inward (tilted so that
    the grasp is not purely radial)."""
    dirs = random_unit(rng, n, 3)
    normals = -dirs + 0.3 * rng.normal(size=(n, 3))
    return radius_m * dirs, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def force_closure_grasp(seed: int, n: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """A random sphere grasp that is in force closure with μ = 0.5 (first seed offset that is)."""
    rng = np.random.default_rng(seed)
    for _ in range(100):
        p, nrm = sphere_grasp(rng, n)
        if gws_metrics(p, nrm, 0.5, torque_scale_m=0.04).epsilon > 0.05:
            return p, nrm
    raise AssertionError("no force-closure grasp found")


# ------------------------------------------------------------------------------ cones & wrenches


def test_cone_edges_are_unit_normal_force_and_evenly_spaced() -> None:
    rng = np.random.default_rng(0)
    # axis-aligned normals (the usual failure point of tangent constructions), near-axis and random
    normals = np.vstack([AXES, AXES + 1e-12, random_unit(rng, 20, 3), [[1.0, 1.0, 1.0]]])
    mu, m = 0.7, 8
    edges = friction_cone_edges(normals, mu, m)
    assert edges.shape == (len(normals), m, 3)
    assert np.isfinite(edges).all()
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("nmk,nk->nm", edges, n), 1.0, atol=1e-12)
    tangential = edges - n[:, None, :]
    np.testing.assert_allclose(np.linalg.norm(tangential, axis=2), mu, atol=1e-12)
    # consecutive edges 2π/m apart about the normal
    cos_step = np.einsum("nmk,nmk->nm", tangential, np.roll(tangential, -1, axis=1)) / mu**2
    np.testing.assert_allclose(cos_step, np.cos(2 * np.pi / m), atol=1e-12)
    t1, t2 = tangent_basis(n)
    np.testing.assert_allclose(np.cross(t1, t2), n, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nk,nk->n", t1, n), 0.0, atol=1e-12)


def test_explicit_tangents_pin_the_cone_phase() -> None:
    rng = np.random.default_rng(1)
    n = random_unit(rng, 6, 3)
    t1, _ = tangent_basis(n)
    # a tangent given with some normal component is projected: same edges as the default basis
    np.testing.assert_allclose(friction_cone_edges(n, 0.5, 8, tangents=t1 + 0.3 * n),
                               friction_cone_edges(n, 0.5, 8), atol=1e-12)
    edges = friction_cone_edges(n, 0.5, 8, tangents=-t1)
    np.testing.assert_allclose(edges[:, 0], n - 0.5 * t1, atol=1e-12)
    with pytest.raises(ValueError, match="parallel"):
        friction_cone_edges(n, 0.5, 8, tangents=2.0 * n)


def test_contact_wrench_torque_and_centre() -> None:
    p = np.array([[0.0, 0.02, 0.0]])
    nrm = np.array([[0.0, -1.0, 0.0]])
    rho = 0.05
    w = contact_wrenches(p, nrm, 0.5, 4, torque_scale_m=rho)
    assert w.shape == (4, 6)
    f = friction_cone_edges(nrm, 0.5, 4)[0]
    np.testing.assert_allclose(w[:, :3], f)
    # (0, r, 0) × (fx, fy, fz) = (r·fz, 0, −r·fx)
    expected_torque = np.stack([0.02 * f[:, 2], np.zeros(4), -0.02 * f[:, 0]], axis=1) / rho
    np.testing.assert_allclose(w[:, 3:], expected_torque, atol=1e-15)
    # moving the grasp and the centre together changes nothing
    c = np.array([0.3, -0.1, 0.7])
    np.testing.assert_allclose(contact_wrenches(p + c, nrm, 0.5, 4, c, torque_scale_m=rho), w, atol=1e-14)


# ------------------------------------------------------------------------------ closed form


@pytest.mark.parametrize("mu", [0.3, 0.5, 1.0])
def test_cube_six_face_centres_closed_form(mu: float) -> None:
    """Six contacts at the face centres of a cube (half-size a), 8-edge cones, torque scale ρ =
    a√3 (the cube's maximum radius from its centre).

    Derivation. Face with outward normal s·e_i (s = ±1, (i, j, l) cyclic): contact p = s·a·e_i,
    force direction n = −s·e_i. The normal has two zero components, so the default tangent is an
    axis (n × e_j) and the 8 tangent directions are c = (cos kπ/4, sin kπ/4) in the (e_j, e_l)
    plane, a set closed under swapping and negating components. Edge force f = n + μc, scaled
    torque p × f / ρ = (a/ρ)·s·μ·(c_j e_l − c_l e_j) (e_i × e_j = e_l, e_i × e_l = −e_j).

    Take the pure-torque direction u* = (0, d), d = (1, 1, 1)/√3. Then u*·w = (a/ρ)·μ·s·(c_j − c_l)/√3,
    whose maximum over the octagon is √2 (at c = ±(1, −1)/√2), on every face. So the support value
    h(u*) = μ·(a/ρ)·√(2/3) = μ·√2/3 for ρ = a√3, reached by exactly one edge per face. Those 6
    wrenches span a 5D affine plane (checked below), so {u*·w = h(u*)} is a facet and
    ε = min_u h(u) ≤ μ√2/3.

    That no facet is closer: for pure torques, pairing the two faces of each axis gives
    h ≥ μ(a/ρ)·g(T_j, T_l) with g the octagon support function max(|x|, |y|, (|x| + |y|)/√2);
    with |T_1| ≥ |T_2| ≥ |T_3| the largest pair term is max(|T_1|, (|T_1| + |T_2|)/√2), which on the
    unit sphere is smallest (√(2/3)) at the diagonal. Mixed force/torque directions are not
    closer: checked here with an LP gauge (no Qhull) along random 6D directions.
    """
    a = 0.03
    rho = a * np.sqrt(3.0)
    centre = np.array([0.1, -0.2, 0.05])
    points = centre + a * AXES
    normals = -AXES
    expected = mu * np.sqrt(2.0) / 3.0

    w = contact_wrenches(points, normals, mu, 8, centre, torque_scale_m=rho)
    u_star = np.concatenate([np.zeros(3), np.ones(3) / np.sqrt(3.0)])
    proj = w @ u_star
    assert proj.max() == pytest.approx(expected, abs=1e-12)
    on_plane = w[np.isclose(proj, expected, atol=1e-12)]
    assert len(on_plane) == 6
    assert np.linalg.matrix_rank(on_plane[1:] - on_plane[0], tol=1e-9) == 5

    metrics = gws_metrics(points, normals, mu, 8, centre, torque_scale_m=rho)
    assert metrics.force_closure
    assert metrics.epsilon == pytest.approx(expected, abs=1e-6)
    assert metrics.volume > 0.0

    # independent LP: the boundary is exactly ε* away along u*, and no closer in any direction
    assert ray_gauge(w, u_star) == pytest.approx(expected, abs=1e-7)
    rng = np.random.default_rng(7)
    gauges = [ray_gauge(w, u) for u in random_unit(rng, 200, 6)]
    assert min(gauges) >= expected - 1e-7


def test_epsilon_matches_lp_on_random_grasp() -> None:
    """On an asymmetric grasp, Qhull's ε must be a lower bound of the LP gauge in every direction
    and equal to it along the nearest facet's normal."""
    p, nrm = force_closure_grasp(seed=3)
    w = contact_wrenches(p, nrm, 0.5, 8, torque_scale_m=0.04)
    eps = gws_metrics(p, nrm, 0.5, torque_scale_m=0.04).epsilon
    hull = ConvexHull(w)
    nearest = hull.equations[np.argmin(-hull.equations[:, -1]), :6]
    assert ray_gauge(w, nearest) == pytest.approx(eps, rel=1e-6)
    rng = np.random.default_rng(8)
    assert min(ray_gauge(w, u) for u in random_unit(rng, 100, 6)) >= eps - 1e-7


# ------------------------------------------------------------------------------ force closure


@pytest.mark.parametrize("seed", range(3))
def test_two_antipodal_contacts_are_not_force_closure(seed: int) -> None:
    """Two point contacts cannot resist torque about the line joining them: every wrench has zero
    moment about that axis, the set spans 5D, so ε = −1 and the 6D volume is 0."""
    rng = np.random.default_rng(seed)
    d = random_unit(rng, 1, 3)[0]
    radius = 0.05
    points = np.array([radius * d, -radius * d])
    normals = np.array([-d, d])
    for mu in (0.5, 2.0):
        assert gws_metrics(points, normals, mu, torque_scale_m=radius) == DEGENERATE
    # the same on a box: centres of two opposite faces
    box = np.array([[0.02, 0.0, 0.0], [-0.02, 0.0, 0.0]])
    assert gws_metrics(box, -box / 0.02, 0.5, torque_scale_m=0.03).epsilon == NO_FORCE_CLOSURE


def test_contacts_on_one_side_give_minus_one() -> None:
    """Four contacts on the top cap of a sphere (within 30° of the pole, normals inward): with
    μ = 0.5 every edge force has f_z <= −cos 30° + 0.5·sin 30° < 0, so the origin is outside a
    full-dimensional hull, and ε is −1 (not a positive distance to the hull)."""
    polar = np.radians([10.0, 30.0, 20.0, 25.0])
    azimuth = np.radians([0.0, 100.0, 200.0, 290.0])
    dirs = np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth),
                            np.cos(polar)])
    assert contact_wrenches(0.04 * dirs, -dirs, 0.5, torque_scale_m=0.04)[:, 2].max() < -0.6
    metrics = gws_metrics(0.04 * dirs, -dirs, 0.5, torque_scale_m=0.04)
    assert metrics.epsilon == NO_FORCE_CLOSURE
    assert not metrics.force_closure
    assert metrics.volume > 0.0


def test_origin_on_the_boundary_is_not_force_closure() -> None:
    """Side contacts tilted up by atan(μ), with one cone edge pinned to point straight down the
    slope, plus a bottom contact: every wrench has f_z ≥ 0 and four are horizontal pure forces
    ±x, ±y, so the origin lies exactly on the facet f_z = 0. Qhull's distance is ~1e-17 of either
    sign; ε must be −1 all the same."""
    mu = 0.5
    alpha = np.arctan(mu)
    up = np.array([0.0, 0.0, 1.0])
    side = AXES[[0, 1, 3, 4]]
    points = np.vstack([0.02 * side, [[0.0, 0.0, -0.02]]])
    normals = np.vstack([-np.cos(alpha) * side + np.sin(alpha) * up, up])
    tangents = np.vstack([-np.sin(alpha) * side - np.cos(alpha) * up, [[1.0, 0.0, 0.0]]])
    w = contact_wrenches(points, normals, mu, 8, torque_scale_m=0.03, tangents=tangents)
    assert w[:, 2].min() == pytest.approx(0.0, abs=1e-15)
    assert abs((-ConvexHull(w).equations[:, -1]).min()) < 1e-12
    metrics = gws_metrics(points, normals, mu, 8, torque_scale_m=0.03, tangents=tangents)
    assert metrics.epsilon == NO_FORCE_CLOSURE
    assert metrics.volume > 0.0


# ------------------------------------------------------------------------------ invariances


@pytest.mark.parametrize("seed", range(3))
def test_rotating_the_grasp_about_the_centre_changes_nothing(seed: int) -> None:
    """Rotation about the centre rotates forces and torques alike (an isometry of wrench space),
    so ε and volume are unchanged when the cone phase turns with the grasp (explicit tangents)."""
    p, nrm = force_closure_grasp(seed=10 + seed)
    centre = np.array([0.01, 0.02, -0.03])
    p = p + centre
    t1, _ = tangent_basis(nrm)
    rot = Rotation.random(random_state=seed)
    before = gws_metrics(p, nrm, 0.5, 8, centre, torque_scale_m=0.05, tangents=t1)
    after = gws_metrics(centre + rot.apply(p - centre), rot.apply(nrm), 0.5, 8, centre,
                        torque_scale_m=0.05, tangents=rot.apply(t1))
    assert before.epsilon > 0.0
    assert after.epsilon == pytest.approx(before.epsilon, rel=1e-9)
    assert after.volume == pytest.approx(before.volume, rel=1e-9)


def test_more_friction_gives_larger_epsilon() -> None:
    """With an even edge count, a μ1 edge is a convex combination of two opposite μ2 > μ1 edges, so
    the GWS only grows with μ; on a generic force-closure grasp ε grows strictly."""
    p, nrm = force_closure_grasp(seed=20)
    eps = [gws_metrics(p, nrm, mu, torque_scale_m=0.04).epsilon for mu in (0.3, 0.5, 0.8, 1.2)]
    assert all(e > 0.0 for e in eps[1:])
    assert np.all(np.diff(eps) > 1e-6), eps


def test_batch_matches_single_calls() -> None:
    grasps = [force_closure_grasp(seed=s) for s in (30, 31)] + [(np.zeros((0, 3)), np.zeros((0, 3)))]
    eps, vol = gws_metrics_batch(grasps, 0.5, torque_scale_m=0.04)
    for (p, n), e, v in zip(grasps, eps, vol, strict=True):
        assert GwsMetrics(float(e), float(v)) == gws_metrics(p, n, 0.5, torque_scale_m=0.04)


# ------------------------------------------------------------------------------ degenerate input


def test_degenerate_inputs_give_no_force_closure() -> None:
    empty = np.zeros((0, 3))
    assert gws_metrics(empty, empty, torque_scale_m=0.05) == DEGENERATE
    # one contact: 8 wrenches, but torque = p × f is linear in f, so they span only 3D
    one = gws_metrics([[0.0, 0.0, 0.05]], [[0.0, 0.0, -1.0]], torque_scale_m=0.05)
    assert one == GwsMetrics(epsilon=-1.0, volume=0.0)
    # frictionless face centres: forces along axes, zero torque about the centre: rank 3
    assert gws_metrics(0.02 * AXES, -AXES, 0.0, torque_scale_m=0.03) == DEGENERATE
    # fewer than 7 wrenches: 2 contacts x 3 edges
    assert gws_metrics(0.02 * AXES[:2], -AXES[:2], 0.5, 3, torque_scale_m=0.03) == DEGENERATE
    assert wrench_hull_metrics(np.zeros((10, 6))) == DEGENERATE


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"points": [[np.nan, 0.0, 0.0]]}, "points: contains NaN"),
    ({"normals": [[0.0, np.inf, 1.0]]}, "normals: contains NaN"),
    ({"points": [0.0, 0.0, 0.0]}, r"points: expected shape \(N, 3\)"),
    ({"normals": [[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]}, r"normals: expected shape \(1, 3\)"),
    ({"normals": [[0.0, 0.0, 0.0]]}, "normals: row 0 has zero length"),
    ({"mu": -0.1}, "mu"),
    ({"mu": np.nan}, "mu"),
    ({"n_edges": 2}, "n_edges"),
    ({"centre": [0.0, 0.0]}, r"centre: expected shape \(3,\)"),
    ({"torque_scale_m": 0.0}, "torque_scale_m"),
])
def test_malformed_inputs_raise_value_error(kwargs: dict, match: str) -> None:
    args = {"points": [[0.0, 0.0, 0.05]], "normals": [[0.0, 0.0, -1.0]], "mu": 0.5, "n_edges": 8,
            "centre": None, "torque_scale_m": 0.05} | kwargs
    with pytest.raises(ValueError, match=match):
        gws_metrics(**args)


def test_malformed_scalars_raise_even_without_contacts() -> None:
    with pytest.raises(ValueError, match="torque_scale_m"):
        gws_metrics(np.zeros((0, 3)), np.zeros((0, 3)), torque_scale_m=-1.0)
    with pytest.raises(ValueError, match="wrenches"):
        wrench_hull_metrics(np.zeros((10, 5)))


def test_benchmark_runs(capsys: pytest.CaptureFixture[str]) -> None:
    assert benchmark(n_calls=5) > 0.0
    assert "ms per call" in capsys.readouterr().out
