"""Grasps for an object as it lies (#15): lift-drop pulls along a chosen gravity direction,
FSG's table mode keeps every finger link out of the table, and ``dexaug arm --grasps
as-it-lies`` makes grasps per resting pose from the demonstration its dataset keeps."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from augment.autows.build import build_workspace
from augment.autows.seed import DemoSeed
from augment.fsg.candidates import links_below_table
from augment.fsg.params import load_fsg_params
from augment.fsg.run import generate
from augment.fsg.table import TablePlane
from augment.object_cloud import object_cloud
from dexaug.cli import main
from dexaug.pipeline.options import AugmentOptions
from dexaug.pipeline.rest_grasps import RestGrasps, rest_table_plane
from dexaug.pipeline.run import augment_demo
from sim.arm.config import load_arm_config
from sim.arm.evaluate import evaluate_on_arm
from sim.arm.plan import ApproachSettings
from sim.demo import load_demo
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.transforms import quat_to_mat
from sim.validate.config import GRAVITY_MPS2
from sim.validate.validator import Validator
from sim.world.objects import load_object
from sim.world.render import gl_available
from sim.world.resting import resting_poses
from tests.conftest import needs_menagerie, needs_ycb

pytestmark = [pytest.mark.slow, needs_menagerie, needs_ycb, pytest.mark.timeout(300)]

REPO = Path(__file__).resolve().parents[1]
CAN = "005_tomato_soup_can"
DEMO = REPO / "recordings" / "demos" / f"{CAN}.json"


@pytest.fixture(scope="module")
def box(shadow: Hand):
    grasp = next(r.grasp for r in load_reference_grasps(shadow) if r.object == "004_sugar_box")
    return Validator(shadow, load_object("004_sugar_box")), grasp


def test_lift_drop_pulls_and_lifts_along_the_gravity_direction(box) -> None:
    validator, grasp = box
    scene = validator.scene("lift-drop")
    seen: list[tuple[np.ndarray, np.ndarray]] = []

    def observe(phase: str) -> None:
        if phase == "lift":
            seen.append((scene.model.opt.gravity.copy(), scene.data.mocap_pos[scene.mocap_id].copy()))

    result = validator.validate(grasp, observe=observe, gravity_dir=np.array([2.0, 0.0, 0.0]))
    assert result.phases["lift"].passed, result     # the lift ran to its end
    gravity, _ = seen[0]
    assert np.allclose(gravity, [GRAVITY_MPS2, 0.0, 0.0])       # normalised, pulls along +x
    # from the first lift chunk to the last the hand rose 49/50 of the lift against gravity
    # (along −x), not along z
    moved = seen[-1][1] - seen[0][1]
    lift_m = validator.config.lift_drop.lift_height_m
    assert moved == pytest.approx([-lift_m * 49 / 50, 0.0, 0.0], abs=1e-9)


def test_default_gravity_is_minus_z_and_another_direction_changes_the_outcome(box) -> None:
    validator, grasp = box
    default = validator.validate(grasp)
    minus_z = validator.validate(grasp, gravity_dir=np.array([0.0, 0.0, -1.0]))
    assert (default.passed, default.displacement_m, default.rotation_rad) == \
        (minus_z.passed, minus_z.displacement_m, minus_z.rotation_rad)
    sideways = validator.validate(grasp, gravity_dir=np.array([0.0, 1.0, 0.0]))
    assert sideways.displacement_m != default.displacement_m


@pytest.mark.parametrize("bad", [np.zeros(3), np.array([1.0, 0.0]), np.array([np.nan, 0, 1])])
def test_a_bad_gravity_direction_is_one_clear_error(box, bad: np.ndarray) -> None:
    validator, grasp = box
    with pytest.raises(ValueError, match="gravity_dir"):
        validator.validate(grasp, gravity_dir=bad)
    with pytest.raises(ValueError, match="lift-drop"):
        validator.validate(grasp, "six-dir", gravity_dir=np.array([0.0, 0.0, -1.0]))


def test_links_below_table_sees_any_skeleton_point_under_the_plane() -> None:
    plane = TablePlane.horizontal(0.0)
    rot, trans = np.eye(3), np.zeros(3)
    above = [np.array([[0.0, 0.0, 0.05], [0.01, 0.0, 0.03]])]
    assert not links_below_table(above, rot, trans, plane, clearance_m=0.02)
    assert links_below_table(above, rot, trans, plane, clearance_m=0.04)
    # the transform is object → palm: a palm frame 10 cm above the object's origin lifts nothing
    # of the skeleton (it is given in the palm frame) but moves it up in the object frame
    lifted = links_below_table([np.array([[0.0, 0.0, -0.05]])], rot, np.array([0.0, 0.0, -0.1]),
                               plane, clearance_m=0.02)
    assert not lifted


def _lowest_link_elevation_m(hand: Hand, grasps, plane: TablePlane) -> np.ndarray:
    """Per grasp, the lowest point of every finger's skeleton above ``plane`` (object frame)."""
    q = np.array([g.joints for g in grasps])
    out = np.full(len(grasps), np.inf)
    for f in hand.finger_names:
        sk = hand.skeleton(q, f)                                   # (N, K, 3) frame_palm
        rot = quat_to_mat(np.array([g.palm_quat_wxyz for g in grasps]))
        pos = np.array([g.palm_pos for g in grasps])
        obj_pts = pos[:, None] + np.einsum("nij,nkj->nki", rot, sk)
        out = np.minimum(out, plane.elevation_m(obj_pts).min(axis=1))
    return out


