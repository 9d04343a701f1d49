"""``dexaug arm``: a grasp dataset's hand-only grasps evaluated on an arm at a table, written as
an arm dataset (paper §5.3).

Input: a ``grasps.h5`` of ``augment`` / ``generate`` (its passing grasps; the hand is the
table's ``hand`` attribute). Two ways to get grasps to the arm: ``carried`` (the paper's: the
dataset's grasps carried to every placement) and ``as-it-lies``
(:mod:`dexaug.pipeline.rest_grasps`: grasps made for each resting pose with the dataset's
demonstration — kept in its provenance — or the hand's manual workspace). Output: one HDF5
file (written atomically) with a group per object holding one row per (placement, grasp) —
:class:`~sim.arm.evaluate.ArmGraspResult`'s fields as columns: ``grasp`` (row in the input
table when carried, index in its resting pose's set as it lies), ``placement``,
``rest_index``, ``object_pos`` / ``object_quat_wxyz`` (the settled pose, world, m),
``palm_pose`` (the grasp's frame_palm in the object frame: position m, quaternion wxyz),
``passed``, ``failure`` and ``detail`` (text), ``arm_q_rad`` (the arm at the grasp; NaN when
not planned), ``hand_q_rad`` (the grasp's joints), ``times_s`` (K,) and
``trajectory_rad`` (K, n_arm) (the commanded piecewise-linear arm trajectory, NaN-padded),
``final_qpos`` (the whole scene's qpos — arm, hand, object — at the end of the simulation, in
the composed model's order), ``retreat`` (unit vector, world: from the grasp to the pregrasp
it was approached from), ``ik_pos_err_m``,
``ik_rot_err_rad``, ``displacement_m``, ``rotation_rad``, ``lifted_m``, ``plan_s``, ``sim_s``;
attributes: arm, hand, object, placements, seed, input file, ``grasps_from`` (carried or
as-it-lies; for as-it-lies ``made_per_rest``: grasps generated and passed per resting pose),
package versions, and the joint names of arm and hand.
"""

from __future__ import annotations

import functools
import json
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from augment import dataset
from augment.grasp_table import ObjectTable, grasps_of
from dexaug.pipeline.arm_report import ArmReportPart, write_arm_report
from dexaug.pipeline.rest_grasps import RestGrasps
from sim.arm.config import load_arm_config
from sim.arm.evaluate import ArmGraspResult, GraspSource, evaluate_on_arm
from sim.arm.scene import ArmScene
from sim.demo import Demo, DemoError, demo_from_json
from sim.errors import DexaugError
from sim.hand.model import Hand
from sim.io import atomic_path
from sim.versions import package_versions
from sim.world.objects import load_object

__all__ = ["GRASP_SOURCES", "ArmRunSummary", "run_arm", "table_demo"]

#: how grasps reach the arm (module docstring)
GRASP_SOURCES = ("carried", "as-it-lies")


@dataclass(frozen=True)
class ArmRunSummary:
    """Per object: grasps in, (placement, grasp) pairs evaluated, how many passed, the
    failures by reason, and seconds per planned arm grasp (IK + planning + simulation)."""

    object: str
    grasps: int
    pairs: int
    passed: int
    failures: dict[str, int]
    seconds: float
    seconds_per_planned: float


def _columns(results: list[ArmGraspResult], n_arm: int) -> dict[str, np.ndarray]:
    k = max((len(r.times_s) for r in results if r.times_s is not None), default=1)
    times = np.full((len(results), k), np.nan)
    traj = np.full((len(results), k, n_arm), np.nan)
    arm_q = np.full((len(results), n_arm), np.nan)
    nq = max((len(r.final_qpos) for r in results if r.final_qpos is not None), default=1)
    final = np.full((len(results), nq), np.nan)
    retreat = np.full((len(results), 3), np.nan)
    for j, r in enumerate(results):
        if r.times_s is not None:
            times[j, :len(r.times_s)] = r.times_s
            traj[j, :len(r.times_s)] = r.trajectory_rad
            arm_q[j] = r.arm_q_rad
            final[j] = r.final_qpos
            retreat[j] = r.retreat
    scalar = ("ik_pos_err_m", "ik_rot_err_rad", "displacement_m", "rotation_rad", "lifted_m",
              "plan_s", "sim_s")
    cols = {"grasp": np.array([r.grasp for r in results], int),
            "placement": np.array([r.placement for r in results], int),
            "rest_index": np.array([r.rest_index for r in results], int),
            "object_pos": np.array([r.object_pos for r in results]).reshape(-1, 3),
            "object_quat_wxyz": np.array([r.object_quat_wxyz for r in results]).reshape(-1, 4),
            "palm_pose": np.array([r.palm_pose for r in results]).reshape(-1, 7),
            "passed": np.array([r.passed for r in results], bool),
            "failure": np.array([(r.failure or "").encode() for r in results], dtype="S16"),
            "detail": np.array([r.detail.encode() for r in results], dtype=h5py.string_dtype()),
            "arm_q_rad": arm_q,
            "hand_q_rad": np.array([r.hand_q_rad for r in results]).reshape(len(results), -1),
            "times_s": times, "trajectory_rad": traj, "final_qpos": final, "retreat": retreat}
    cols.update({c: np.array([getattr(r, c) for r in results], float) for c in scalar})
    return cols


