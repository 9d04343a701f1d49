"""FSG's rules on synthetic geometry where the answer is known (no YCB, no MuJoCo model): eq. 2
neighbour removal, the finger-crossing rule, finger iteration, de-duplication, eq. 3, and the
determinism of a two-worker run.

The end-to-end tests use a toy world: a 4 cm cube (``cloud_full`` on a 4 mm grid per face), a
stand-in hand (only the attributes :func:`augment.fsg.run.generate` reads) and hand-made
workspace clouds: a small "thumb" patch facing +y at y = 0 and an "index" grid facing −y at
y = 4 cm, so every candidate that puts a cube face on the thumb has the opposite face on the
index grid; a "middle" grid beside the index one, facing −y too, is in reach of that face or
1 m away.
"""

from __future__ import annotations

import dataclasses
import itertools
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from augment.autows.cloud import FingerCloud, WorkspaceCloud
from augment.fsg.candidates import Candidates
from augment.fsg.checks import Dedup, eq3_crossing, link_penetrates
from augment.fsg.matching import FingerIndex, crossing_groups, eq2_removed, match_fingers
from augment.fsg.params import FsgParams
from augment.fsg.result import FsgGrasp
from augment.fsg.run import generate, merge, misses_budget
from augment.object_cloud import ObjectCloud
from sim.grasp import Grasp
from sim.transforms import axis_angle_to_mat, mat_to_quat

pytestmark = pytest.mark.slow

SIDE_M = 0.04


def _finger(name: str, positions: np.ndarray, normals: np.ndarray, joints: float | np.ndarray,
            radius_m: float = 0.006) -> FingerCloud:
    """A workspace cloud of circular faces, two joints per finger, a two-point skeleton 10 cm
    behind each face (never near the object)."""
    pos = np.asarray(positions, float).reshape(-1, 3)
    nrm = np.broadcast_to(np.asarray(normals, float), pos.shape).copy()
    n = len(pos)
    q = np.broadcast_to(np.asarray(joints, float), (n, 2)).copy()
    skel = (pos[:, None] - 0.1 * nrm[:, None] * np.array([1.0, 2.0])[None, :, None])
    return FingerCloud(
        name=name, joint_names=(f"{name}_j0", f"{name}_j1"), positions=pos, normals=nrm, joints=q,
        face_index=np.zeros(n, np.int16), face_kind=np.zeros(n, np.uint8),
        radius=np.full(n, radius_m), half_edges=np.full((n, 2, 3), np.nan),
        skeleton=skel.astype(np.float32), tip_centres=np.zeros((1, 3)),
        tip_normals=np.array([[0.0, 0, 1]]), tip_radius=np.array([radius_m]),
        tip_half_edges=np.full((1, 2, 3), np.nan), tip_area=np.array([np.pi * radius_m ** 2]))


def _patch(y: float, half_m: float, step_m: float, x0: float = 0.0) -> np.ndarray:
    """Points on a square grid in the plane at palm y = ``y``, centred on x = ``x0``, z = 0."""
    v = np.arange(-half_m, half_m + 1e-12, step_m)
    xx, zz = np.meshgrid(v, v, indexing="ij")
    return np.column_stack([x0 + xx.ravel(), np.full(xx.size, y), zz.ravel()])


def _cube_cloud() -> ObjectCloud:
    v = np.arange(-0.018, 0.0181, 0.004)
    a, b = (g.ravel() for g in np.meshgrid(v, v, indexing="ij"))
    pts, nrm = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.zeros((a.size, 3))
            p[:, axis] = sign * SIDE_M / 2
            p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = a, b
            n = np.zeros_like(p)
            n[:, axis] = sign
            pts.append(p)
            nrm.append(n)
    points, normals = np.concatenate(pts), np.concatenate(nrm)
    return ObjectCloud(name="cube", points=points, normals=normals,
                       part_mask=np.ones(len(points), bool), curvature=np.zeros(len(points)),
                       source="curvature", com_m=np.zeros(3),
                       max_radius_m=float(np.linalg.norm(points, axis=1).max()),
                       z_min_m=-SIDE_M / 2, key="cube")


