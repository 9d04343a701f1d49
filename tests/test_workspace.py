"""AutoWS workspace clouds (augment.autows): exactness
against MuJoCo's own kinematics for every hand, contact faces on the pulp, demo-centred clouds,
bad input, the disk cache and the rendering."""

from __future__ import annotations

import dataclasses
import logging
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from augment.autows import fingertip as fingertip_mod
from augment.autows.build import build_workspace
from augment.autows.cloud import FACE_KINDS, WorkspaceCloud, summarise
from augment.autows.fingertip import (
    FingertipParams,
    TipMesh,
    fingertip_faces,
    hand_fingertip_faces,
    tip_mesh,
)
from augment.autows.grids import joint_grids
from augment.autows.params import AutoWSParams, WorkspaceError, load_autows_params
from augment.autows.render import free_camera_projection, render_workspace_png
from augment.autows.seed import DemoSeed
from augment.geometry.face import ContactFaceError
from sim.errors import ConfigError
from sim.hand.model import Hand
from sim.transforms import pose_mul, quat_to_mat
from tests.conftest import needs_menagerie

pytestmark = [pytest.mark.slow, needs_menagerie]

HANDS = ("shadow_right", "allegro_right", "robotiq_2f85")


@pytest.fixture(autouse=True)
def _tmp_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Never touch the user's cache: each test gets an empty cache folder."""
    path = tmp_path_factory.mktemp("cache")
    monkeypatch.setenv("DEXAUG_CACHE_DIR", str(path))
    return path


@pytest.fixture(scope="module")
def params() -> AutoWSParams:
    return load_autows_params()


@pytest.fixture(scope="module")
def hands() -> dict[str, Hand]:
    return {name: Hand.load(name) for name in HANDS}


@pytest.fixture(scope="module")
def clouds(hands: dict[str, Hand], params: AutoWSParams) -> dict[str, WorkspaceCloud]:
    """Real clouds from the configs' manual ranges (the paper's Table 1 for the Shadow Hand)."""
    return {name: build_workspace(hand, params, cache=False) for name, hand in hands.items()}


def _demo_for(hand: Hand, joints: dict[str, float], name: str = "demo") -> DemoSeed:
    """A demo whose contacts are the fingertip surface points (of the Poisson-disk cloud of the
    tip mesh) nearest each finger's pulp site."""
    q = np.zeros(hand.nq)
    for joint, value in joints.items():
        q[hand.joint_names.index(joint)] = value
    q = hand.fill_coupled(q)
    contacts = {}
    for f in hand.config.fingers:
        surface = hand_fingertip_faces(hand, f.name).cloud_points
        contacts[f.name] = surface[np.argmin(np.linalg.norm(surface - f.tip_site_pos, axis=1))]
    return DemoSeed(joints=q, contacts=contacts, id=name)


SHADOW_DEMO = {"rh_FFJ3": 0.6, "rh_FFJ2": 0.5, "rh_MFJ3": 0.7, "rh_MFJ2": 0.4, "rh_RFJ3": 0.5,
               "rh_RFJ2": 0.6, "rh_LFJ5": 0.1, "rh_LFJ3": 0.6, "rh_LFJ2": 0.5, "rh_THJ5": 0.4,
               "rh_THJ4": 1.0, "rh_THJ2": 0.2, "rh_THJ1": 0.3}


# ---------------------------------------------------------------------------------------------
# parameters and grids


