"""Why grasps fail the benchmark (``dgb``): where the drift comes from, and what the hand does.

Most ``dgb`` failures happen in the closing, before the first push (README "Grasps that hold"),
and the benchmark's verdict alone does not say why. :func:`diagnose_dgb` replays one grasp with
the validator's own stages (so the same verdict) and adds:

- the free object's drift after the grasp stage and after the squeeze stage
  (:func:`sim.validate.dgb.closing_drift`), and the first push direction that failed;
- the **held closing**: the same closing with the object held exactly still. The hand's net
  force and torque on it (:func:`hand_wrench`) say how far the squeeze is from balancing on its
  own; a free object moves until they balance. ``imbalance_n`` is ‖F‖ + ‖τ‖ / 2 cm, averaged
  over the closing's control steps (predicts the verdict on four of five demos,
  ``benchmarks/bench_dgb_demo_hand.py``);
- per tendon-shared joint pair (:mod:`sim.validate.free_modes`: one servo, the split free), how
  far the split J1 − J2 moved in the held closing: a pressed finger that reconfigures rolls its
  fingertip over the object;
- the planned contacts (hand bodies within ``[dgb] contact_search_m`` at the grasp stage) that
  carry no force at the end of the held closing;
- the **hardest push** replayed (:func:`replay_push`: the first failing one, else the one that
  turned the object most): its direction in frame_palm, the hand's total normal force on the
  object when it starts and at its last check inside the limits, and how far each tendon-shared
  pair's split moved in it.

Units: metres, newtons, N·m, radians (degrees only in the summary's printed drift).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from sim.grasp import Grasp
from sim.transforms import quat_to_mat
from sim.validate.config import DgbParams
from sim.validate.dgb import DGB_DIRECTIONS, closed, closing_drift, push
from sim.validate.effort import closest_per_body
from sim.validate.stages import GraspStages
from sim.validate.validator import Validator
from sim.world.contacts import contacts_between
from sim.world.scene import HAND_PREFIX, Scene

__all__ = ["IMBALANCE_LEVER_M", "DgbDiagnosis", "PushReplay", "diagnose_dgb", "hand_wrench", "held_closing",
           "held_steps", "replay_push", "summarise_dgb"]

#: lever (metres) that turns the held net torque into newtons for ``imbalance_n``
IMBALANCE_LEVER_M = 0.02
#: a pair's split moving more than this (radians) in the held closing counts as reconfigured
RECONFIGURED_RAD = 0.1


def held_steps(scene: Scene, nstep: int) -> None:
    """``nstep`` simulation steps with the object held exactly where it is (its pose restored
    and its velocity zeroed after every step): the hand's forces on it can be read, not its
    motion."""
    m, d = scene.model, scene.data
    qadr = m.jnt_qposadr[m.body_jntadr[scene.obj_body]]
    pose = d.qpos[qadr:qadr + 7].copy()
    for _ in range(nstep):
        mujoco.mj_step(m, d)
        d.qpos[qadr:qadr + 7] = pose
        d.qvel[scene.obj_dadr:scene.obj_dadr + 6] = 0.0


def hand_wrench(scene: Scene) -> tuple[np.ndarray, np.ndarray, set[int]]:
    """The hand's contacts on the object: net force (N, world), net torque about the object's
    centre of mass (N·m, world; contact torsion included) and the ids of the hand bodies
    pressing it."""
    m, d = scene.model, scene.data
    centre = d.xipos[scene.obj_body]
    force, torque, bodies = np.zeros(3), np.zeros(3), set()
    f6 = np.zeros(6)
    for i in range(d.ncon):
        con = d.contact[i]
        g1, g2 = int(con.geom1), int(con.geom2)
        b1, b2 = int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])
        if scene.obj_body not in (b1, b2) or not (scene.hand_geom_mask[g1] or scene.hand_geom_mask[g2]):
            continue
        mujoco.mj_contactForce(m, d, i, f6)
        frame = con.frame.reshape(3, 3)
        sign = 1.0 if b2 == scene.obj_body else -1.0      # the contact frame's force acts on geom2
        f = sign * frame.T @ f6[:3]
        force += f
        torque += sign * frame.T @ f6[3:] + np.cross(con.pos - centre, f)
        if f6[0] > 0.0:
            bodies.add(b1 if b2 == scene.obj_body else b2)
    return force, torque, bodies


@dataclass(frozen=True)
class HeldClosing:
    """The benchmark's closing run on the held object: ``imbalance_n`` per control step (N),
    the net force and torque at its end, the hand bodies pressing at its end, and the split
    J1 − J2 of each tendon-shared pair (by the pair's joint names) at its start and end."""

    imbalance_n: np.ndarray
    force_n: np.ndarray
    torque_nm: np.ndarray
    pressing: set[str]
    split_rad: dict[str, tuple[float, float]]


def _splits(scene: Scene) -> dict[str, float]:
    m, d, hand = scene.model, scene.data, scene.hand
    out = {}
    for follower, leader, _ in hand.couplings:
        a, b = (hand.joint_names[k] for k in (follower, leader))
        ja, jb = m.joint(HAND_PREFIX + a), m.joint(HAND_PREFIX + b)
        out[f"{b}/{a}"] = float(d.qpos[ja.qposadr[0]] - d.qpos[jb.qposadr[0]])
    return out


def held_closing(scene: Scene, steps: tuple[int, int], palm_world: tuple[np.ndarray, np.ndarray],
                 stages: GraspStages) -> HeldClosing:
    """Close pregrasp → grasp → squeeze as the benchmark does (``steps``: its increments per
    stage and simulation steps per increment) with the object held still."""
    increments, per_increment = steps
    m, d = scene.model, scene.data
    scene.reset_with_grasp(*palm_world, stages.pregrasp)
    mujoco.mj_forward(m, d)
    start = _splits(scene)
    imbalance = []
    for q_from, q_to in ((stages.pregrasp, stages.grasp), (stages.grasp, stages.squeeze)):
        c_from, c_to = scene.ctrl_for(q_from), scene.ctrl_for(q_to)
        for k in range(1, increments + 1):
            d.ctrl[scene.hand_act] = c_from + (c_to - c_from) * k / increments
            held_steps(scene, per_increment)
            mujoco.mj_forward(m, d)
            force, torque, _ = hand_wrench(scene)
            imbalance.append(np.linalg.norm(force) + np.linalg.norm(torque) / IMBALANCE_LEVER_M)
    force, torque, bodies = hand_wrench(scene)
    end = _splits(scene)
    return HeldClosing(np.array(imbalance), force, torque,
                       {m.body(b).name.removeprefix(HAND_PREFIX) for b in bodies},
                       {k: (start[k], end[k]) for k in start})


@dataclass
class DgbDiagnosis:
    """One grasp's ``dgb`` replay: the verdict, and the findings (plain data, JSON-ready)."""

    passed: bool
    findings: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class PushReplay:
    """One push of the benchmark replayed from its closing: its direction in frame_palm (unit),
    the hand's total normal force on the object (N) when the push starts and at the last check
    the object was still inside the limits, each tendon-shared pair's split J1 − J2 moved
    (radians) from the push's start to where it ended (its first failing check, or its end),
    and the object's drift there (metres, radians; the benchmark's phase result)."""

    direction_palm: np.ndarray
    grip_start_n: float
    grip_end_n: float
    split_moved_rad: dict[str, float]
    drift_m_rad: tuple[float, float]


def _grip_n(scene: Scene) -> float:
    con = contacts_between(scene.model, scene.data, scene.hand_geom_mask, scene.obj_geom_mask,
                           with_force=True)
    return float(con.force_n.sum())


def replay_push(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
                stages: GraspStages, direction: str) -> PushReplay:
    """The benchmark's push ``direction`` (a key of :data:`sim.validate.dgb.DGB_DIRECTIONS`)
    after its closing of ``stages``, checked as it checks (every ``check_every_steps`` steps
    against its limits from the object's pose at the pregrasp), with the grip and the splits
    read along the way. Why: a pinch's servos may hold the sum of a tendon-shared pair while
    the push turns the pair to its stop and the fingertip backs off the object, which the
    closing alone does not show (README "Grasps that hold", the dice)."""
    m, d = scene.model, scene.data
    scene.reset_with_grasp(*palm_world, stages.pregrasp)
    pose0 = scene.object_pose()
    closed(scene, p, palm_world, stages)
    mujoco.mj_forward(m, d)
    start, grips = _splits(scene), [_grip_n(scene)]

    def read_grip() -> None:
        mujoco.mj_forward(m, d)
        grips.append(_grip_n(scene))

    _, disp, rot = push(scene, p, pose0, direction, read_grip)
    d.xfrc_applied[scene.obj_body] = 0.0
    end = _splits(scene)
    return PushReplay(quat_to_mat(palm_world[1]).T @ np.asarray(DGB_DIRECTIONS[direction], float),
                      grips[0], grips[-1], {k: end[k] - start[k] for k in start}, (disp, rot))


def _planned_bodies(v: Validator, grasp: Grasp, stages: GraspStages) -> set[str]:
    """Hand bodies within ``[dgb] contact_search_m`` of the object at the grasp stage."""
    scene = v.scene("lift-drop")
    scene.reset_with_grasp(*v.palm_world(grasp), stages.grasp)
    near = v.near_contacts(scene, v.config.dgb.contact_search_m)
    return {scene.model.body(int(near.body_a[i])).name.removeprefix(HAND_PREFIX)
            for i in closest_per_body(near)}


def diagnose_dgb(v: Validator, grasp: Grasp) -> DgbDiagnosis:
    """Replay ``grasp`` under ``dgb`` with ``v``'s stages and settings (module docstring)."""
    result = v.validate(grasp, "dgb")
    stages = v.stages(grasp, sized_for="dgb")
    p, scene = v.config.dgb, v.scene("dgb")
    drift = closing_drift(scene, p, v.palm_world(grasp), stages)
    held = held_closing(scene, (p.stage_increments, p.steps_per_increment), v.palm_world(grasp),
                        stages)
    planned = _planned_bodies(v, grasp, stages)
    failed = [k for k, ph in result.phases.items() if not ph.passed]
    moved = {k: end - start for k, (start, end) in held.split_rad.items()}
    hardest = failed[0] if failed else max(result.phases, key=lambda k: result.phases[k].rotation_rad,
                                           default=None)
    push = None if hardest is None else replay_push(scene, p, v.palm_world(grasp), stages, hardest)
    return DgbDiagnosis(result.passed, {
        "verdict": "passed" if result.passed else str(result.failure),
        "failing_push": failed[0] if failed else None,
        "drift_after_grasp_m_rad": list(drift["grasp"]),
        "drift_after_squeeze_m_rad": list(drift["squeeze"]),
        "held_imbalance_mean_n": float(held.imbalance_n.mean()),
        "held_force_end_n": float(np.linalg.norm(held.force_n)),
        "held_torque_end_nm": float(np.linalg.norm(held.torque_nm)),
        "split_moved_rad": moved,
        "pairs_reconfigured": sorted(k for k, x in moved.items() if abs(x) > RECONFIGURED_RAD),
        "planned_contacts": sorted(planned),
        "planned_contacts_unloaded": sorted(planned - held.pressing),
        "hardest_push": None if push is None else {
            "direction": hardest, "direction_palm": push.direction_palm.tolist(),
            "grip_start_n": push.grip_start_n, "grip_end_n": push.grip_end_n,
            "split_moved_rad": push.split_moved_rad},
    })


def _median(values: list[float]) -> float:
    return float(np.median(values)) if values else float("nan")


def _palm_axes(pushes: list[dict[str, Any]]) -> dict[str, int]:
    """How many pushes run mostly along each frame_palm axis (their largest component)."""
    axes = ["xyz"[int(np.argmax(np.abs(x["direction_palm"])))] for x in pushes]
    return {a: axes.count(a) for a in sorted(set(axes))}


def summarise_dgb(diagnoses: list[DgbDiagnosis]) -> dict[str, Any]:
    """Per verdict group ("failing", "passing"): medians of the drift after each closing stage
    (mm, degrees), the held imbalance (N), the reconfigured pairs and the unloaded planned
    contacts per grasp, and of the hardest push (the first failing one, else the one that
    turned the object most): the share of the grip left at its end, the largest split moved
    (degrees), and the frame_palm axes it ran along; and, over the failing grasps, the verdicts
    and failing push directions."""
    out: dict[str, Any] = {"grasps": len(diagnoses)}
    for label, group in (("failing", [g for g in diagnoses if not g.passed]),
                         ("passing", [g for g in diagnoses if g.passed])):
        f = [g.findings for g in group]
        hardest = [x["hardest_push"] for x in f if x.get("hardest_push")]
        out[label] = {
            "grasps": len(group),
            "squeeze_drift_mm_median": _median([1e3 * x["drift_after_squeeze_m_rad"][0] for x in f]),
            "squeeze_drift_deg_median": _median([float(np.degrees(x["drift_after_squeeze_m_rad"][1]))
                                                 for x in f]),
            "grasp_drift_deg_median": _median([float(np.degrees(x["drift_after_grasp_m_rad"][1]))
                                               for x in f]),
            "held_imbalance_median_n": _median([x["held_imbalance_mean_n"] for x in f]),
            "pairs_reconfigured_median": _median([len(x["pairs_reconfigured"]) for x in f]),
            "planned_unloaded_median": _median([len(x["planned_contacts_unloaded"]) for x in f]),
            "push_grip_kept_median": _median([h["grip_end_n"] / h["grip_start_n"] for h in hardest
                                              if h["grip_start_n"] > 0]),
            "push_split_moved_deg_median": _median([
                float(np.degrees(max(map(abs, h["split_moved_rad"].values()), default=0.0)))
                for h in hardest]),
            "hardest_push_palm_axis": _palm_axes(hardest),
        }
    failing = [g.findings for g in diagnoses if not g.passed]
    out["verdicts"] = {k: sum(x["verdict"] == k for x in failing)
                       for k in sorted({x["verdict"] for x in failing})}
    pushes = [x["failing_push"] or "refused before any push" for x in failing]
    out["failing_push"] = {k: pushes.count(k) for k in sorted(set(pushes))}
    return out