def test_table_mode_keeps_every_finger_link_out_of_the_table(shadow: Hand) -> None:
    obj = load_object(CAN)
    cloud = object_cloud(obj)
    side = next(p for p in resting_poses(obj).poses if not p.upright)   # the can on its side
    plane = rest_table_plane(np.asarray(cloud.points), side)
    ws = build_workspace(shadow, demo=DemoSeed.from_demo(load_demo(DEMO)))
    made = generate(shadow, cloud, ws, n=12, table=plane, seed=0, workers=1, time_budget_s=60)
    assert len(made.grasps) >= 6
    p = load_fsg_params(shadow.config)
    low = _lowest_link_elevation_m(shadow, [g.grasp for g in made.grasps], plane)
    assert (low >= p.link_clearance_m + p.table_clearance_m - 1e-9).all(), low
    # the check can fail: without table mode, grasps of the same workspace reach into that table
    free = generate(shadow, cloud, ws, n=12, table=False, seed=0, workers=1, time_budget_s=60)
    low_free = _lowest_link_elevation_m(shadow, [g.grasp for g in free.grasps], plane)
    assert (low_free < p.link_clearance_m + p.table_clearance_m).any()


@pytest.fixture(scope="module")
def grasps_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The 005 demo augmented as ``dexaug augment`` does (8 grasps): its dataset keeps the demo."""
    out = tmp_path_factory.mktemp("aug")
    summary = augment_demo(load_demo(DEMO), out, AugmentOptions(n=8, workers=1, gallery=0))
    return Path(summary.dataset)


def _rows(path: Path) -> dict[str, np.ndarray]:
    with h5py.File(path, "r") as f:
        g = f[CAN]
        rows = {k: g[k][:] for k in g}
        rows["attrs"] = dict(g.attrs)
    return rows


def test_arm_as_it_lies_makes_grasps_per_resting_pose(grasps_file: Path, tmp_path: Path) -> None:
    carried, lies = tmp_path / "carried.h5", tmp_path / "lies.h5"
    common = [str(grasps_file), "--arm", "ur5e", "--placements", "3", "--max-grasps", "6",
              "--seed", "1", "--workers", "1"]
    assert main(["arm", *common, "--out", str(carried)]) == 0
    report = tmp_path / "lies.html"
    assert main(["arm", *common, "--grasps", "as-it-lies", "--out", str(lies),
                 "--report", str(report)]) == 0
    c, s = _rows(carried), _rows(lies)
    _check_report(report, s)
    assert s["attrs"]["grasps_from"] == "as-it-lies" and c["attrs"]["grasps_from"] == "carried"
    made = {int(k): v for k, v in json.loads(s["attrs"]["made_per_rest"]).items()}
    poses = resting_poses(load_object(CAN))
    for placement in set(s["placement"]):
        at = s["placement"] == placement
        (k,) = set(s["rest_index"][at])
        assert at.sum() == made[k]["passed"] <= made[k]["generated"]
        # the object lay in that resting pose: its settled "down" is the pose's
        quat = s["object_quat_wxyz"][at][0]
        assert np.dot(quat_to_mat(quat).T @ [0, 0, -1.0], poses[k].down) > np.cos(np.radians(5))
    # carried grasps keep the dataset's palm poses; grasps made as it lies are new ones
    assert np.isin(c["palm_pose"][:, 0], _dataset_palm_x(grasps_file)).all()
    assert not np.isin(s["palm_pose"][:, 0], _dataset_palm_x(grasps_file)).any()
    # made for the pose, they clear the table far more often than grasps made upright
    table_share = [np.mean(r["failure"] == b"table") for r in (c, s)]
    assert table_share[1] < table_share[0], table_share


def _check_report(report: Path, rows: dict[str, np.ndarray]) -> None:
    """The report states the file's numbers and shows a held grasp per image."""
    text = report.read_text()
    held, n = int(rows["passed"].sum()), len(rows["passed"])
    assert f"<th>placement × grasp pairs</th><td>{n}</td>" in text
    assert f"<th>held</th><td>{held} (" in text if held else "<th>held</th><td>0</td>" in text
    images = sorted((report.parent / f"{report.stem}_images").glob("*.png"))
    if gl_available() is not None:
        assert len(images) == min(held, 4) and all(i.name in text for i in images)
        for image in images:                       # each pictured grasp is a held one
            p, g = (int(x[1:]) for x in image.stem.split("_")[-2:])
            assert rows["passed"][(rows["placement"] == p) & (rows["grasp"] == g)].all()