def test_params_from_toml(tmp_path: Path) -> None:
    p = load_autows_params()
    assert p.step_deg == 10.0 and p.demo_step_deg == 5.0 and p.demo_steps == 2
    assert p.normal_band == 0.001 and p.skeleton_spacing_m == 0.005
    assert p.fingertip == FingertipParams()
    bad = tmp_path / "augment.toml"
    bad.write_text("[autows]\nshape = 'hexagon'\n")
    with pytest.raises(ConfigError, match=r"augment\.toml: autows\.shape"):
        load_autows_params(bad)
    bad.write_text("[autows]\nstep_deg = -1\n")
    with pytest.raises(ConfigError, match=r"autows\.step_deg"):
        load_autows_params(bad)
    bad.write_text("[autows]\nstep_degs = 5\n")
    with pytest.raises(ConfigError, match="unknown key"):
        load_autows_params(bad)
    bad.write_text("[other]\nx = 1\n")  # other tables are someone else's business
    assert load_autows_params(bad) == AutoWSParams()


def test_table1_grid_sizes(hands: dict[str, Hand], params: AutoWSParams) -> None:
    grids = joint_grids(hands["shadow_right"], params)
    sizes = {f: math.prod(len(v) for v in g.values()) for f, g in grids.items()}
    assert sizes == {"thumb": 3 * 3 * 3 * 5 * 5, "forefinger": 3 * 4 * 4, "middle": 48,
                     "ring": 48, "little": 1 * 3 * 4 * 4}
    np.testing.assert_allclose(np.rad2deg(grids["forefinger"]["rh_FFJ3"]), [20, 30, 40, 50],
                               atol=1e-3)
    # a range that is not a whole number of steps keeps its upper bound
    robotiq = joint_grids(hands["robotiq_2f85"], params)
    np.testing.assert_allclose(np.rad2deg(robotiq["right"]["right_driver_joint"]),
                               [0, 10, 20, 30, 40, 45], atol=1e-9)


# ---------------------------------------------------------------------------------------------
# exactness against MuJoCo


