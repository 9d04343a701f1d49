"""The operator's hand at the grasp moment (:func:`grasp_target`): wrist pose and joint angles
such that the *retargeted* robot hand reproduces a grasp of the object.

With a reference grasp (``configs/hands/<hand>/grasps.toml``) for the object, the wrist pose is
the inverse of the retargeter's wrist correspondence (operator wrist = robot palm pose ∘
(palm ← wrist), :class:`teleop.synthetic.correspondence.Correspondence`), and each operator
fingertip is placed where the retargeter's scaling maps it onto the reference grasp's robot
pulp site, by a small bounded least-squares fit of that finger's human joint angles
(:meth:`HumanHand.fit_finger`, with a weak prior toward natural DIP ≈ 0.7·PIP coupling). The
robot pulp sites of a reference grasp lie on the object surface (within
``tip_surface_snap_m`` they are snapped onto it first), so retargeting puts the robot
fingertips on it up to the human hand's reach residual and the IK error. Without a reference
grasp, the generic grasp is searched (:mod:`teleop.synthetic.grasp_search`): wrist placements
from the operator's side and from above × per-finger closure levels, scored on where the
robot fingertips would land.

World frame, metres; rotations as 3×3 matrices.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from sim.errors import ConfigError
from sim.hand.model import Hand
from sim.transforms import quat_to_mat
from teleop.messages import JOINT_INDEX
from teleop.synthetic.config import SynthConfig
from teleop.synthetic.correspondence import Correspondence
from teleop.synthetic.grasp_search import search_grasp
from teleop.synthetic.human_hand import FINGERS, LONG_FINGERS, HandPose, HumanHand, finger_of
from teleop.synthetic.surface import closest_surface_frames, closest_surface_points

__all__ = ["GraspTarget", "grasp_target"]

logger = logging.getLogger(__name__)

Array = np.ndarray


@dataclass(frozen=True)
class GraspTarget:
    """The operator at the grasp (noise-free). wrist_pos_m / wrist_rot: operator wrist
    (tracking space, metres; axes). pose: the hand's joint angles. palm_pos_m / palm_rot: where
    the retargeted robot frame_palm should be (world). residual_m: per human finger, how far
    its tip stays from where it maps onto the wanted robot fingertip (metres, operator scale);
    for a generic grasp instead ``mean_surface_m``. reference: the reference grasp imitated
    (None: generic side grasp)."""

    wrist_pos_m: Array
    wrist_rot: Array
    pose: HandPose
    palm_pos_m: Array
    palm_rot: Array
    residual_m: dict[str, float]
    reference: str | None


def grasp_target(robot: Hand, human: HumanHand, corr: Correspondence, scale: float,
                 object_name: str, obj_pos: Array, obj_rot: Array, *, grasp_name: str | None,
                 snap_m: float, press_m: float = 0.0, standoff_m: Array | None = None,
                 grip_friction: float = SynthConfig.grip_friction) -> GraspTarget:
    """The operator's grasp of ``object_name`` (world pose ``obj_pos``, ``obj_rot``) for robot
    hand ``robot``: imitating its reference grasp for the object (or ``grasp_name``), else a
    generic side grasp (module docstring). ``scale``: the retargeter's fingertip scale for this
    operator; ``snap_m``: reference pulp sites this close to the surface go onto it;
    ``press_m``: the operator closes the fingertips this far past the surface (metres; a
    generic grasp only); ``standoff_m`` (per finger, :data:`FINGERS` order, thumb first,
    metres): instead, the operator's *own* pads (tip joint less its radius) stop this far short
    of the surface — a person's standoff on a virtual object, for the touching fingers of a
    reference grasp as well; ``grip_friction``: the friction the operator counts on to hold
    it up."""
    ref = _reference_for(robot, object_name, grasp_name)
    residual: dict[str, float] = {}
    if ref is not None:
        palm_rot = obj_rot @ quat_to_mat(ref.grasp.palm_quat_wxyz)
        palm_pos = obj_pos + obj_rot @ ref.grasp.palm_pos
        wrist_pos, wrist_rot = corr.wrist_for_palm(palm_pos, palm_rot)
        tips_palm = robot.fingertip_sites(ref.grasp.joints, frame="palm")[0]
        from sim.world.objects import load_object

        mesh = load_object(object_name).surface_mesh()
        snapped = np.zeros(len(tips_palm), bool)
        if snap_m > 0.0:
            tips_palm, snapped = _snap_tips(tips_palm, mesh, ref.grasp.palm_pos,
                                            quat_to_mat(ref.grasp.palm_quat_wxyz), snap_m)
        grasp_pose = HandPose.relaxed()
        for k, robot_finger in enumerate(robot.finger_names):
            joint = corr.mapping.fingers.get(robot_finger)
            if joint is None:
                continue
            finger = finger_of(joint)
            target = corr.operator_tip_for(tips_palm[k], scale)
            if standoff_m is not None and snapped[k]:
                target = _pad_short_of_surface(
                    target, corr, wrist_pos, wrist_rot, mesh, obj_pos, obj_rot,
                    float(standoff_m[FINGERS.index(finger)]
                          + human.radii[JOINT_INDEX[f"{finger}_tip"]]))
            x, res = human.fit_finger(finger, target, grasp_pose)
            grasp_pose = (replace(grasp_pose, thumb=x) if finger == "thumb" else
                          replace(grasp_pose, fingers={**grasp_pose.fingers, finger: x}))
            residual[finger] = res
        _fill_unmapped(grasp_pose, corr.mapping.fingers.values())
        logger.info("reference grasp %s: human fingertip fit residuals (m) %s", ref.name,
                    {k: round(v, 4) for k, v in residual.items()})
    else:
        wrist_pos, wrist_rot, grasp_pose, residual = _generic_grasp(
            robot, human, corr, scale, object_name, obj_pos, obj_rot, press_m, standoff_m,
            grip_friction)
        palm_pos, palm_rot = corr.palm_for_wrist(wrist_pos, wrist_rot)
    return GraspTarget(wrist_pos_m=wrist_pos, wrist_rot=wrist_rot, pose=grasp_pose,
                       palm_pos_m=palm_pos, palm_rot=palm_rot, residual_m=residual,
                       reference=None if ref is None else ref.name)


def _reference_for(hand: Hand, object_name: str, grasp_name: str | None) -> Any:
    from sim.hand.reference_grasps import load_reference_grasps

    try:
        refs = load_reference_grasps(hand)
    except ConfigError as exc:
        logger.info("no reference grasps for %s (%s): generic grasp", hand.name, exc)
        return None
    for ref in refs:
        if (grasp_name is None and ref.object == object_name) or ref.name == grasp_name:
            return ref
    if grasp_name is not None:
        raise ConfigError(f"no reference grasp {grasp_name!r} for hand {hand.name!r} "
                          f"(have {[r.name for r in refs]})")
    return None


def _snap_tips(tips_palm: Array, mesh: Any, palm_pos_obj: Array, palm_rot_obj: Array,
               max_gap_m: float) -> tuple[Array, Array]:
    """Reference pulp sites (frame_palm) within ``max_gap_m`` of the object's surface ``mesh``
    (object frame) moved
    onto it (closest point), and which were. Why: hand-built reference grasps touch the object
    with whatever part of the finger met it first, so their pulp sites sit up to ~1.5 cm off
    the surface; an operator grasping the object puts the finger *pads* on it. Fingers
    farther away (the reference's unused fingers) keep their place. (No press past the
    surface here: a reference grasp's pads on a thin wall, a bowl's rim, would aim through
    it.)"""
    tips_obj = palm_pos_obj + tips_palm @ palm_rot_obj.T
    closest, signed = closest_surface_points(mesh, tips_obj)
    snap = np.abs(signed) <= max_gap_m
    tips_obj = np.where(snap[:, None], closest, tips_obj)
    logger.info("reference pulp sites off the surface (m): %s; snapped: %s",
                np.round(signed, 4).tolist(), snap.tolist())
    return (tips_obj - palm_pos_obj) @ palm_rot_obj, snap


def _pad_short_of_surface(tip_wrist: Array, corr: Correspondence, wrist_pos: Array,
                          wrist_rot: Array, mesh: Any, obj_pos: Array, obj_rot: Array,
                          out_m: float) -> Array:
    """An operator fingertip target (wrist frame) moved to ``out_m`` (metres: standoff plus the
    tip's radius) outside the object's surface ``mesh`` (object frame) along the normal at the
    surface point nearest to it. Why: the retargeter's fingertip scale maps a robot pad on the
    surface back to an operator tip millimetres *inside* the object (a human hand is larger
    than the robot's); a person's tracked pads stop short of a virtual object instead."""
    world = corr.world_of_tracking(wrist_pos + wrist_rot @ tip_wrist)
    closest, _, normal = closest_surface_frames(mesh, ((world - obj_pos) @ obj_rot)[None])
    out = obj_pos + obj_rot @ (closest[0] + out_m * normal[0])
    return wrist_rot.T @ (corr.tracking_of_world(out) - wrist_pos)


def _fill_unmapped(pose: HandPose, mapped_joints: Iterable[str]) -> None:
    """Long fingers no robot finger follows curl like the mean of the mapped ones."""
    mapped = {finger_of(j) for j in mapped_joints}
    used = [pose.fingers[f] for f in LONG_FINGERS if f in mapped]
    if not used:
        return
    mean = np.mean(used, axis=0)
    for f in LONG_FINGERS:
        if f not in mapped:
            pose.fingers[f] = mean.copy()


def _generic_grasp(robot: Hand, human: HumanHand, corr: Correspondence, scale: float,
                   object_name: str, obj_pos: Array, obj_rot: Array,
                   press_m: float, standoff_m: Array | None, grip_friction: float
                   ) -> tuple[Array, Array, HandPose, dict[str, float]]:
    """The searched generic grasp (:func:`teleop.synthetic.grasp_search.search_grasp`) as an
    operator wrist pose and hand pose; residuals: the mapped tips' signed surface distances
    per finger and their mean absolute value ``mean_surface_m``."""
    from sim.world.objects import load_object

    asset = load_object(object_name)
    mesh = asset.surface_mesh()
    found = search_grasp(robot, human, corr, scale, mesh, obj_pos, obj_rot, press_m,
                         com_m=obj_pos + obj_rot @ asset.com_m, friction=grip_friction,
                         standoff_m=standoff_m)
    wrist_pos, wrist_rot = corr.wrist_for_palm(found.palm_pos_m, found.palm_rot)
    pose = found.pose
    _fill_unmapped(pose, corr.mapping.fingers.values())
    residual = {**found.surface_m,
                "mean_surface_m": float(np.mean(np.abs(list(found.surface_m.values()))))}
    logger.info("generic grasp on %s: fingertips touching %s (cost %.4f)", object_name,
                found.touching, found.cost)
    return wrist_pos, wrist_rot, pose, residual
