"""FSG (augment.fsg) on YCB objects, object clouds (augment.object_cloud) and the HDF5 dataset
(augment.dataset).

The central checks: every generated grasp satisfies its own claims (contacts inside the claimed
fingertip faces at the stored joint angles by forward kinematics, palm box clear, ε recomputed
from the stored contacts), the grasps pass the MuJoCo lift-and-drop test at a non-trivial rate,
and bad inputs end cleanly (errors naming the problem, time budgets honoured). Q1 hand checks
(antipodal → −1, closed-form cube) live in tests/test_gws.py; FSG's rules on synthetic geometry
(eq. 2, crossing, finger iteration, de-duplication, eq. 3, workers) in tests/test_fsg_rules.py.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from pathlib import Path

import numpy as np
import pytest

from augment import dataset
from augment.fsg.candidates import palm_box_vertices
from augment.fsg.params import FsgError, FsgParams, load_fsg_params
from augment.fsg.result import FsgGrasp
from augment.fsg.run import generate
from augment.fsg.table import TablePlane
from augment.geometry.sampling import poisson_disk_sample
from augment.object_cloud import ObjectCloudError, normal_variation, object_cloud
from sim.errors import DexaugError
from sim.metrics.gws import gws_metrics
from sim.transforms import axis_angle_to_mat, quat_to_mat, rotation_between
from sim.validate.batch import ScenePenetration
from sim.validate.result import ValidationResult
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = pytest.mark.slow

CAN = "005_tomato_soup_can"


# ------------------------------------------------------------------------------ pure helpers


def test_candidate_rotations() -> None:
    """The rotations FSG's step 1 builds candidates with (sim.transforms)."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(50, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = rng.normal(size=(50, 3))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    b[0] = -a[0]   # antiparallel case
    b[1] = a[1]
    r = rotation_between(a, b)
    np.testing.assert_allclose(np.einsum("bij,bj->bi", r, a), b, atol=1e-9)
    np.testing.assert_allclose(r @ r.transpose(0, 2, 1), np.broadcast_to(np.eye(3), r.shape),
                               atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-9)
    rz = axis_angle_to_mat(np.array([[0.0, 0, 1]]), np.array([np.pi / 2]))[0]
    np.testing.assert_allclose(rz @ [1.0, 0, 0], [0, 1, 0], atol=1e-12)


def test_normal_variation_marks_cube_edges() -> None:
    """Curvature filter: on a cube the face interiors stay, points next to edges go."""
    import trimesh

    box = trimesh.creation.box([0.05, 0.05, 0.05])
    pts, nrm = poisson_disk_sample(box.vertices, box.faces, n_points=1024, seed=0)
    c = normal_variation(pts, nrm)
    edge_dist = (0.025 - np.abs(pts)).copy()
    # distance to the nearest edge = second-smallest distance to a face plane
    to_edge = np.sort(edge_dist, axis=1)[:, 1]
    assert np.all(c[to_edge > 0.012] < 1e-6)      # interiors (> ~3 spacings): flat
    assert np.mean(c[to_edge < 0.001] > 0.7) > 0.8  # at the edges: excluded