def _toy_hand() -> SimpleNamespace:
    fingers = ("thumb", "index", "middle")
    joints = (*(f"{f}_j{i}" for f in fingers for i in range(2)), "wrist")
    return SimpleNamespace(
        name="toy", finger_names=fingers, joint_names=joints, nq=len(joints),
        finger_qadr={f: np.array([2 * i, 2 * i + 1]) for i, f in enumerate(fingers)},
        config=SimpleNamespace(palm=SimpleNamespace(box_center=np.array([0.0, -0.3, 0.0]),
                                                    box_half_extents=np.full(3, 0.01))))


def _toy_workspace(middle_reachable: bool) -> WorkspaceCloud:
    thumb = _finger("thumb", _patch(0.0, 0.004, 0.004), [0, 1.0, 0], [0.1, 0.2])   # 9 points
    index = _finger("index", _patch(SIDE_M, 0.03, 0.004, x0=-0.01), [0, -1.0, 0], [0.3, 0.4])
    # middle: at +x of the index grid (same opposition group), or 1 m further
    x0 = 0.02 if middle_reachable else 1.02
    middle = _finger("middle", _patch(SIDE_M, 0.012, 0.004, x0=x0), [0, -1.0, 0], [0.5, 0.6])
    return WorkspaceCloud(hand="toy", fingers=(thumb, index, middle), provenance={})


TOY_PARAMS = FsgParams(fingertip_width_m=0.02, link_clearance_m=0.008, outer=20, outer_batch=5,
                       inner=6, min_valid=3)


# ------------------------------------------------------------------------------ eq. 2


def test_eq2_half_width_and_normal_sign() -> None:
    """The band is ±w_tip·|n_x|/√(n_x² + n_z²) around the contact's palm x (n_y plays no part);
    only points whose normal agrees with the contact's are removed."""
    con_nrm = np.array([0.6, 0.48, 0.8]) / np.linalg.norm([0.6, 0.48, 0.8])
    w = 0.02                       # half-width 0.6 / 1.0 · w = 12 mm
    x = np.array([[0.0119, 0.05, 0.0], [-0.0119, -0.05, 0.03], [0.0121, 0, 0], [-0.0121, 0, 0],
                  [0.0, 0.0, 0.0]])
    same = np.broadcast_to(con_nrm, x.shape)
    out = eq2_removed(x, same, np.zeros((5, 3)), np.broadcast_to(con_nrm, (5, 3)), w)
    assert out.tolist() == [True, True, False, False, True]
    opposite = eq2_removed(x, -same, np.zeros((5, 3)), np.broadcast_to(con_nrm, (5, 3)), w)
    assert not opposite.any()


def _match_one(first_cloud: FingerCloud, other: FingerCloud, obj_pts: np.ndarray,
               obj_nrm: np.ndarray, first_nrm: np.ndarray
               ) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, int]]:
    """match_fingers on one candidate with the identity transform (object frame = palm frame),
    the first finger's contact at the origin."""
    clouds = {first_cloud.name: first_cloud, other.name: other}
    params = FsgParams(fingertip_width_m=0.02, link_clearance_m=0.008)
    cands = Candidates(rot=np.eye(3)[None], trans=np.zeros((1, 3)), full=obj_pts[None],
                       first_ws=np.array([0]), first_pos=np.zeros((1, 3)),
                       first_nrm=np.asarray(first_nrm, float)[None])
    stats = {"no_match": 0}
    alive, chosen = match_fingers(np.random.default_rng(0), tuple(clouds), first_cloud.name,
                                  cands, np.arange(len(obj_pts)), obj_nrm, clouds,
                                  FingerIndex.build(clouds, params), params, stats)
    return alive, chosen, stats


def test_eq2_removes_the_used_region_in_matching() -> None:
    """Two object points the second finger could take: one 5 mm from the first contact along
    palm x (inside the 12 mm band, same normal: removed), one 20 mm away (kept)."""
    n_obj = np.array([0.6, 0.0, 0.8])
    obj_pts = np.array([[0.0, 0, 0], [0.005, 0.03, 0], [0.02, 0.03, 0]])
    obj_nrm = np.tile(n_obj, (3, 1))
    thumb = _finger("thumb", [[0.0, 0, 0]], -n_obj, 0.0)
    index = _finger("index", obj_pts[1:], -n_obj, 0.0)
    alive, chosen, stats = _match_one(thumb, index, obj_pts, obj_nrm, n_obj)
    assert stats["pairs_index"] == 2 and stats["usable_index"] == 1
    assert alive.tolist() == [0] and chosen["index"].tolist() == [1]   # the 20 mm point


