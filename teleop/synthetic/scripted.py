"""Scripted demonstrations: a grasp performed in the bridge's scene and recorded like a session.

Why: the augmenter needs sessions with a real grasp in them (fingertips holding the object on
the table), with a known grasp behind it, for ``make demo``, tests and benchmarks. The
synthetic operator drives the full teleop chain, but its retargeted precision grasps do not yet
close reliably on a free object (the hand's approach knocks light objects over, and tip errors
of a few millimetres leave fingers short); a scripted demonstration is the kinesthetic
counterpart: the robot hand is driven in joint space, like an operator guiding it by hand.

The episode, in the bridge's world (table top z = 0, the object resting on it at
``object_pos_m``): the hand appears at the grasp's pregrasp (fingers backed off along the
contact normals, :meth:`sim.validate.validator.Validator.derive_targets`), closes to the squeeze target
in ``close_s`` (grasp mark at its end), holds, lifts ``lift_m`` in ``lift_s`` and holds again,
all with gravity on. Every ``record_every`` physics steps the recorder gets the bridge's
``/state`` and ``/contacts`` (:mod:`teleop.bridge.scene_contacts`), so the file reads exactly like a
bridge recording (metadata ``scripted = true``; no ``/hands``, as no operator input existed).
"""

from __future__ import annotations

import logging
from pathlib import Path

import mujoco
import numpy as np

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.transforms import pose_mul
from sim.validate.validator import Validator
from sim.world.objects import load_object
from sim.world.scene import Scene
from teleop.bridge.object_mode import table_record
from teleop.bridge.scene_contacts import contact_records, tip_finger_bodies
from teleop.record.recorder import SessionRecorder

__all__ = ["record_scripted_demo"]

log = logging.getLogger(__name__)


def record_scripted_demo(hand: Hand, object_name: str, grasp: Grasp, out: Path | str, *,
                         object_pos_m: tuple[float, float] = (0.45, 0.0), close_s: float = 0.4,
                         hold_s: float = 0.4, lift_m: float = 0.10, lift_s: float = 1.0,
                         record_every: int = 3, overwrite: bool = False) -> Path:
    """Perform ``grasp`` (frame_palm in the object frame, joints) on ``object_name`` resting on
    the table and record it to ``out`` (module docstring). Returns ``out``."""
    obj = load_object(object_name)
    scene = Scene(hand, obj, table=True)
    m, d = scene.model, scene.data
    z = -float(obj.collision_mesh().bounds[0][2]) + 1e-3
    obj_pos, obj_quat = np.array([*object_pos_m, z]), np.array([1.0, 0.0, 0.0, 0.0])
    mujoco.mj_resetData(m, d)
    scene.set_object_pose(obj_pos, obj_quat)
    palm_pos, palm_quat = pose_mul(obj_pos, obj_quat, grasp.palm_pos, grasp.palm_quat_wxyz)
    base = hand.base_pose_for_palm(palm_pos, palm_quat, grasp.joints)
    scene.set_hand_pose(*base)
    scene.set_hand_joints(grasp.joints)
    mujoco.mj_forward(m, d)
    targets = Validator(hand, obj).derive_targets(scene, grasp.joints)
    scene.set_hand_joints(targets.pregrasp)
    scene.set_hand_ctrl(targets.pregrasp)
    mujoco.mj_forward(m, d)
    tips = tip_finger_bodies(scene)
    meta = {"hand": hand.name, "object": object_name, "joint_names": list(hand.joint_names),
            "fingers": list(hand.finger_names), "scripted": True,
            "object_pos_m": obj_pos.tolist(), "rig": "scripted",
            "object_mode": "free", "table": table_record(scene)}
    dt = m.opt.timestep
    stepped = 0
    with SessionRecorder(out, metadata=meta, overwrite=overwrite, start_time_ns=0) as rec:
        def run(seconds: float, q_from: np.ndarray | None = None,
                q_to: np.ndarray | None = None, rise_m: float = 0.0) -> None:
            nonlocal stepped
            steps = max(round(seconds / dt), 1)
            start = d.mocap_pos[scene.mocap_id].copy()
            for k in range(steps):
                a = (k + 1) / steps
                if q_from is not None and q_to is not None:
                    scene.set_hand_ctrl((1 - a) * q_from + a * q_to)
                d.mocap_pos[scene.mocap_id] = start + np.array([0.0, 0.0, rise_m * a])
                mujoco.mj_step(m, d)
                stepped += 1
                if stepped % record_every == 0:
                    t_ns = round(d.time * 1e9)
                    pp, pq = scene.palm_world_pose()
                    op, oq = scene.object_pose()
                    rec.write_state(d.qpos[scene.hand_qadr], pp, pq, op, oq, t_s=d.time,
                                    object_name=object_name, log_time_ns=t_ns)
                    rec.write_contacts(contact_records(scene, tips), t_s=d.time,
                                       object_name=object_name, log_time_ns=t_ns)

        run(close_s, targets.pregrasp, targets.squeeze)
        rec.write_event("grasp_mark", {"source": "scripted"}, t_s=d.time,
                        log_time_ns=round(d.time * 1e9))
        run(hold_s)
        run(lift_s, rise_m=lift_m)
        run(hold_s)
    log.info("scripted demo of %s recorded to %s (%.2f s)", object_name, out, d.time)
    return Path(out)