def table_demo(path: Path, name: str, table: dataset.ObjectTable) -> Demo | None:
    """The demonstration a table was augmented from (its ``demo`` provenance), None for a
    table made without one; a clear error for a demo-made table that does not keep it."""
    text = str(table.attrs.get("demo") or "")
    if text:
        try:
            return demo_from_json(json.loads(text), f"{path} [{name}] attribute 'demo'")
        except json.JSONDecodeError as exc:
            raise DexaugError(f"{path}: table {name!r} attribute 'demo' is not JSON ({exc})") from None
    if str(table.attrs.get("demo_source") or ""):
        raise DexaugError(f"{path}: table {name!r} was augmented from a demonstration but does not "
                          f"keep it (made before this version); augment it again to use "
                          f"--grasps as-it-lies")
    return None


def _stages_of(progress: Callable[[str, int, int], None] | None,
               name: str) -> Callable[[str, int, int], None] | None:
    """``progress`` with each stage named after the object ``name`` (one bar per object and
    stage when several objects are put on the arm), or None without a callback."""
    if progress is None:
        return None
    report = progress

    def tick(stage: str, done: int, total: int) -> None:
        report(f"{name} {stage}", done, total)

    return tick


def run_arm(grasps_path: Path, arm_name: str, out: Path, *, placements: int, seed: int = 0,
            object_name: str | None = None, max_grasps: int | None = None,
            progress: Callable[[str, int, int], None] | None = None,
            grasps_from: str = "carried", workers: int = 1,
            report: Path | None = None, gallery: int = 4) -> list[ArmRunSummary]:
    """Evaluate the dataset's grasps on ``arm_name`` at ``placements`` placements per object
    and write ``out`` (module docstring); one summary per object. ``grasps_from``: one of
    :data:`GRASP_SOURCES`; as it lies, each resting pose drawn gets ``max_grasps`` (default:
    as many as the table holds) new grasps, made and validated on ``workers`` processes.
    ``report``: also write this HTML report (:mod:`dexaug.pipeline.arm_report`) with up to
    ``gallery`` images of held grasps per object."""
    if grasps_from not in GRASP_SOURCES:
        raise DexaugError(f"grasps_from {grasps_from!r}: expected one of {GRASP_SOURCES}")
    tables: dict[str, ObjectTable] = dataset.load(grasps_path)
    if object_name is not None:
        if object_name not in tables:
            raise DexaugError(f"{grasps_path}: no table for object {object_name!r} "
                              f"(it has {sorted(tables)})")
        tables = {object_name: tables[object_name]}
    arm = load_arm_config(arm_name)
    summaries, groups, parts = [], {}, []
    for name, table in tables.items():
        hand_name = str(table.attrs.get("hand") or "")
        if not hand_name:
            raise DexaugError(f"{grasps_path}: table {name!r} has no 'hand' attribute")
        hand = Hand.load(hand_name)
        grasps = grasps_of(table, max_grasps)
        if not grasps:
            raise DexaugError(f"{grasps_path}: table {name!r} holds no grasp to put on an arm")
        obj = load_object(name)
        source: GraspSource = grasps
        if grasps_from == "as-it-lies":
            try:
                demo = table_demo(grasps_path, name, table)
            except DemoError as exc:
                raise DexaugError(str(exc)) from None
            source = RestGrasps(
                hand, obj, demo, n=len(grasps), seed=seed, workers=workers,
                progress=_stages_of(progress, name))
        _, results = evaluate_on_arm(
            arm, hand, obj, source, placements=placements, seed=seed,
            progress=functools.partial(progress, name) if progress else None)
        planned = [r for r in results if r.times_s is not None]
        seconds = sum(r.plan_s + r.sim_s for r in results)
        summaries.append(ArmRunSummary(
            name, len(grasps), len(results), sum(r.passed for r in results),
            dict(Counter(r.failure for r in results if r.failure)), seconds,
            sum(r.plan_s + r.sim_s for r in planned) / len(planned) if planned else float("nan")))
        made = source.made if isinstance(source, RestGrasps) else {}
        groups[name] = (_columns(results, len(arm.joints)), hand, made)
        if report is not None:
            parts.append(ArmReportPart(name, ArmScene(arm, hand, obj), results, placements,
                                       grasps_from, made))
    with atomic_path(out) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = "dexaug-arm-grasps-1"
        f.attrs["versions"] = json.dumps(package_versions())
        for name, (cols, hand, made) in groups.items():
            g = f.create_group(name)
            for key, value in cols.items():
                g.create_dataset(key, data=value)
            g.attrs.update({"arm": arm.name, "hand": hand.name, "object": name,
                            "placements": placements, "seed": seed, "input": str(grasps_path),
                            "grasps_from": grasps_from,
                            "made_per_rest": json.dumps({str(k): v for k, v in made.items()}),
                            "arm_joints": json.dumps(list(arm.joints)),
                            "hand_joints": json.dumps(list(hand.joint_names))})
    if report is not None:
        write_arm_report(report, arm.name, parts[0].scene.hand.name, parts, gallery=gallery)
    return summaries