# ------------------------------------------------------------------------------ crossing


def test_crossing_groups_split_by_normal_and_order_along_the_fingers() -> None:
    thumb = _finger("thumb", [[0.0, 0.0, 0.0]], [0, 0, 1.0], 0.0)
    fingers = [_finger(f, [[0.01, y, 0.05]], [0, 0, -1.0], 0.0)
               for f, y in (("index", 0.02), ("middle", 0.0), ("ring", -0.02))]
    clouds = {c.name: c for c in (thumb, *fingers)}
    g = crossing_groups(tuple(clouds), clouds)
    assert g["thumb"][0] != g["index"][0] == g["middle"][0] == g["ring"][0]
    order = [g[f][1] for f in ("index", "middle", "ring")]
    assert order == sorted(order) or order == sorted(order, reverse=True)
    assert len(set(order)) == 3
    assert abs(g["index"][2][1]) == pytest.approx(1.0)     # the spread axis is palm y here


@pytest.mark.parametrize("same_group", [True, False])
def test_crossing_rule_keeps_the_order_within_a_group(same_group: bool) -> None:
    """The index cloud lies at +y of the thumb's (mostly far-away points that only set its mean);
    an index contact at −y of the thumb's contact crosses it, which the rule forbids only when
    both clouds are in one opposition group."""
    n_obj = np.array([0.0, 0, 1.0])
    obj_pts = np.array([[0.0, 0, 0], [0.02, -0.03, 0]])     # only the crossing side
    obj_nrm = np.tile(n_obj, (2, 1))
    thumb = _finger("thumb", [[0.0, 0, 0]], -n_obj if same_group else n_obj, 0.0)
    far = np.column_stack([np.full(8, 0.02), np.linspace(0.2, 0.3, 8), np.zeros(8)])
    index = _finger("index", np.vstack([obj_pts[1:], far]), -n_obj, 0.0)
    alive, chosen, stats = _match_one(thumb, index, obj_pts, obj_nrm, n_obj)
    assert stats["pairs_index"] == 1
    if same_group:
        assert stats["usable_index"] == 0 and alive.tolist() == [] and stats["no_match"] == 1
    else:
        assert stats["usable_index"] == 1 and alive.tolist() == [0]
        assert chosen["index"].tolist() == [0]
    # the allowed side (+y) is usable in either case
    obj_pts[1, 1] = 0.03
    index = _finger("index", np.vstack([obj_pts[1:], far]), -n_obj, 0.0)
    assert _match_one(thumb, index, obj_pts, obj_nrm, n_obj)[2]["usable_index"] == 1


# ------------------------------------------------------------------------------ finger iteration


def test_finger_iteration_drops_the_least_important_finger() -> None:
    """All three fingers cannot grasp (the middle cloud is out of reach): after one round below
    ``min_valid`` the middle finger is dropped and thumb + index deliver; unused joints are 0."""
    hand, cloud, ws = _toy_hand(), _cube_cloud(), _toy_workspace(middle_reachable=False)
    res = generate(hand, cloud, ws, n=4, seed=0, time_budget_s=10, params=TOY_PARAMS)
    assert res.stopped == "done" and len(res.grasps) == 4
    assert res.finger_sets == [("thumb", "index", "middle"), ("thumb", "index")]
    for g in res.grasps:
        assert g.fingers == ("thumb", "index")
        assert g.grasp.joints.tolist() == [0.1, 0.2, 0.3, 0.4, 0.0, 0.0, 0.0]
        assert g.epsilon > 0 and set(g.contact_finger.tolist()) == {0, 1}
    # without finger iteration the same workspace yields nothing within the budget
    res = generate(hand, cloud, ws, n=4, seed=0, time_budget_s=0.5, params=TOY_PARAMS,
                   finger_iteration=False)
    assert res.stopped == "time budget" and res.grasps == []
    assert res.finger_sets == [("thumb", "index", "middle")]


