"""Closing a placed grasp onto its squeeze target, and measuring what it then touches.

The shared closing of the protocols that close before their own phases (lift-drop, six-dir;
:class:`sim.validate.protocols.base.ClosingProtocol`): from the pregrasp, at rest, the fingers
ramp to the squeeze target with gravity off, then settle (DESIGN §5). The contacts measured
after it are the result's count and grasp wrench space (object frame). Units: metres, seconds.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco

from sim.metrics.gws import gws_metrics
from sim.transforms import pose_inv, rotate
from sim.validate.program import Advance, Program, run_here
from sim.world.contacts import Contacts, contacts_between, merge_nearby

if TYPE_CHECKING:
    from sim.validate.config import CommonParams
    from sim.validate.result import ValidationResult
    from sim.validate.targets import GraspTargets
    from sim.world.objects import ObjectAsset
    from sim.world.scene import Scene

__all__ = ["close", "closing", "hand_object_contacts", "measure_contacts", "start_closing"]


def start_closing(scene: Scene, targets: GraspTargets) -> None:
    """Put the placed grasp's fingers at the pregrasp, at rest, their servos holding it."""
    scene.set_hand_joints(targets.pregrasp)
    scene.set_hand_ctrl(targets.pregrasp)
    mujoco.mj_forward(scene.model, scene.data)


def closing(scene: Scene, common: CommonParams, targets: GraspTargets) -> Program:
    """From the pregrasp, close the fingers onto the squeeze target with gravity off.

    By default the object is free while the fingers close (DESIGN §5): a grasp whose first
    finger to arrive shoves the object out of the hand fails. ``pin_while_closing`` (a named
    option; results record it) holds the object still until the settle phase instead, as a
    table or another hand would while a grasp is acquired; an unbalanced squeeze still moves
    it during the settle, before the lift measures its pose in the palm."""
    timestep = scene.model.opt.timestep
    pin = scene.object_pose() if common.pin_while_closing else None
    yield Advance(max(round(common.close_time_s / timestep), 0),
                  ctrl_from=scene.ctrl_for(targets.pregrasp),
                  ctrl_to=scene.ctrl_for(targets.squeeze), pin=pin)
    yield Advance(max(round(common.settle_time_s / timestep), 0))


def close(scene: Scene, common: CommonParams, targets: GraspTargets) -> None:
    """Close the fingers of the grasp placed in ``scene`` onto ``targets``, here."""
    start_closing(scene, targets)
    run_here(scene, closing(scene, common, targets))


def hand_object_contacts(scene: Scene, with_force: bool = False) -> Contacts:
    return contacts_between(scene.model, scene.data, scene.hand_geom_mask, scene.obj_geom_mask,
                            with_force=with_force)


def measure_contacts(scene: Scene, obj: ObjectAsset, common: CommonParams,
                     result: ValidationResult) -> None:
    """Contact count and the grasp wrench space of the simulated contacts (object frame)."""
    con = hand_object_contacts(scene)
    touching = con.dist <= 1e-4
    result.n_contacts = int(touching.sum())
    obj_pos, obj_quat = scene.object_pose()
    inv_p, inv_q = pose_inv(obj_pos, obj_quat)
    pts = inv_p + rotate(inv_q, con.pos[touching])
    nrm = rotate(inv_q, con.normal[touching])
    result.contact_pos_obj, result.contact_normal_obj = pts, nrm
    pts, nrm = merge_nearby(pts, nrm, con.body_a[touching])
    metrics = gws_metrics(pts, nrm, mu=common.gws_mu, centre=obj.com_m,
                          torque_scale_m=obj.max_radius_m)
    result.epsilon, result.volume = metrics.epsilon, metrics.volume