def _palm_frame_mujoco(hand: Hand, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    b = hand.model.body(hand.config.palm.body).id
    pos, quat = pose_mul(data.xpos[b], data.xquat[b], hand.config.palm.pos,
                         hand.config.palm.quat_wxyz)
    return pos, quat_to_mat(quat)


@pytest.mark.parametrize("name", HANDS)
def test_points_reproduce_mujoco_kinematics(name: str, hands: dict[str, Hand],
                                            clouds: dict[str, WorkspaceCloud],
                                            params: AutoWSParams) -> None:
    """Stored joints → MuJoCo mj_kinematics → stored face centre from the tip frame reproduces
    the stored position and normal in frame_palm (1e-9), for 200 random points per finger."""
    hand, cloud = hands[name], clouds[name]
    m = hand.model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    assert cloud.finger_names == hand.finger_names  # priority = config order
    for fc in cloud.fingers:
        cfg = hand.config.finger(fc.name)
        assert fc.n_points > 0 and fc.joint_names == cfg.joints
        tip_id = m.body(cfg.tip_body).id
        adr = [m.joint(j).qposadr[0] for j in fc.joint_names]
        for i in rng.choice(fc.n_points, min(200, fc.n_points), replace=False):
            d.qpos[:] = 0.0
            d.qpos[adr] = fc.joints[i]
            mujoco.mj_kinematics(m, d)
            p_palm, r_palm = _palm_frame_mujoco(hand, d)
            r_tip = d.xmat[tip_id].reshape(3, 3)
            k = fc.face_index[i]
            centre_w = d.xpos[tip_id] + r_tip @ fc.tip_centres[k]
            normal_w = r_tip @ fc.tip_normals[k]
            np.testing.assert_allclose(r_palm.T @ (centre_w - p_palm), fc.positions[i], atol=1e-9)
            np.testing.assert_allclose(r_palm.T @ normal_w, fc.normals[i], atol=1e-9)
            if FACE_KINDS[fc.face_kind[i]] == "rect":
                np.testing.assert_allclose(r_palm.T @ r_tip @ fc.tip_half_edges[k].T,
                                           fc.half_edges[i].T, atol=1e-9)
            # the skeleton ends at the fingertip body origin (fingertip link excluded)
            tip_palm = r_palm.T @ (d.xpos[tip_id] - p_palm)
            np.testing.assert_allclose(fc.skeleton[i, -1], tip_palm, atol=1e-6)


@pytest.mark.parametrize("name", HANDS)
def test_cloud_fields_are_consistent(name: str, hands: dict[str, Hand],
                                     clouds: dict[str, WorkspaceCloud],
                                     params: AutoWSParams) -> None:
    hand, cloud = hands[name], clouds[name]
    band = params.normal_band
    for fc in cloud.fingers:
        n, f = fc.n_points, fc.n_faces
        cfg = hand.config.finger(fc.name)
        assert fc.positions.shape == (n, 3) and fc.normals.shape == (n, 3)
        assert fc.joints.shape == (n, len(cfg.joints))
        assert fc.half_edges.shape == (n, 2, 3) and fc.radius.shape == (n,)
        assert fc.skeleton.dtype == np.float32 and fc.skeleton.shape[0] == n
        assert np.isfinite(fc.skeleton).all()
        np.testing.assert_allclose(np.linalg.norm(fc.normals, axis=1), 1.0, atol=1e-12)
        assert set(np.unique(fc.face_index)) <= set(range(f)) and 0 in fc.face_index
        # circles (the configured default) carry a radius, no half-edges
        assert (fc.face_kind == FACE_KINDS.index("circle")).all()
        np.testing.assert_allclose(fc.radius, fc.tip_radius[fc.face_index])
        assert np.isnan(fc.half_edges).all() and (fc.radius > 1e-3).all()
        # joints inside the limits; coupled followers follow their leaders
        lo = np.array([hand.lower[hand.joint_names.index(j)] for j in cfg.joints])
        hi = np.array([hand.upper[hand.joint_names.index(j)] for j in cfg.joints])
        assert (fc.joints >= lo - 1e-12).all() and (fc.joints <= hi + 1e-12).all()
        for follower, (leader, coef) in cfg.coupled_to.items():
            fi, li = cfg.joints.index(follower), cfg.joints.index(leader)
            np.testing.assert_allclose(fc.joints[:, fi],
                                       np.clip(coef * fc.joints[:, li], lo[fi], hi[fi]))
        # mean-normal filter: no normal y of the opposite sign beyond the band
        sign = 1.0 if fc.normals[:, 1].mean() > 0 else -1.0
        assert (sign * fc.normals[:, 1] >= -band).all()


def test_normal_filter_removes_opposite_points(hands: dict[str, Hand],
                                               clouds: dict[str, WorkspaceCloud],
                                               params: AutoWSParams) -> None:
    """Unfiltered, the Shadow clouds have both signs of normal y; the filter drops the minority
    (the paper's Fig. 2 (h) → (i))."""
    shadow = clouds["shadow_right"]
    unfiltered = build_workspace(hands["shadow_right"], dataclasses.replace(params, normal_band=2.0),
                                 cache=False)
    for before, after in zip(unfiltered.fingers, shadow.fingers, strict=True):
        assert after.n_points < before.n_points
        assert (before.normals[:, 1] > 0.001).any() and (before.normals[:, 1] < -0.001).any()


# ---------------------------------------------------------------------------------------------
# contact faces


def test_shadow_faces_on_the_pulp(hands: dict[str, Hand]) -> None:
    hand = hands["shadow_right"]
    for f in hand.config.fingers:
        tip = hand_fingertip_faces(hand, f.name)
        assert 1 <= len(tip.faces) <= 4
        assert (tip.normals @ f.v_f > 0).all(), f.name
        assert tip.faces[0].normal @ f.v_f > 0.7
        # face centres are points of the pulp cloud, which has lost the nail side
        for face in tip.faces:
            np.testing.assert_allclose(face.centre, tip.pulp_points[face.centre_index])
        nail = tip.cloud_normals @ f.v_f < -0.5
        assert nail.sum() > 0.2 * len(tip.cloud_points)
        assert (tip.pulp_normals @ f.v_f < -0.5).sum() == 0
        assert len(tip.pulp_points) < 0.6 * len(tip.cloud_points)


def test_tip_mesh_is_in_the_body_frame(hands: dict[str, Hand]) -> None:
    """MuJoCo re-centres meshes; mapped by the geom pose, the tip mesh placed by the tip body's
    pose lands exactly where MuJoCo puts the mesh geom (at a bent pose)."""
    for hand in hands.values():
        m = hand.model
        d = mujoco.MjData(m)
        d.qpos[:] = np.clip(0.3, hand.lower, hand.upper)
        mujoco.mj_kinematics(m, d)
        for f in hand.config.fingers:
            mesh = tip_mesh(hand, f.name)
            # every pulp site sits on (or just inside) its fingertip's surface
            surface = hand_fingertip_faces(hand, f.name).cloud_points
            dist = np.linalg.norm(surface - f.tip_site_pos, axis=1).min()
            assert dist < 0.006, (hand.name, f.name, dist)
            mesh_id = m.mesh(f.tip_mesh).id
            b = m.body(f.tip_body).id
            g = next(g for g in range(m.ngeom) if m.geom_dataid[g] == mesh_id
                     and m.geom_bodyid[g] == b)
            va, nv = m.mesh_vertadr[mesh_id], m.mesh_vertnum[mesh_id]
            raw = m.mesh_vert[va:va + nv].astype(float)
            by_geom = d.geom_xpos[g] + raw @ d.geom_xmat[g].reshape(3, 3).T
            by_body = d.xpos[b] + mesh.vertices @ d.xmat[b].reshape(3, 3).T
            np.testing.assert_allclose(by_body, by_geom, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# demonstrations


def test_demo_cloud_contains_the_demo_contact(hands: dict[str, Hand],
                                              params: AutoWSParams) -> None:
    hand = hands["shadow_right"]
    demo = _demo_for(hand, SHADOW_DEMO)
    cloud = build_workspace(hand, params, demo, cache=False)
    assert cloud.provenance["mode"] == "demo" and cloud.provenance["demo_id"] == "demo"
    pos, quat = hand.tip_frames_in_palm(demo.joints)
    for i, fc in enumerate(cloud.fingers):
        contact = pos[0, i] + quat_to_mat(quat[0, i]) @ demo.contact(fc.name)
        dist = np.linalg.norm(fc.positions - contact, axis=1)
        assert dist.min() < 0.002, (fc.name, dist.min())
        # ...at the demo's own joint angles
        q_demo = demo.joints[hand.finger_qadr[fc.name]]
        assert np.allclose(fc.joints[np.argmin(dist)], q_demo)
    grids = joint_grids(hand, params, demo)
    np.testing.assert_allclose(np.rad2deg(grids["forefinger"]["rh_FFJ3"] - 0.6),
                               [-10, -5, 0, 5, 10], atol=1e-9)
    # demo angles near a limit are clipped (LFJ5 at 0.1 rad = 5.7°: −10° is clipped to 0)
    lfj5 = np.rad2deg(grids["little"]["rh_LFJ5"])
    assert lfj5.min() == pytest.approx(0.0) and len(lfj5) == 5


def test_demo_keeps_its_coupled_offset(hands: dict[str, Hand], params: AutoWSParams) -> None:
    """A demo whose simulated FJ1 differs from FJ2: the grid still contains the demo pose."""
    hand = hands["shadow_right"]
    demo = _demo_for(hand, SHADOW_DEMO)
    q = demo.joints.copy()
    q[hand.joint_names.index("rh_FFJ1")] += 0.1
    uneven = DemoSeed(joints=q, contacts=demo.contacts, id="uneven")
    fc = build_workspace(hand, params, uneven, fingers=["forefinger"], cache=False).fingers[0]
    q_demo = q[hand.finger_qadr["forefinger"]]
    assert np.isclose(fc.joints, q_demo).all(axis=1).any()
    j1, j2 = fc.joint_names.index("rh_FFJ1"), fc.joint_names.index("rh_FFJ2")
    np.testing.assert_allclose(fc.joints[:, j1] - fc.joints[:, j2], 0.1, atol=1e-12)


def test_demo_query_moves_the_face(hands: dict[str, Hand]) -> None:
    hand = hands["shadow_right"]
    near_tip = hand_fingertip_faces(hand, "forefinger", [0.0, -0.006, 0.027])
    default = hand_fingertip_faces(hand, "forefinger")
    assert near_tip.faces[0].centre[2] > default.faces[0].centre[2] + 0.002


# ---------------------------------------------------------------------------------------------
# bad input


def _flat_square(normal_sign: float) -> TipMesh:
    """A 2 cm square in the z = 0 plane wound so its normal is ``normal_sign``·z."""
    v = np.array([[0, 0, 0], [0.02, 0, 0], [0.02, 0.02, 0], [0, 0.02, 0]], dtype=float)
    f = np.array([[0, 1, 2], [0, 2, 3]]) if normal_sign > 0 else np.array([[0, 2, 1], [0, 3, 2]])
    return TipMesh(vertices=v, faces=f)


def test_mesh_facing_away_is_an_error(hands: dict[str, Hand], monkeypatch: pytest.MonkeyPatch,
                                      params: AutoWSParams) -> None:
    away = _flat_square(-1.0)
    with pytest.raises(ContactFaceError, match="no fingertip point is visible"):
        fingertip_faces(away.vertices, away.faces, [0, 0, 1], [1, 0, 0])
    facing = _flat_square(+1.0)
    ok = fingertip_faces(facing.vertices, facing.faces, [0, 0, 1], [1, 0, 0])
    assert ok.faces[0].normal @ [0, 0, 1] > 0.99
    # the same through the builder: the error names the hand and the finger
    # (a pad turned round: its surface faces +y, away from the finger's v_f = −y)
    hand = hands["robotiq_2f85"]
    real = fingertip_mod.tip_mesh
    turned = TipMesh(vertices=away.vertices[:, [0, 2, 1]], faces=away.faces)
    monkeypatch.setattr(fingertip_mod, "tip_mesh",
                        lambda h, f: turned if f == "right" else real(h, f))
    with pytest.raises(WorkspaceError, match=r"finger 'right' of hand 'robotiq_2f85'.*visible"):
        build_workspace(hand, params, cache=False)


def test_empty_range_is_an_error(hands: dict[str, Hand], params: AutoWSParams) -> None:
    hand = hands["shadow_right"]
    with pytest.raises(WorkspaceError, match=r"rh_FFJ3.*empty range"):
        build_workspace(hand, params, ranges={"rh_FFJ3": (0.5, 0.2)}, cache=False)
    with pytest.raises(WorkspaceError, match="not finite"):
        build_workspace(hand, params, ranges={"rh_FFJ3": (0.1, math.nan)}, cache=False)
    with pytest.raises(WorkspaceError, match="not independent finger joints"):
        build_workspace(hand, params, ranges={"rh_FFJ1": (0.1, 0.2)}, cache=False)
    # a single-value range is fine
    one = build_workspace(hand, params, ranges={"rh_FFJ3": (0.5, 0.5)}, fingers=["forefinger"],
                          cache=False)
    j3 = one.fingers[0].joint_names.index("rh_FFJ3")
    np.testing.assert_allclose(one.fingers[0].joints[:, j3], 0.5)


def test_parallel_directions_are_an_error(hands: dict[str, Hand],
                                          params: AutoWSParams) -> None:
    hand = hands["allegro_right"]
    fingers = list(hand.config.fingers)
    fingers[1] = dataclasses.replace(fingers[1], v_u=-fingers[1].v_f)
    broken = Hand(dataclasses.replace(hand.config, fingers=tuple(fingers)))
    with pytest.raises(WorkspaceError, match=r"forefinger.*parallel"):
        build_workspace(broken, params, cache=False)
    with pytest.raises(ValueError, match="parallel"):
        fingertip_faces(_flat_square(1).vertices, _flat_square(1).faces, [0, 0, 1], [0, 0, 2])


def test_bad_demos(hands: dict[str, Hand], params: AutoWSParams) -> None:
    hand = hands["allegro_right"]
    with pytest.raises(WorkspaceError, match=r"has 16 \("):
        build_workspace(hand, params, DemoSeed(np.zeros(5), {}, "short"), cache=False)
    with pytest.raises(WorkspaceError, match="unknown finger"):
        build_workspace(hand, params, DemoSeed(np.zeros(16), {"pinky": [0, 0, 0]}, "x"),
                        cache=False)
    with pytest.raises(WorkspaceError, match="without a demo only"):
        build_workspace(hand, params, DemoSeed(np.zeros(16), {}, "x"),
                        ranges={"ffj0": (0.0, 0.1)}, cache=False)
    with pytest.raises(WorkspaceError, match="finite 3-vector"):
        DemoSeed(np.zeros(16), {"thumb": [0, 0]}, "x")
    with pytest.raises(WorkspaceError, match="finite"):
        DemoSeed(np.full(16, np.nan), {}, "x")


# ---------------------------------------------------------------------------------------------
# cache and files


def test_cache_hits_and_keys(hands: dict[str, Hand], params: AutoWSParams, _tmp_cache: Path,
                             caplog: pytest.LogCaptureFixture) -> None:
    hand = hands["shadow_right"]
    first = build_workspace(hand, params, fingers=["forefinger", "middle"])
    assert not first.from_cache
    files = list((_tmp_cache / "workspace").glob("*.npz"))
    assert len(files) == 1
    with caplog.at_level(logging.INFO, logger="augment.autows.build"):
        second = build_workspace(hand, params, fingers=["forefinger", "middle"])
    assert second.from_cache and "loaded from cache" in caplog.text
    assert second.provenance["key"] == first.provenance["key"]
    for a, b in zip(first.fingers, second.fingers, strict=True):
        for name in a.ARRAYS:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    # a changed parameter, demo or range gives another key
    other = build_workspace(hand, dataclasses.replace(params, step_deg=15.0),
                            fingers=["forefinger", "middle"])
    assert not other.from_cache and other.provenance["key"] != first.provenance["key"]
    demo = _demo_for(hand, SHADOW_DEMO, "a")
    d1 = build_workspace(hand, params, demo, fingers=["forefinger"])
    d2 = build_workspace(hand, params, dataclasses.replace(demo, id="b"), fingers=["forefinger"])
    moved = demo.joints.copy()
    moved[hand.joint_names.index("rh_FFJ3")] += 0.01
    d3 = build_workspace(hand, params, DemoSeed(moved, demo.contacts, "a"), fingers=["forefinger"])
    keys = {c.provenance["key"] for c in (first, other, d1, d2, d3)}
    assert len(keys) == 5
    assert build_workspace(hand, params, demo, fingers=["forefinger"]).from_cache
    # a damaged cache file is rebuilt, not trusted
    for f in (_tmp_cache / "workspace").glob("*.npz"):
        f.write_bytes(b"garbage")
    with caplog.at_level(logging.WARNING, logger="augment.autows.build"):
        again = build_workspace(hand, params, fingers=["forefinger", "middle"])
    assert not again.from_cache and "damaged" in caplog.text


def test_save_load_roundtrip(clouds: dict[str, WorkspaceCloud], tmp_path: Path) -> None:
    cloud = clouds["allegro_right"]
    path = tmp_path / "ws.npz"
    cloud.save(path)
    back = WorkspaceCloud.load(path)
    assert back.hand == cloud.hand and back.finger_names == cloud.finger_names
    assert back.provenance == cloud.provenance
    assert summarise(back) == summarise(cloud)
    for a, b in zip(cloud.fingers, back.fingers, strict=True):
        assert a.joint_names == b.joint_names
        for name in a.ARRAYS:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    with pytest.raises(WorkspaceError, match="no such"):
        WorkspaceCloud.load(tmp_path / "missing.npz")
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(WorkspaceError, match="not a readable"):
        WorkspaceCloud.load(tmp_path / "bad.npz")


def test_summary_and_sizes(clouds: dict[str, WorkspaceCloud]) -> None:
    rows = summarise(clouds["shadow_right"])
    assert [r[0] for r in rows] == ["thumb", "forefinger", "middle", "ring", "little"]
    assert all(n > 0 and 1 <= k <= 4 for _, n, k in rows)
    assert clouds["shadow_right"].nbytes < 20e6


# ---------------------------------------------------------------------------------------------
# rendering


def _gl() -> str | None:
    from sim.world.render import gl_available

    return gl_available()


def test_projection_matches_the_renderer() -> None:
    if _gl() is None:
        pytest.skip("no OpenGL backend")
    from sim.world.render import render_scene

    pts = np.array([[0.0, 0.0, 0.0], [0.06, -0.04, 0.03], [-0.05, 0.03, -0.04]])
    spheres = "".join(f'<geom type="sphere" size=".006" pos="{p[0]} {p[1]} {p[2]}" '
                      f'material="red"/>' for p in pts)
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><visual><global offwidth="800" offheight="600"/></visual><asset>'
        '<material name="red" rgba="1 0 0 1" emission="1" specular="0"/></asset>'
        f'<worldbody>{spheres}</worldbody></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    for az, el, w, h in [(135.0, -25.0, 640, 480), (30.0, -60.0, 400, 600)]:
        img = render_scene(model, data, lookat=np.zeros(3), distance_m=0.3, azimuth_deg=az,
                           elevation_deg=el, width=w, height=h, show_contacts=False)
        uv, depth = free_camera_projection(model, data, np.zeros(3), 0.3, az, el, w, h)(pts)
        assert (depth > 0).all()
        red = (img[..., 0] > 100) & (img[..., 1] < 60) & (img[..., 2] < 60)
        for u, v in uv:
            ys, xs = np.nonzero(red[max(int(v) - 12, 0):int(v) + 13, max(int(u) - 12, 0):int(u) + 13])
            assert len(xs) > 10
            centre = np.array([xs.mean() + max(int(u) - 12, 0), ys.mean() + max(int(v) - 12, 0)])
            assert np.linalg.norm(centre - [u, v]) < 1.5


def test_render_workspace_png(hands: dict[str, Hand], clouds: dict[str, WorkspaceCloud],
                              tmp_path: Path) -> None:
    if _gl() is None:
        pytest.skip("no OpenGL backend")
    hand = hands["allegro_right"]
    path = tmp_path / "ws.png"
    img = render_workspace_png(hand, clouds["allegro_right"], path, width=480, height=360)
    assert path.is_file() and img.shape == (360, 480, 3)
    # the first finger's colour is drawn
    assert ((img[..., 0] > 200) & (img[..., 1] < 80) & (img[..., 2] < 80)).sum() > 50
    with pytest.raises(WorkspaceError, match="drawn over"):
        render_workspace_png(hands["shadow_right"], clouds["allegro_right"], None)


def test_fingertip_faces_on_plain_arrays() -> None:
    """The fingertip module works on any mesh given as arrays: a box's top face (+z as v_f) is
    the main contact face."""
    box = trimesh.creation.box(extents=(0.02, 0.01, 0.006))
    tip = fingertip_faces(box.vertices, box.faces, [0, 0, 1], [1, 0, 0])
    assert tip.faces[0].normal @ [0, 0, 1] > 0.99