def test_reachable_fingers_are_all_used() -> None:
    """Control for the test above: with the middle cloud in reach, no finger is dropped."""
    hand, cloud, ws = _toy_hand(), _cube_cloud(), _toy_workspace(middle_reachable=True)
    res = generate(hand, cloud, ws, n=2, seed=0, time_budget_s=10, params=TOY_PARAMS)
    assert res.stopped == "done" and res.finger_sets == [("thumb", "index", "middle")]
    assert all(g.grasp.joints[4:6].tolist() == [0.5, 0.6] for g in res.grasps)


def test_grasps_rejected_for_their_effort_do_not_drop_fingers() -> None:
    """Three reachable fingers whose grasps the actuators mostly cannot hold (a toy effort: 3 of
    every 4 above the limit): the first round keeps fewer than ``min_valid`` grasps (≈ 33 of
    ≈ 130 found), but the fingers did reach the object, so none is dropped (fewer fingers
    would hold even less). Counting only the kept grasps dropped the middle finger."""
    hand, cloud, ws = _toy_hand(), _cube_cloud(), _toy_workspace(middle_reachable=True)
    calls = itertools.count()

    def effort(grasp: object) -> float:
        return 0.5 if next(calls) % 4 == 3 else 2.0

    params = dataclasses.replace(TOY_PARAMS, max_actuator_effort=1.0, min_valid=40)
    res = generate(hand, cloud, ws, n=45, seed=0, time_budget_s=30, params=params, effort=effort)
    assert res.stopped == "done" and len(res.grasps) == 45
    assert res.stats["effort"] >= 2 * len(res.grasps)
    assert res.finger_sets == [("thumb", "index", "middle")]
    assert all(g.actuator_effort == 0.5 for g in res.grasps)


# ------------------------------------------------------------------------------ closure relaxation


def test_closure_filter_relaxes_when_the_budget_cannot_be_met() -> None:
    """An unreachable ε floor (``min_epsilon`` = 10) makes every geometrically valid candidate
    fail the quality step: strict (``relax_closure`` off) gives nothing within the budget; relaxed,
    the first round's zero rate cannot meet the budget, the filter is relaxed and the grasps come
    out, each recorded with its ε, all below the floor."""
    hand, cloud, ws = _toy_hand(), _cube_cloud(), _toy_workspace(middle_reachable=True)
    floor = dataclasses.replace(TOY_PARAMS, min_epsilon=10.0)
    strict = generate(hand, cloud, ws, n=3, seed=0, time_budget_s=0.5,
                      params=dataclasses.replace(floor, relax_closure=False))
    assert strict.stopped == "time budget" and strict.grasps == [] and strict.stats["epsilon"] > 0
    assert not strict.closure_relaxed
    # a generous budget: a round that finds nothing never meets any budget, so the filter is
    # relaxed after the first round whatever the budget, and the run ends as soon as it has 3
    # (10 s ran out on a loaded 2-core machine before the first round ended)
    res = generate(hand, cloud, ws, n=3, seed=0, time_budget_s=300, params=floor)
    assert res.stopped == "done" and len(res.grasps) == 3 and res.closure_relaxed
    assert res.stats["accepted_open"] == res.stats["accepted"] >= 3
    assert all(g.epsilon <= 10.0 for g in res.grasps)
    eps = [g.epsilon for g in res.grasps]
    assert eps == sorted(eps, reverse=True)


def test_a_round_that_meets_the_budget_keeps_the_filter() -> None:
    """With the default floor the toy cube gives force-closure grasps at a rate that meets the
    budget: no relaxation, every grasp in force closure."""
    hand, cloud, ws = _toy_hand(), _cube_cloud(), _toy_workspace(middle_reachable=True)
    res = generate(hand, cloud, ws, n=6, seed=0, time_budget_s=300, params=TOY_PARAMS)
    assert res.stopped == "done" and not res.closure_relaxed
    assert all(g.epsilon > 0 for g in res.grasps) and res.stats["accepted_open"] == 0


def test_misses_budget_projects_the_round_rate() -> None:
    assert misses_budget(10, 0, 1.0, 1e9)           # a round with nothing never catches up
    assert not misses_budget(10, 5, 1.0, 2.5)       # two more rounds, 2 s < 2.5 s
    assert misses_budget(10, 5, 1.0, 1.5)


# ------------------------------------------------------------------------------ de-duplication