@needs_menagerie
def test_load_fsg_params_defaults_and_errors(shadow, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    p = load_fsg_params(shadow.config)
    assert (p.outer, p.inner, p.match_distance_m, p.normal_dot) == (200, 15, 0.008, -0.98)
    # the hand's geometry comes from its folder, not from augment.toml
    assert (p.fingertip_width_m, p.link_clearance_m) == (shadow.config.fingertip_width_m,
                                                         shadow.config.link_radius_m)
    bad = tmp_path / "a.toml"
    bad.write_text("[fsg]\nouter = 0\n")
    with pytest.raises(Exception, match="outer"):
        load_fsg_params(shadow.config, bad)
    bad.write_text("[fsg]\nbogus = 1\n")
    with pytest.raises(Exception, match="bogus"):
        load_fsg_params(shadow.config, bad)
    bad.write_text("[fsg]\nfingertip_width_m = 0.02\n")
    with pytest.raises(Exception, match=r"fingertip_width_m.*property of the hand"):
        load_fsg_params(shadow.config, bad)


# ------------------------------------------------------------------------------ FSG on the can


@pytest.fixture(scope="module")
def can_setup(shadow):  # type: ignore[no-untyped-def]
    from augment.autows.build import build_workspace
    from sim.world.objects import load_object

    obj = load_object(CAN)
    ws = build_workspace(shadow)
    cloud = object_cloud(obj)
    return obj, ws, cloud


@pytest.fixture(scope="module")
def can_result(shadow, can_setup):  # type: ignore[no-untyped-def]
    _, ws, cloud = can_setup
    return generate(shadow, cloud, ws, n=10, seed=0, time_budget_s=20, link_penetration=True,
                    exact_penetration=ScenePenetration(shadow.name, cloud.name))


def _assert_claims(hand, ws, cloud, grasps, params: FsgParams, *,  # type: ignore[no-untyped-def]
                   relaxed: bool = False) -> None:
    """Every grasp satisfies its own claims: palm box clear, unused joints 0, contacts inside the
    claimed faces at the stored joint angles (forward kinematics), ε recomputed; force closure
    for all unless the run ``relaxed`` its closure filter, and then force-closure grasps first."""
    closure = [g.epsilon > 0 for g in grasps]
    assert all(closure) or relaxed
    assert closure == sorted(closure, reverse=True)
    for g in grasps:
        rot = quat_to_mat(g.grasp.palm_quat_wxyz)

        def to_palm(x: np.ndarray, rot: np.ndarray = rot, g=g) -> np.ndarray:  # type: ignore[no-untyped-def]
            return (np.asarray(x) - g.grasp.palm_pos) @ rot

        # palm box holds at most max_palm_points object points
        box = np.all(np.abs(to_palm(cloud.points) - hand.config.palm.box_center)
                     <= hand.config.palm.box_half_extents, axis=1)
        assert box.sum() <= params.max_palm_points
        # unused finger joints are 0
        used_q = np.concatenate([hand.finger_qadr[f] for f in g.fingers])
        others = np.setdiff1d(np.arange(hand.nq), used_q)
        assert np.all(g.grasp.joints[others] == 0)
        # contacts lie in the claimed faces at the stored joint angles (forward kinematics)
        tpos, tquat = hand.tip_frames_in_palm(g.grasp.joints)
        cp = to_palm(g.contact_points)
        cn = g.contact_normals @ rot
        assert len(cp) >= params.min_contacts
        for fi, f in enumerate(g.fingers):
            fc = ws.finger(f)
            h = hand.finger_names.index(f)
            r_tip = quat_to_mat(tquat[0, h])
            face = g.face_index[fi]
            centre = tpos[0, h] + r_tip @ fc.tip_centres[face]
            normal = r_tip @ fc.tip_normals[face]
            np.testing.assert_allclose(centre, fc.positions[g.ws_index[fi]], atol=1e-9)
            mine = g.contact_finger == fi
            assert mine.any(), f"finger {f} claims no contact"
            d = cp[mine] - centre
            hgt = d @ normal
            inplane = d - hgt[:, None] * normal
            assert np.all(np.abs(hgt) <= params.contact_plane_m + 1e-9)
            assert np.all(np.linalg.norm(inplane, axis=1) <= fc.tip_radius[face] + 1e-9)
            assert np.all(cn[mine] @ normal < 0)   # the object faces the fingertip
        # Q1 recomputed from the stored contacts
        m = gws_metrics(g.contact_points, -g.contact_normals, 0.5, 8, cloud.com_m,
                        torque_scale_m=cloud.max_radius_m)
        assert m.epsilon == pytest.approx(g.epsilon, rel=1e-9)
        assert m.volume == pytest.approx(g.volume, rel=1e-9)


def _eq3_crossings(ws, cloud, grasps) -> list[bool]:  # type: ignore[no-untyped-def]
    """Per grasp: does a used finger's link skeleton cross the object surface by the paper's
    eq. 3, [(p_n − q_n)·nor_n]·[(p_n+1 − q_n+1)·nor_n] < 0? Computed here from the stored palm
    pose, independently of the sampler's code."""
    from scipy.spatial import cKDTree

    tree = cKDTree(cloud.points)
    out = []
    for g in grasps:
        rot = quat_to_mat(g.grasp.palm_quat_wxyz)
        hit = False
        for fi, f in enumerate(g.fingers):
            sk = np.asarray(ws.finger(f).skeleton[g.ws_index[fi]], float) @ rot.T + g.grasp.palm_pos
            _, qi = tree.query(sk)
            nor = cloud.normals[qi[:-1]]
            a = np.einsum("ij,ij->i", sk[:-1] - cloud.points[qi[:-1]], nor)
            b = np.einsum("ij,ij->i", sk[1:] - cloud.points[qi[1:]], nor)
            hit |= bool(np.any(a * b < 0))
        out.append(hit)
    return out


@needs_menagerie
@needs_ycb
def test_outputs_satisfy_their_claims(shadow, can_setup, can_result) -> None:  # type: ignore[no-untyped-def]
    _, ws, cloud = can_setup
    res = can_result
    assert len(res.grasps) == 10 and res.shortfall == 0 and res.stopped == "done"
    _assert_claims(shadow, ws, cloud, res.grasps, FsgParams(fingertip_width_m=0.02, link_clearance_m=0.008))
    eps = [g.epsilon for g in res.grasps]
    assert eps == sorted(eps, reverse=True)
    # with the exact check at the end of step 6, no output penetrates deeper than the validator
    # allows (this holds through the exact check alone; eq. 3 has its own test below)
    from sim.validate.batch import cached_validator

    validator = cached_validator(shadow.name, cloud.name)
    deepest = max(validator.penetration_m(g.grasp) for g in res.grasps)
    assert deepest <= validator.config.common.max_penetration_m, deepest


@needs_menagerie
@needs_ycb
def test_eq3_rejects_skeletons_that_cross_the_object(shadow, can_setup) -> None:  # type: ignore[no-untyped-def]
    """Paper eq. 3 alone (the link clearance set to 0, no exact check): with it no output's
    link skeleton crosses the surface; without it (``link_penetration=False``) some do, so the
    first assertion is not vacuous."""
    _, ws, cloud = can_setup
    params = dataclasses.replace(load_fsg_params(shadow.config), link_clearance_m=0.0)
    kw = dict(n=10, seed=0, time_budget_s=20, params=params)
    with_eq3 = generate(shadow, cloud, ws, link_penetration=True, **kw)
    without = generate(shadow, cloud, ws, link_penetration=False, **kw)
    assert len(with_eq3.grasps) == len(without.grasps) == 10
    assert not any(_eq3_crossings(ws, cloud, with_eq3.grasps))
    assert any(_eq3_crossings(ws, cloud, without.grasps))
    assert with_eq3.stats["link"] > 0 and without.stats["link"] == 0


@needs_menagerie
@needs_ycb
def test_same_seed_same_grasps(shadow, can_setup, can_result) -> None:  # type: ignore[no-untyped-def]
    _, ws, cloud = can_setup
    again = generate(shadow, cloud, ws, n=10, seed=0, time_budget_s=20, link_penetration=True,
                    exact_penetration=ScenePenetration(shadow.name, cloud.name))
    assert len(again.grasps) == len(can_result.grasps)
    for a, b in zip(again.grasps, can_result.grasps, strict=True):
        np.testing.assert_array_equal(a.grasp.joints, b.grasp.joints)
        np.testing.assert_array_equal(a.grasp.palm_pos, b.grasp.palm_pos)


@needs_menagerie
@needs_ycb
def test_lift_drop_pass_rate(can_result) -> None:  # type: ignore[no-untyped-def]
    from sim.validate.batch import validate_many

    grasps = [g.grasp for g in can_result.grasps]
    results = validate_many("shadow_right", CAN, grasps, "lift-drop",
                            workers=min(len(grasps), os.cpu_count() or 1))
    passed = sum(r.passed for r in results)
    print(f"\nFSG on {CAN}: lift-drop pass rate {passed}/{len(results)}; failures "
          f"{[str(r.failure) for r in results if not r.passed]}")
    assert passed >= 1


@needs_menagerie
@needs_ycb
def test_demo_seeded_run_ends_cleanly(shadow, can_setup, caplog) -> None:  # type: ignore[no-untyped-def]
    """With the can_side_wrap demo (a power wrap: the fingertips face the palm), FSG's
    precision model finds few or no grasps; whatever it finds must satisfy the claims, and the
    run must end within its budget with the shortfall reported."""
    from augment.autows.build import build_workspace
    from augment.autows.seed import DemoSeed
    from sim.hand.reference_grasps import load_reference_grasps
    from sim.validate.validator import Validator

    obj, _, cloud = can_setup
    ref = next(r for r in load_reference_grasps(shadow) if r.name == "can_side_wrap")
    contacts = Validator(shadow, obj).fingertip_contacts(ref.grasp)
    ws = build_workspace(shadow, demo=DemoSeed(ref.grasp.joints, contacts, ref.name))
    with caplog.at_level(logging.WARNING, logger="augment.fsg"):
        res = generate(shadow, cloud, ws, n=3, seed=0, time_budget_s=2.0)
    # "done" exactly when all 3 came out; a shortfall is a time-budget stop, and it is logged
    assert (res.stopped == "done") == (len(res.grasps) == 3)
    assert res.stopped in ("done", "time budget")
    if res.shortfall:
        assert f"shortfall {res.shortfall}, stopped: time budget" in caplog.text
    # every candidate is accounted for exactly once: rejected at one step, or accepted
    st = res.stats
    steps = ("palm", "table", "no_match", "contacts", "depth", "link", "epsilon", "duplicate",
             "penetration", "accepted")
    assert st["candidates"] > 0 and st["candidates"] == sum(st[k] for k in steps)
    assert st["accepted"] >= len(res.grasps)
    _assert_claims(shadow, ws, cloud, res.grasps, FsgParams(fingertip_width_m=0.02, link_clearance_m=0.008),
                   relaxed=res.closure_relaxed)


@needs_menagerie
@needs_ycb
def test_palm_candidates_keep_exactly_those_clear_of_palm_box_and_table(shadow, can_setup) -> None:  # type: ignore[no-untyped-def]
    """Step 2 checks the table first and the palm box only on what is left (the cloud's
    transform is most of the work): the candidates kept are exactly those of the same draws that
    pass both checks, each counted once, and the checks reject some (the test can fail)."""
    from augment.fsg.candidates import palm_candidates

    _, ws, cloud = can_setup
    params = load_fsg_params(shadow.config)
    centre = np.asarray(shadow.config.palm.box_center)
    half = np.asarray(shadow.config.palm.box_half_extents)
    table = TablePlane.horizontal(cloud.z_min_m)
    fc0 = ws.finger("thumb")
    points, normals, part = np.asarray(cloud.points), np.asarray(cloud.normals), cloud.part_indices

    def draw(tab, max_points, stats):  # type: ignore[no-untyped-def]
        p = dataclasses.replace(params, max_palm_points=max_points)
        return palm_candidates(np.random.default_rng(7), points, normals, part, fc0, 40,
                               palm_center=centre, palm_half=half, table=tab, params=p, stats=stats)

    every = draw(None, len(points), {"candidates": 0, "palm": 0, "table": 0})
    stats = {"candidates": 0, "palm": 0, "table": 0}
    kept = draw(table, params.max_palm_points, stats)
    in_box = (np.abs(every.full - centre) <= half).all(axis=2).sum(axis=1)
    verts = palm_box_vertices(centre, half)
    v_obj = np.einsum("cji,cvj->cvi", every.rot, verts[None] - every.trans[:, None])
    above = table.elevation_m(v_obj).min(axis=1) >= params.table_clearance_m
    clear = above & (in_box <= params.max_palm_points)
    assert stats["candidates"] == len(every.rot) == 40 * params.inner
    assert 0 < clear.sum() < len(clear) and stats["table"] == int((~above).sum()) > 0
    assert stats["palm"] == int((above & ~clear).sum()) > 0
    np.testing.assert_array_equal(kept.rot, every.rot[clear])
    np.testing.assert_array_equal(kept.full, every.full[clear])
    np.testing.assert_array_equal(kept.first_pos, every.first_pos[clear])


@needs_ycb
def test_table_mode_keeps_the_palm_above_the_table(shadow, can_setup) -> None:  # type: ignore[no-untyped-def]
    _, ws, cloud = can_setup
    params = load_fsg_params(shadow.config)
    res = generate(shadow, cloud, ws, n=3, seed=2, table=True, time_budget_s=10)
    assert res.grasps
    verts = palm_box_vertices(np.asarray(shadow.config.palm.box_center),
                              np.asarray(shadow.config.palm.box_half_extents))
    for g in res.grasps:
        v_obj = g.grasp.palm_pos + verts @ quat_to_mat(g.grasp.palm_quat_wxyz).T
        assert v_obj[:, 2].min() >= cloud.z_min_m + params.table_clearance_m - 1e-9


@needs_menagerie
@needs_ycb
def test_a_tilted_table_keeps_palm_and_fingertips_on_its_side(shadow, can_setup) -> None:  # type: ignore[no-untyped-def]
    """A can lying on its side (a demonstration's table in the object frame: normal +x through
    the can's lowest x): every palm box corner and contact point stays above that plane, and
    the horizontal table's answer would not (the test can fail)."""
    _, ws, cloud = can_setup
    params = load_fsg_params(shadow.config)
    side = TablePlane.through(cloud.points[np.argmin(cloud.points[:, 0])], np.array([1.0, 0.0, 0.0]))
    res = generate(shadow, cloud, ws, n=3, seed=2, table=side, time_budget_s=10)
    assert res.grasps and res.stats["table"] > 0
    verts = palm_box_vertices(np.asarray(shadow.config.palm.box_center),
                              np.asarray(shadow.config.palm.box_half_extents))
    for g in res.grasps:
        v_obj = g.grasp.palm_pos + verts @ quat_to_mat(g.grasp.palm_quat_wxyz).T
        assert side.elevation_m(v_obj).min() >= params.table_clearance_m - 1e-9
        assert side.elevation_m(np.asarray(g.contact_points)).min() >= -1e-9
    with pytest.raises(FsgError, match="unit normal"):
        TablePlane(np.array([0.0, 0.0, 2.0]), 0.0)


@needs_menagerie
@needs_ycb
def test_unreachable_n_reports_a_shortfall(shadow, can_setup) -> None:  # type: ignore[no-untyped-def]
    _, ws, cloud = can_setup
    res = generate(shadow, cloud, ws, n=100_000, seed=1, time_budget_s=1.0)
    assert res.stopped == "time budget"   # the budget ended it, not the unreachable n
    assert res.shortfall == 100_000 - len(res.grasps) > 0


@needs_menagerie
@needs_ycb
def test_no_graspable_part(can_setup) -> None:  # type: ignore[no-untyped-def]
    obj, _, _ = can_setup
    with pytest.raises(ObjectCloudError, match=r"005_tomato_soup_can.*curvature_threshold -1"):
        object_cloud(obj, curvature_threshold=-1.0, affordance=False)


@needs_menagerie
@needs_ycb
def test_workspace_of_another_hand(shadow, can_setup) -> None:  # type: ignore[no-untyped-def]
    _, ws, cloud = can_setup
    with pytest.raises(FsgError, match="allegro_right"):
        generate(shadow, cloud, dataclasses.replace(ws, hand="allegro_right"), n=1)
    from augment.autows.build import build_workspace
    from sim.hand.model import Hand

    try:
        allegro = Hand.load("allegro_right")
    except Exception as exc:  # pragma: no cover - asset missing
        pytest.skip(f"no Allegro model: {exc}")
    with pytest.raises(FsgError, match="shadow_right"):
        generate(allegro, cloud, ws, n=1)
    a_ws = build_workspace(allegro)
    with pytest.raises(FsgError, match="allegro_right"):
        generate(shadow, cloud, a_ws, n=1)


@needs_menagerie
@needs_ycb
def test_exact_penetration_needs_a_loadable_object(shadow) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(DexaugError, match=r"exact penetration.*'no_such_object_xyz' does not load"):
        ScenePenetration.of(shadow.name, "no_such_object_xyz")


@needs_menagerie
@needs_ycb
def test_exact_penetration_refuses_fingers_inside_each_other(shadow) -> None:  # type: ignore[no-untyped-def]
    """Half a metre above the object, so the hand touches nothing but itself: the middle finger
    spread towards the forefinger by 0.1 rad overlaps it by ≈ 3 mm (within the 5 mm the
    validator allows the hand into the object), by 0.15 rad ≈ 7 mm (refused)."""
    from sim.grasp import Grasp
    from sim.validate.batch import cached_validator
    from sim.validate.self_clearance import self_penetration_m

    check = ScenePenetration(shadow.name, "005_tomato_soup_can")
    scene = cached_validator(shadow.name, "005_tomato_soup_can").scene("lift-drop")
    verdicts = {}
    for spread_rad in (0.0, 0.1, 0.15):
        q = np.zeros(len(shadow.joint_names))
        q[list(shadow.joint_names).index("rh_MFJ4")] = spread_rad
        grasp = Grasp(np.array([0.0, 0.0, 0.5]), np.array([1.0, 0.0, 0.0, 0.0]), q)
        verdicts[spread_rad] = (check(grasp), 1e3 * self_penetration_m(scene, q))
    assert verdicts[0.0] == (False, 0.0)
    assert not verdicts[0.1][0] and 1.0 < verdicts[0.1][1] < 5.0
    assert verdicts[0.15][0] and verdicts[0.15][1] > 5.0


# ------------------------------------------------------------------------------ dataset


def _fake_grasps(n: int, nq: int, fingers: tuple[str, ...], seed: int = 0) -> list:
    from sim.grasp import Grasp

    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        m = 3 + i
        q = rng.normal(size=4)
        out.append(FsgGrasp(
            grasp=Grasp(rng.normal(size=3), q / np.linalg.norm(q), rng.normal(size=nq)),
            fingers=fingers[:2 + i % 2], contact_points=rng.normal(size=(m, 3)),
            contact_normals=rng.normal(size=(m, 3)), contact_finger=np.arange(m) % 2,
            ws_index=(0, 1), face_index=(0, 0), epsilon=float(rng.random()),
            volume=float(rng.random())))
    return out


def _val(passed: bool, failure: str | None, q: int) -> ValidationResult:
    """A validation result as the validator fills it (pregrasp/squeeze made by dexaug)."""
    return ValidationResult("lift-drop", passed, failure, 0.0, epsilon=0.05, displacement_m=0.001,
                            rotation_rad=0.01, closing="free", squeeze_convention="dexaug",
                            pregrasp=np.full(q, 0.1), squeeze=np.full(q, 0.3))


def test_dataset_round_trip_append_and_atomicity(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    joints = tuple(f"j{i}" for i in range(6))
    fingers = ("thumb", "index", "middle")
    grasps = _fake_grasps(4, 6, fingers)
    vals = [_val(True, None, 6), _val(False, "slipped", 6), _val(True, None, 6),
            _val(False, "penetration", 6)]
    attrs = {"hand": "h", "config_hash": "abc", "seed": 3, "versions": {"numpy": np.__version__}}
    table = dataset.from_fsg(grasps, joints, fingers, vals, demo_id="d1", attrs=attrs)
    path = tmp_path / "grasps.h5"
    dataset.save(path, {"obj": table})
    loaded = dataset.load(path)["obj"]
    assert len(loaded) == 2 and loaded.rejected is not None and len(loaded.rejected) == 2
    assert list(loaded.rejected["failure"]) == ["slipped", "penetration"]
    np.testing.assert_array_equal(loaded["palm_pose"][1][:3], grasps[2].grasp.palm_pos)
    np.testing.assert_array_equal(loaded["hand_pose"][0], grasps[0].grasp.joints)
    assert loaded.joint_names == joints and loaded.finger_names == fingers
    pts, nrm, _ = loaded.contacts(1)
    np.testing.assert_array_equal(pts, grasps[2].contact_points)
    np.testing.assert_array_equal(nrm, grasps[2].contact_normals)
    assert list(loaded["fingers_used"][1]) == [True, True, False]
    assert loaded.attrs["hand"] == "h" and loaded.attrs["seed"] == 3
    assert list(loaded["demo_id"]) == ["d1", "d1"]
    np.testing.assert_array_equal(loaded["pregrasp_pose"], np.full((2, 6), 0.1))
    np.testing.assert_array_equal(loaded["squeeze_pose"], np.full((2, 6), 0.3))
    assert list(loaded["stages_made_by"]) == ["dexaug", "dexaug"]
    assert list(loaded["closing"]) == ["free", "free"]
    import h5py
    with h5py.File(path) as f:
        assert f["obj/palm_pose"].attrs["order"] == "x y z qw qx qy qz"
    # append: same object grows, a new object appears
    more = dataset.from_fsg(_fake_grasps(3, 6, fingers, seed=1), joints, fingers)
    dataset.append(path, {"obj": more, "other": more})
    both = dataset.load(path)
    assert len(both["obj"]) == 5 and len(both["other"]) == 3
    pts, _, _ = both["obj"].contacts(4)
    np.testing.assert_array_equal(pts, _fake_grasps(3, 6, fingers, seed=1)[2].contact_points)
    assert [p.name for p in tmp_path.iterdir()] == ["grasps.h5"]
    # a failing write leaves the old file intact and no temp file behind
    before = path.read_bytes()

    def boom(*_a, **_k):  # type: ignore[no-untyped-def]
        raise RuntimeError("disk full")

    monkeypatch.setattr(dataset, "_write_group", boom)
    fresh = dataset.from_fsg(_fake_grasps(3, 6, fingers, seed=2), joints, fingers)
    with pytest.raises(RuntimeError, match="disk full"):
        dataset.append(path, {"obj": fresh})
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["grasps.h5"]


def test_a_file_written_before_a_column_existed_takes_appended_rows_that_have_it(
        tmp_path: Path) -> None:
    """``touch_pose`` (the ``dgb`` grasp stage) came after files were written without it:
    appending to such a file keeps the new rows' values and gives the old rows NaN, either way
    round, instead of dropping the column or failing."""
    joints = tuple(f"j{i}" for i in range(6))
    fingers = ("thumb", "index", "middle")
    old = dataset.from_fsg(_fake_grasps(2, 6, fingers), joints, fingers)
    del old.columns["touch_pose"]                       # as written before the column
    path = tmp_path / "old.h5"
    dataset.save(path, {"obj": old})
    dgb = dataclasses.replace(_val(True, None, 6), protocol="dgb", touch=np.full(6, 0.2))
    new = dataset.from_fsg(_fake_grasps(1, 6, fingers, seed=1), joints, fingers, [dgb])
    dataset.append(path, {"obj": new})
    touch = dataset.load(path)["obj"]["touch_pose"]
    assert touch.shape == (3, 6)
    assert np.isnan(touch[:2]).all()
    np.testing.assert_array_equal(touch[2], np.full(6, 0.2))
    path2 = tmp_path / "new.h5"                         # the other way round
    dataset.save(path2, {"obj": new})
    dataset.append(path2, {"obj": old})
    touch = dataset.load(path2)["obj"]["touch_pose"]
    np.testing.assert_array_equal(touch[0], np.full(6, 0.2))
    assert np.isnan(touch[1:]).all()
