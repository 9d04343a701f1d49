"""Hand-only grasps evaluated on an arm at a table (paper §5.3), placement by placement.

For each placement (:func:`~sim.arm.placement.sample_placements`) the object is dropped there
and settles (:func:`~sim.arm.simulate.settle_object`); every grasp is carried to the settled
pose, pre-filtered against the table (:func:`~sim.arm.placement.table_clear`), planned
(:func:`~sim.arm.plan.plan_grasp`: IK, approach, collision checks) and simulated
(:func:`~sim.arm.simulate.simulate_plan`). Each (placement, grasp) gets one
:class:`ArmGraspResult` whose ``failure`` says what stopped it: ``table`` (the hand would be in
the table), ``unreachable``, ``collision``, ``pushed``, ``dropped``, ``slipped``; None when the
object was lifted and held. The pregrasp and squeeze of each grasp are the hand-only
validator's (same convention, same contact-derived targets), and the hand's servos, contacts
and the pose limits are ``configs/validate.toml``'s lift-drop ones.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from sim.arm.config import ArmConfig
from sim.arm.placement import Placement, palm_targets, sample_placements, table_clear
from sim.arm.plan import ApproachSettings, plan_grasp
from sim.arm.scene import ArmScene
from sim.arm.simulate import ArmOutcome, ArmTiming, settle_object, simulate_plan
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.validate.config import ValidateConfig
from sim.validate.stages import GraspStages
from sim.validate.validator import Validator
from sim.world.objects import ObjectAsset
from sim.world.resting import RestPose, resting_poses

__all__ = ["ArmGraspResult", "GraspSource", "evaluate_on_arm"]

#: hand-only grasps (object frame) for the arm: one sequence carried to every placement, or a
#: function of (resting pose index, resting pose) giving grasps made for the object lying so
GraspSource = Sequence[Grasp] | Callable[[int, RestPose], Sequence[Grasp]]


@dataclass(frozen=True)
class ArmGraspResult:
    """One grasp at one placement: ``grasp`` index (in the sequence given, or in its resting
    pose's set), ``placement`` and its ``rest_index`` (with the settled object pose
    ``object_pos`` / ``object_quat_wxyz``), the grasp itself (``palm_pose``: frame_palm in
    the object frame, position m + quaternion wxyz; ``hand_q_rad``), ``failure`` (module
    docstring) and ``detail``;
    for planned grasps the whole-body configuration at the grasp (``arm_q_rad`` and the
    grasp's hand joints), the commanded trajectory (``times_s``, ``trajectory_rad`` (K, n_arm)),
    the scene's qpos at the end of the simulation (``final_qpos``: arm, hand and object), the
    unit direction (world) from the grasp to the pregrasp it was approached from (``retreat``),
    the IK errors at the grasp, the simulated pose change (m, rad) and rise (m); seconds spent
    planning and simulating."""

    grasp: int
    placement: int
    rest_index: int
    object_pos: np.ndarray
    object_quat_wxyz: np.ndarray
    palm_pose: np.ndarray
    hand_q_rad: np.ndarray
    failure: str | None
    detail: str = ""
    arm_q_rad: np.ndarray | None = None
    times_s: np.ndarray | None = None
    trajectory_rad: np.ndarray | None = None
    final_qpos: np.ndarray | None = None
    retreat: np.ndarray | None = None
    ik_pos_err_m: float = float("nan")
    ik_rot_err_rad: float = float("nan")
    displacement_m: float = float("nan")
    rotation_rad: float = float("nan")
    lifted_m: float = float("nan")
    plan_s: float = 0.0
    sim_s: float = 0.0

    @property
    def passed(self) -> bool:
        return self.failure is None


def evaluate_on_arm(arm: ArmConfig, hand: Hand, obj: ObjectAsset, grasps: GraspSource, *,
                    placements: int, seed: int = 0, config: ValidateConfig | None = None,
                    approach: ApproachSettings | None = None, timing: ArmTiming | None = None,
                    area_margin_m: float = 0.15, rest_index: int | None = None,
                    progress: Callable[[int, int], None] | None = None,
                    ) -> tuple[list[Placement], list[ArmGraspResult]]:
    """Evaluate ``grasps`` (:data:`GraspSource`; a function is called once per resting pose
    drawn) of ``hand`` on ``obj`` carried by ``arm`` at ``placements`` seeded placements on
    the table (its top minus ``area_margin_m`` at each edge); results in placement-major order;
    ``rest_index`` places the object only in that resting pose. ``progress(done, total)``
    counts (placement, grasp) pairs (total known once every pose's grasps are)."""
    cfg = config or ValidateConfig.load()
    validator = Validator(hand, obj, cfg)
    scene = ArmScene(arm, hand, obj, contact=cfg.common.contact, servos=validator.servos)
    table = scene.table
    assert table is not None   # the scene above has the default table
    (cx, cy), (hx, hy) = table.center_xy_m, table.half_size_xy_m
    poses = resting_poses(obj)
    places = sample_placements(obj, poses, placements, seed=seed,
                               area_x_m=(cx - hx + area_margin_m, cx + hx - area_margin_m),
                               area_y_m=(cy - hy + area_margin_m, cy + hy - area_margin_m),
                               top_z_m=table.top_z_m, rest_index=rest_index)
    sets: dict[int, tuple[list[Grasp], list[GraspStages]]] = {}
    for k in dict.fromkeys(p.rest_index for p in places):
        gs = list(grasps(k, poses[k]) if callable(grasps) else grasps)
        sets[k] = (gs, [validator.stages(g) for g in gs])
    limits = {"max_displacement_m": cfg.lift_drop.max_displacement_m,
              "max_rotation_rad": cfg.lift_drop.max_rotation_rad}
    out: list[ArmGraspResult] = []
    total = sum(len(sets[p.rest_index][0]) for p in places)
    for p in places:
        gs, stages = sets[p.rest_index]
        if not gs:
            continue
        settled = settle_object(scene, p.pos, p.quat_wxyz)
        obj_q = settled.qpos[scene.obj_qadr:scene.obj_qadr + 7].copy()
        pos, quat = obj_q[:3], obj_q[3:]
        clear = table_clear(hand, gs, pos, quat, top_z_m=table.top_z_m)
        targets = palm_targets(gs, pos, quat)
        for i, g in enumerate(gs):
            base = {"grasp": i, "placement": p.index, "rest_index": p.rest_index,
                    "object_pos": pos, "object_quat_wxyz": quat,
                    "palm_pose": np.concatenate([g.palm_pos, g.palm_quat_wxyz]),
                    "hand_q_rad": np.asarray(g.joints, float)}
            if not clear[i]:
                out.append(ArmGraspResult(**base, failure="table",
                                          detail="the hand at the grasp is in the table"))
            else:
                out.append(_plan_and_simulate(scene, settled, targets[0][i], targets[1][i], g,
                                              stages[i], obj_q, base, approach, timing, limits))
            if progress is not None:
                progress(len(out), total)
    return places, out


def _plan_and_simulate(scene: ArmScene, settled: mujoco.MjData, palm_pos: np.ndarray,
                       palm_quat: np.ndarray, grasp: Grasp, stage: GraspStages, obj_q: np.ndarray,
                       base: dict[str, Any], approach: ApproachSettings | None,
                       timing: ArmTiming | None, limits: dict[str, float]) -> ArmGraspResult:
    """Plan one grasp and, when planned, simulate it; the result either way."""
    t0 = time.perf_counter()
    plan = plan_grasp(scene, palm_pos, palm_quat, stage.pregrasp, grasp.joints, obj_q,
                      settings=approach)
    plan_s = time.perf_counter() - t0
    if plan.failure is not None:
        return ArmGraspResult(**base, failure=plan.failure, detail=plan.detail, plan_s=plan_s)
    assert plan.approach is not None   # a plan without a failure has its waypoints
    t0 = time.perf_counter()
    sim = simulate_plan(scene, settled, plan, stage.squeeze, timing=timing,
                        **limits)
    at_grasp = plan.ik[len(plan.approach) - 1]
    return ArmGraspResult(
        **base, failure=sim.failure, detail="" if sim.passed else _sim_detail(sim),
        arm_q_rad=plan.approach[-1], times_s=sim.times_s, trajectory_rad=sim.arm_q_rad,
        final_qpos=sim.final_qpos, retreat=plan.retreat,
        ik_pos_err_m=at_grasp.pos_err_m, ik_rot_err_rad=at_grasp.rot_err_rad,
        displacement_m=sim.displacement_m, rotation_rad=sim.rotation_rad, lifted_m=sim.lifted_m,
        plan_s=plan_s, sim_s=time.perf_counter() - t0)


def _sim_detail(sim: ArmOutcome) -> str:
    return (f"object moved {sim.displacement_m * 1e3:.1f} mm, turned "
            f"{np.degrees(sim.rotation_rad):.1f}°, rose {sim.lifted_m * 1e3:.0f} mm")