def test_dedup_thresholds_just_inside_and_just_outside() -> None:
    """Duplicate: palm within 5 mm AND |q·q'| > 1 − 5e-3 AND every joint within 0.1 rad."""
    p = FsgParams(fingertip_width_m=0.02, link_clearance_m=0.008)
    assert (p.dedup_pos_m, p.dedup_quat, p.dedup_joint_rad) == (0.005, 5e-3, 0.1)
    d = Dedup(3, p)
    pos, q = np.array([0.1, 0.0, 0.0]), np.array([0.2, -0.1, 0.3])
    quat = mat_to_quat(np.eye(3))
    assert not d.is_duplicate(pos, quat, q)           # nothing accepted yet
    d.add(pos, quat, q)

    def turned(dot: float) -> np.ndarray:             # a rotation with |q·q'| = dot
        return mat_to_quat(axis_angle_to_mat(np.array([[0.0, 0, 1]]),
                                             np.array([2 * np.arccos(dot)]))[0])

    assert d.is_duplicate(pos, quat, q)
    assert d.is_duplicate(pos, -quat, q)              # q and −q are the same rotation
    assert d.is_duplicate(pos + np.array([0.0049, 0, 0]), quat, q)
    assert not d.is_duplicate(pos + np.array([0.0051, 0, 0]), quat, q)
    assert d.is_duplicate(pos, turned(1 - 4.9e-3), q)
    assert not d.is_duplicate(pos, turned(1 - 5.1e-3), q)
    assert d.is_duplicate(pos, quat, q + np.array([0.0, 0.099, 0]))
    assert not d.is_duplicate(pos, quat, q + np.array([0.0, 0.101, 0]))
    # all three must hold: each near miss alone is not a duplicate
    assert not d.is_duplicate(pos + np.array([0.0049, 0, 0]), quat, q + np.array([0.101, 0, 0]))


def test_merge_dedups_across_workers_in_worker_order() -> None:
    def grasp(x: float, worker: int) -> FsgGrasp:
        return FsgGrasp(grasp=Grasp(np.array([x, 0, 0]), np.array([1.0, 0, 0, 0]), np.zeros(2)),
                        fingers=("a", "b"), contact_points=np.zeros((3, 3)),
                        contact_normals=np.zeros((3, 3)), contact_finger=np.zeros(3, int),
                        ws_index=(0, 0), face_index=(0, 0), epsilon=0.1, volume=0.1,
                        worker=worker)

    outs = [([grasp(0.0, 0), grasp(0.1, 0)], {"accepted": 2}, "done", [("a", "b")]),
            ([grasp(0.003, 1), grasp(0.2, 1)], {"accepted": 2}, "time budget", [("a", "b")])]
    grasps, stats, stopped, sets = merge(outs, 2, FsgParams(fingertip_width_m=0.02, link_clearance_m=0.008))
    assert [(g.grasp.palm_pos[0], g.worker) for g in grasps] == [(0.0, 0), (0.1, 0), (0.2, 1)]
    assert stats == {"accepted": 4} and stopped == "time budget" and sets == [("a", "b")]


# ------------------------------------------------------------------------------ eq. 3


def _plane(n: int = 21) -> tuple[np.ndarray, np.ndarray]:
    """The plane z = 0 (x, y in ±5 cm), outward normal +z."""
    v = np.linspace(-0.05, 0.05, n)
    xx, yy = np.meshgrid(v, v)
    pts = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
    return pts, np.tile([0.0, 0, 1], (len(pts), 1))


def _eq3_on(skeleton: np.ndarray) -> bool:
    pts, nrm = _plane()
    _, qi = cKDTree(pts).query(skeleton)
    return eq3_crossing(skeleton, pts[qi], nrm[qi])


def test_eq3_flags_a_crossing_skeleton_not_a_clear_one() -> None:
    z = np.linspace(0.021, -0.009, 7)      # through the surface between z = 1 mm and −4 mm
    crossing = np.column_stack([np.linspace(-0.01, 0.01, 7), np.zeros(7), z])
    assert _eq3_on(crossing)
    up = np.array([0, 0, 0.012])
    assert not _eq3_on(crossing + up)      # lowest point 3 mm above the surface
    assert not _eq3_on(crossing - 3 * up)  # wholly inside: no crossing (eq. 3's limit)


