"""The ``lift-drop`` protocol (DESIGN §5): lift the closed grasp against gravity, hold it, let go.

After closing, gravity is turned on and the hand's mocap base rises ``lift_height_m`` in small
chunks; the grasp slips when the object moves or turns in the palm past the limits during the
lift or the hold that follows. A grasp that held must also release: the hand opens and the
object must fall out of the palm, or it was held by interpenetration (``stuck``). Units: metres,
seconds, radians.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.hand.model import Hand
from sim.transforms import rotate
from sim.validate.config import GRAVITY_MPS2, LiftDropParams
from sim.validate.result import Failure, PhaseResult, ValidationResult
from sim.validate.stepping import drift, relative_object_pose, run_for
from sim.validate.targets import GraspTargets
from sim.world.scene import Scene

__all__ = ["run_lift_drop"]


def run_lift_drop(scene: Scene, hand: Hand, p: LiftDropParams, targets: GraspTargets,
                  result: ValidationResult) -> None:
    """Run lift, hold and drop on the closed grasp in ``scene``; fills ``result`` (phases
    ``lift``, ``hold``, ``drop``, the worst drift, the verdict)."""
    m, d = scene.model, scene.data
    ref_pos, ref_quat = relative_object_pose(scene)
    start = d.mocap_pos[scene.mocap_id].copy()
    m.opt.gravity[:] = (0.0, 0.0, -GRAVITY_MPS2)
    lift_steps = max(round(p.lift_time_s / m.opt.timestep), 1)
    chunk = max(lift_steps // 50, 1)
    ok = True
    for k in range(0, lift_steps, chunk):
        rise = p.lift_height_m * min(k + chunk, lift_steps) / lift_steps
        d.mocap_pos[scene.mocap_id] = start + np.array([0.0, 0.0, rise])
        mujoco.mj_step(m, d, nstep=min(chunk, lift_steps - k))
        disp, rot = drift(scene, ref_pos, ref_quat)
        if disp > p.max_displacement_m or rot > p.max_rotation_rad:
            ok = False
            break
    result.phases["lift"] = PhaseResult(ok, disp, rot)
    if ok:
        run_for(scene, p.hold_time_s)
        disp, rot = drift(scene, ref_pos, ref_quat)
        ok = bool(disp <= p.max_displacement_m and rot <= p.max_rotation_rad)
        result.phases["hold"] = PhaseResult(ok, disp, rot)
    result.displacement_m, result.rotation_rad = disp, rot
    if not ok:
        result.failure = Failure.SLIPPED
        return
    _release(scene, hand, p, targets, ref_pos, ref_quat, result)


def _release(scene: Scene, hand: Hand, p: LiftDropParams, targets: GraspTargets,
             ref_pos: np.ndarray, ref_quat: np.ndarray, result: ValidationResult) -> None:
    """Open the hand and pull the object out of the palm: a real grasp lets go.

    Gravity is turned to point out of the palm face (frame_palm +y) while the fingers open
    to the pregrasp and then to the hand's open pose, so a wrap grasp or a palm-up grasp
    releases too; an object that stays put is held by interpenetration (DESIGN §5 drops
    along world −z, which a palm-up grasp never passes; see the closing note).
    """
    m = scene.model
    _, palm_quat = scene.palm_world_pose()
    m.opt.gravity[:] = GRAVITY_MPS2 * rotate(palm_quat, np.array([0.0, 1.0, 0.0]))
    ctrl_sq = hand.ctrl_for(targets.squeeze)
    ctrl_open = hand.ctrl_for(hand.open_pose)
    run_for(scene, 0.5 * p.drop_time_s, ctrl_sq, ctrl_open)
    fall, turn = drift(scene, ref_pos, ref_quat)
    steps = round(0.5 * p.drop_time_s / m.opt.timestep)
    chunk = max(steps // 10, 1)
    for k in range(0, steps, chunk):  # stop as soon as the object has left
        if fall >= p.drop_min_fall_m:
            break
        mujoco.mj_step(m, scene.data, nstep=min(chunk, steps - k))
        fall, turn = drift(scene, ref_pos, ref_quat)
    dropped = bool(fall >= p.drop_min_fall_m)
    result.phases["drop"] = PhaseResult(dropped, fall, turn)
    result.passed = dropped
    result.failure = None if dropped else Failure.STUCK