def _dataset_palm_x(path: Path) -> np.ndarray:
    with h5py.File(path, "r") as f:
        return f[CAN]["palm_pose"][:, 0]


def test_as_it_lies_without_the_demo_is_one_clear_error(grasps_file: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    old = tmp_path / "old.h5"
    shutil.copy(grasps_file, old)
    with h5py.File(old, "r+") as f:
        del f[CAN].attrs["demo"]          # as datasets made before the demo was kept
    assert main(["arm", str(old), "--grasps", "as-it-lies", "--placements", "1",
                 "--out", str(tmp_path / "x.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "augment it again" in err and str(old) in err
    assert not (tmp_path / "x.h5").exists()


def test_a_blocked_palm_approach_is_planned_from_above(shadow: Hand) -> None:
    """Grasps of the can lying on its side, at three placements: planning that may also come
    down from above plans every grasp the palm-normal approach plans, and more; the extra
    ones came from above and still lift the can or fail in simulation, never in planning."""
    obj = load_object(CAN)
    side = next(k for k, p in enumerate(resting_poses(obj).poses) if not p.upright)
    source = RestGrasps(shadow, obj, load_demo(DEMO), n=24, seed=0, workers=1)
    runs = {}
    for name, settings in (("palm", ApproachSettings(retreats=((1.0, 0.0),))),
                           ("default", ApproachSettings())):
        _, runs[name] = evaluate_on_arm(load_arm_config("ur5e"), shadow, obj, source,
                                        placements=3, seed=3, rest_index=side, approach=settings)
    planned = {k: {(r.placement, r.grasp) for r in v if r.times_s is not None}
               for k, v in runs.items()}
    assert planned["palm"] <= planned["default"]
    extra = planned["default"] - planned["palm"]
    assert extra, "no grasp needed another approach: the check could not fail here"
    for r in runs["default"]:
        if (r.placement, r.grasp) in extra:
            assert r.retreat[2] > 0.5, r.retreat              # halfway up or straight up
        elif r.retreat is not None:
            assert abs(r.retreat @ np.array([0, 0, 1.0])) < 1.0