def test_eq3_uses_the_normal_of_q_n_for_both_terms() -> None:
    """[(p_n − q_n)·nor_n]·[(p_n+1 − q_n+1)·nor_n]: the second term uses nor_n, not nor_n+1."""
    q = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    nor = np.array([[0.0, 0, 1], [0, 0, -1]])      # q_0 faces +z, q_1 faces −z
    both_above = np.array([[0.0, 0, 0.01], [1.0, 0, 0.01]])
    above_below = np.array([[0.0, 0, 0.01], [1.0, 0, -0.01]])
    assert not eq3_crossing(both_above, q, nor)    # with nor_1 for the second term: a crossing
    assert eq3_crossing(above_below, q, nor)       # with nor_1 for the second term: none


def test_link_penetration_in_the_palm_frame() -> None:
    """link_penetrates moves palm-frame skeletons into the object frame (x_obj = rotᵀ(x − t));
    eq. 3 alone (clearance 0) catches the crossing one, the clearance a clear one that grazes."""
    pts, nrm = _plane()
    tree = cKDTree(pts)
    rot = axis_angle_to_mat(np.array([[1.0, 0, 0]]), np.array([0.7]))[0]
    trans = np.array([0.0, 0.3, -0.2])

    def to_palm(sk_obj: np.ndarray) -> np.ndarray:
        return sk_obj @ rot.T + trans

    crossing = np.column_stack([np.zeros(5), np.zeros(5), np.linspace(0.021, -0.019, 5)])
    grazing = np.column_stack([np.linspace(-0.02, 0.02, 5), np.zeros(5), np.full(5, 0.004)])
    assert link_penetrates([to_palm(crossing)], rot, trans, tree, pts, nrm, 0.0)
    assert not link_penetrates([to_palm(grazing)], rot, trans, tree, pts, nrm, 0.0)
    assert link_penetrates([to_palm(grazing)], rot, trans, tree, pts, nrm, 0.008)
    assert not link_penetrates([to_palm(grazing + np.array([0, 0, 0.01]))], rot, trans, tree, pts, nrm,
                               0.008)


# ------------------------------------------------------------------------------ workers


def test_two_workers_are_deterministic() -> None:
    """workers=2 runs in the process pool (both workers contribute); the same seed gives the same
    grasps twice, and another seed other grasps."""
    hand, cloud, ws = _toy_hand(), _cube_cloud(), _toy_workspace(middle_reachable=False)
    params = dataclasses.replace(TOY_PARAMS, min_valid=1)
    runs = [generate(hand, cloud, ws, n=4, seed=s, workers=2, time_budget_s=60, params=params)
            for s in (3, 3, 4)]
    a, b, c = runs
    assert a.stopped == b.stopped == "done" and len(a.grasps) == len(b.grasps) == 4
    assert {g.worker for g in a.grasps} == {0, 1}

    def key(r):  # type: ignore[no-untyped-def]
        return [(g.grasp.palm_pos.tolist(), g.grasp.palm_quat_wxyz.tolist(),
                 g.grasp.joints.tolist(), g.epsilon, g.worker) for g in r.grasps]

    assert key(a) == key(b)
    assert a.stats == b.stats
    assert key(a) != key(c)


@pytest.mark.parametrize("workers", [1, 2])
def test_progress_moves_while_the_search_runs(workers: int) -> None:
    """The caller's progress sees the count grow during the search (shared memory from the pool's
    workers), never past n, and asking for it changes no grasp."""
    hand, cloud, ws = _toy_hand(), _cube_cloud(), _toy_workspace(middle_reachable=False)
    params = dataclasses.replace(TOY_PARAMS, min_valid=1)
    seen: list[int] = []
    with_progress = generate(hand, cloud, ws, n=120, seed=5, workers=workers, time_budget_s=60,
                             params=params, progress=seen.append)
    plain = generate(hand, cloud, ws, n=120, seed=5, workers=workers, time_budget_s=60,
                     params=params)
    assert len(set(seen)) >= 3, seen                       # it moved, not only 0 and the end
    assert seen == sorted(seen) and max(seen) <= 120 and min(seen) < max(seen)
    assert [g.grasp.joints.tolist() for g in with_progress.grasps] == \
        [g.grasp.joints.tolist() for g in plain.grasps]
