"""The ``lift-drop`` protocol (DESIGN §5): lift the closed grasp against gravity, hold it, let go.

After closing, gravity is turned on and the hand's mocap base rises ``lift_height_m`` in small
chunks; the grasp slips when the object moves or turns in the palm past the limits during the
lift or the hold that follows. A grasp that held must also release: the hand opens and the
object must move out of the palm along the palm normal, or it was held by interpenetration
(``stuck``). Units: metres,
seconds, radians.

No early exit beyond the protocol's own (issue #53, measured in ``benchmarks/bench_early_exit.py``):
the lift already stops at its first check past the limits and the release as soon as the object
has left, which is where their verdicts are decided. The hold is judged on the drift at its end
only, and a drift past the limits mid-hold can come back (a can turning in the grip), so no
earlier state fixes it; what is left (an object that has fallen clear of the hand) needs a bound
on the hand's motion to prove, and on 400 FSG grasps of 005 it is 3 grasps and < 0.2 % of the
steps, while passing grasps, which must run every phase, take 93 %.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sim.hand.model import Hand
from sim.transforms import quat_angle, rotate
from sim.validate.config import GRAVITY_MPS2, LiftDropParams
from sim.validate.program import Advance, Program
from sim.validate.result import Failure, PhaseResult, ValidationResult
from sim.validate.stepping import drift, relative_object_pose
from sim.validate.targets import GraspTargets
from sim.world.contacts import contacts_between
from sim.world.scene import Scene

__all__ = ["Observer", "lift_drop", "unit_down"]

#: called with the phase name ("lift", "hold") after every chunk of steps, for diagnosis
Observer = Callable[[str], None]


def lift_drop(scene: Scene, hand: Hand, p: LiftDropParams, targets: GraspTargets,
              result: ValidationResult, observe: Observer | None = None,
              gravity_dir: np.ndarray | None = None) -> Program:
    """Lift, hold and drop the closed grasp in ``scene`` (a program, :mod:`sim.validate.program`);
    fills ``result`` (phases ``lift``, ``hold``, ``drop``, the worst drift, the verdict).
    ``observe`` sees the scene after every lift chunk (1/50 of the lift) and every hold chunk of
    the same length; stepping in chunks changes nothing (MuJoCo steps the same either way).
    ``gravity_dir``: unit vector, world (= the object's frame: the validator places the object
    at the origin unrotated), along which gravity pulls while the hand lifts against it; None is
    −z, the object upright. A grasp meant for an object lying on its side is checked with
    that pose's "down" (:mod:`sim.world.resting`), as an arm lifting it from the table loads it."""
    m, d = scene.model, scene.data
    ref_pos, ref_quat = relative_object_pose(scene)
    start = d.mocap_pos[scene.mocap_id].copy()
    down = unit_down(gravity_dir)
    gravity = GRAVITY_MPS2 * down
    lift_steps = max(round(p.lift_time_s / m.opt.timestep), 1)
    chunk = max(lift_steps // 50, 1)
    ok = True
    for k in range(0, lift_steps, chunk):
        rise = p.lift_height_m * min(k + chunk, lift_steps) / lift_steps
        yield Advance(min(chunk, lift_steps - k), gravity=gravity if k == 0 else None,
                      mocap_pos=start - rise * down)
        if observe is not None:
            observe("lift")
        disp, rot = drift(scene, ref_pos, ref_quat)
        if disp > p.max_displacement_m or rot > p.max_rotation_rad:
            ok = False
            break
    result.phases["lift"] = PhaseResult(ok, disp, rot)
    if ok:
        hold_steps = max(round(p.hold_time_s / m.opt.timestep), 0)
        if observe is None:
            yield Advance(hold_steps)
        else:
            for k in range(0, hold_steps, chunk):
                yield Advance(min(chunk, hold_steps - k))
                observe("hold")
        disp, rot = drift(scene, ref_pos, ref_quat)
        ok = bool(disp <= p.max_displacement_m and rot <= p.max_rotation_rad)
        result.phases["hold"] = PhaseResult(ok, disp, rot)
    result.displacement_m, result.rotation_rad = disp, rot
    if not ok:
        result.failure = Failure.SLIPPED
        return
    yield from _release(scene, hand, p, targets, ref_quat, result)


def unit_down(gravity_dir: np.ndarray | None) -> np.ndarray:
    """``gravity_dir`` as a unit 3-vector (None: −z); a clear error for anything else."""
    if gravity_dir is None:
        return np.array([0.0, 0.0, -1.0])
    v = np.asarray(gravity_dir, float)
    norm = float(np.linalg.norm(v)) if v.shape == (3,) else float("nan")
    if not (np.isfinite(v).all() and norm > 1e-9):
        raise ValueError(f"gravity_dir: expected a non-zero 3-vector, got {gravity_dir!r}")
    return v / norm


#: joint speed (rad/s or m/s) below which a hand counts as done opening
_OPENING_SPEED = 0.05


def _still_opening(scene: Scene) -> bool:
    return bool(np.abs(scene.data.qvel[scene.hand_dadr]).max(initial=0.0) > _OPENING_SPEED)


def _release(scene: Scene, hand: Hand, p: LiftDropParams, targets: GraspTargets,
             ref_quat: np.ndarray, result: ValidationResult) -> Program:
    """Open the hand and pull the object out of the palm: a real grasp lets go.

    The release direction is frame_palm +y (out of the palm face, toward the pulps: DESIGN §3)
    when the release starts; gravity is turned to point along it while the fingers open to the
    pregrasp and then to the hand's open pose, so a wrap grasp or a palm-up grasp releases too.
    The release lasts ``drop_time_s`` and longer while the fingers are still moving (a gripper
    whose servo opens slowly), at most ``drop_max_time_s``, and ends as soon as the object has
    left. The grasp passes when the object has moved at least ``drop_min_fall_m`` *along* that
    direction, away from the palm, and touches the hand no more: an object that stays put is
    held by interpenetration, and one pulled into the palm (as a hand whose palm frame points
    backwards would pull it, however far it moves) has not been released either (``stuck``).
    """
    m, d = scene.model, scene.data
    _, palm_quat = scene.palm_world_pose()
    release_dir = rotate(palm_quat, np.array([0.0, 1.0, 0.0]))
    # the centre of mass, not the object frame's origin: a long object turning as it falls
    # (a screwdriver whose origin is at one end) swings its origin toward the palm
    start_com = d.xipos[scene.obj_body].copy()

    def moved_out() -> float:
        return float((d.xipos[scene.obj_body] - start_com) @ release_dir)

    def released(fall_m: float) -> bool:
        touching = contacts_between(m, d, scene.hand_geom_mask, scene.obj_geom_mask).dist <= 0.0
        return fall_m >= p.drop_min_fall_m and not touching.any()

    # the fingers first back off to the pregrasp (each contact 1 cm back along its normal: the
    # grip let go where it was made), then open to the hand's open pose; straight from the
    # squeeze to the open pose, the sweep carried some held objects into the hand (screwdrivers
    # left lying on the index and middle fingers, 4–7 cm the wrong way)
    backing = max(round(0.25 * p.drop_time_s / m.opt.timestep), 0)
    yield Advance(backing, gravity=GRAVITY_MPS2 * release_dir,
                  ctrl_from=scene.ctrl_for(targets.squeeze), ctrl_to=scene.ctrl_for(targets.pregrasp))
    yield Advance(backing, ctrl_from=scene.ctrl_for(targets.pregrasp),
                  ctrl_to=scene.ctrl_for(hand.open_pose))
    fall, elapsed_s = moved_out(), 2 * backing * m.opt.timestep
    chunk = max(round(0.05 / m.opt.timestep), 1)
    # until the object has left; past drop_time_s only while the fingers are still opening
    # (a slow gripper), at most drop_max_time_s
    while not (dropped := released(fall)) and elapsed_s < p.drop_max_time_s:
        if elapsed_s >= p.drop_time_s and not _still_opening(scene):
            break
        yield Advance(chunk)
        elapsed_s += chunk * m.opt.timestep
        fall = moved_out()
    _, rel_quat = relative_object_pose(scene)
    turn = float(quat_angle(rel_quat, ref_quat))
    result.phases["drop"] = PhaseResult(dropped, fall, turn)
    result.passed = dropped
    result.failure = None if dropped else Failure.STUCK
