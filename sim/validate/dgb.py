"""The ``dgb`` protocol: DexGraspBench's "fc" evaluation of a floating hand, as its code runs it.

Parameter by parameter as ``../shared/reference/dexgraspbench/README.md`` lists them (the scene's
contacts, servos, mass and solver come from ``[dgb]`` through :class:`sim.world.scene.Scene`):

1. the hand is placed at the **pregrasp**; hand–object or hand–hand penetration deeper than
   ``max_penetration_m`` fails the grasp before any simulation;
2. the object's initial world pose is the reference of every measurement;
3. per world direction −x, +x, −y, +y, −z, +z: reset to the pregrasp (object free, at rest, no
   force), close pregrasp → grasp and then grasp → squeeze, each in ``stage_increments`` control
   steps of ``steps_per_increment`` simulation steps (stage-wise linear: merging the two stages
   changes the verdicts); push with ``force_per_kg``·m newtons at the centre of mass for
   ``push_time_s``, checking every ``check_every_steps`` steps; the first failing check ends the
   direction and the first failing direction ends the test;
4. pass when the object stays within ``max_displacement_m`` and ``max_rotation_rad`` of its
   initial world pose (strictly below, as the benchmark compares) in all six.

The rotation is the benchmark's: 2·arccos(w) of q_now ⊗ q_initial⁻¹ (w clipped at 1, not
folded to the shorter arc). Gravity is off throughout. Units: metres, seconds, newtons, radians.

Step 3 closes the same stages from the same reset six times, and MuJoCo is deterministic: the
closing is simulated once and its end state copied back for the other directions
(:func:`closed`), which gives the same bits as closing again (tests/test_dgb_closing.py).
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from collections.abc import Callable

import mujoco
import numpy as np

from sim.transforms import quat_conj, quat_mul
from sim.validate.config import DgbParams
from sim.validate.result import Failure, PhaseResult, ValidationResult
from sim.validate.stages import GraspStages
from sim.world.contacts import contacts_between
from sim.world.scene import Scene

__all__ = ["DGB_DIRECTIONS", "close", "closed", "closing_drift", "dgb_drift", "dgb_penetration_m", "push",
           "run_dgb"]

DGB_DIRECTIONS = {"-x": (-1, 0, 0), "+x": (1, 0, 0), "-y": (0, -1, 0), "+y": (0, 1, 0),
                  "-z": (0, 0, -1), "+z": (0, 0, 1)}


def dgb_drift(pos0: np.ndarray, quat0: np.ndarray, pos: np.ndarray,
              quat: np.ndarray) -> tuple[float, float]:
    """(metres, radians) from pose 0 to a pose, both in the world, as the benchmark measures."""
    rel = quat_mul(quat, quat_conj(quat0))
    w = float(rel[0]) if abs(rel[0]) <= 1.0 else 1.0
    return float(np.linalg.norm(pos - pos0)), 2.0 * float(np.arccos(w))


def dgb_penetration_m(scene: Scene) -> tuple[float, float]:
    """(hand–object, hand–hand) penetration depth (metres, ≥ 0) of the current state."""
    m, d = scene.model, scene.data
    ho = contacts_between(m, d, scene.hand_geom_mask, scene.obj_geom_mask).max_penetration_m
    hh = contacts_between(m, d, scene.hand_geom_mask, scene.hand_geom_mask).max_penetration_m
    return ho, hh


def _stage(scene: Scene, p: DgbParams, q_from: np.ndarray, q_to: np.ndarray) -> None:
    """One closing stage: the controls from ``q_from``'s to ``q_to``'s in ``stage_increments``
    equal steps, each held for ``steps_per_increment`` simulation steps. No ``mj_forward``
    between a control change and its steps: the first step computes the same forward dynamics
    from the same state, so one there only repeated it (bit-identical results without it)."""
    m, d = scene.model, scene.data
    c_from, c_to = scene.ctrl_for(q_from), scene.ctrl_for(q_to)
    for k in range(1, p.stage_increments + 1):
        alpha = k / p.stage_increments
        d.ctrl[scene.hand_act] = (1.0 - alpha) * c_from + alpha * c_to
        mujoco.mj_step(m, d, nstep=p.steps_per_increment)


def close(scene: Scene, p: DgbParams, stages: GraspStages) -> None:
    """The benchmark's closing from the current state: pregrasp → grasp, then grasp → squeeze."""
    _stage(scene, p, stages.pregrasp, stages.grasp)
    _stage(scene, p, stages.grasp, stages.squeeze)


#: how many closed states each scene keeps: the rehearsal closes up to six candidates before the
#: benchmark runs the one it kept (sim.validate.rehearsal)
CLOSINGS_KEPT = 8
_Kept = weakref.WeakKeyDictionary[Scene, OrderedDict[bytes, mujoco.MjData]]
_closings: _Kept = weakref.WeakKeyDictionary()
#: the states after the pregrasp → grasp stage alone (``[dgb] early_exit``): the rehearsal's
#: fallback squeezes and drift corrections keep the pregrasp and grasp and change the squeeze
_grasp_stages: _Kept = weakref.WeakKeyDictionary()


def _closing_key(p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray], stages: GraspStages,
                 *, first_stage_only: bool = False) -> bytes:
    arrays = (*palm_world, stages.pregrasp, stages.grasp,
              *(() if first_stage_only else (stages.squeeze,)))
    return b"|".join(np.asarray(a, np.float64).tobytes() for a in arrays) + \
        f"|{p.stage_increments}|{p.steps_per_increment}|{first_stage_only}".encode()


def _restore_or_keep(kept_by_scene: _Kept, scene: Scene, key: bytes,
                     simulate: Callable[[], None]) -> None:
    """Copy the ``MjData`` kept under ``key`` into ``scene``, or ``simulate()`` from the state it
    is in and keep the result (the last :data:`CLOSINGS_KEPT` per scene). Only for a simulation
    that ``key`` determines from a reset: MuJoCo is deterministic and the whole ``MjData`` is
    kept (state, contacts, solver warm start), so the copy is what simulating again gives."""
    m, d = scene.model, scene.data
    kept = kept_by_scene.setdefault(scene, OrderedDict())
    if key in kept:
        kept.move_to_end(key)
        mujoco.mj_copyData(d, m, kept[key])
        return
    simulate()
    store = kept.popitem(last=False)[1] if len(kept) >= CLOSINGS_KEPT else mujoco.MjData(m)
    mujoco.mj_copyData(store, m, d)
    kept[key] = store


def closed(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
           stages: GraspStages) -> None:
    """Put ``scene`` where the benchmark's closing of ``stages`` leaves it: reset to the
    pregrasp with frame_palm at ``palm_world``, then :func:`close`. The first time for these
    stages on this scene it is simulated and the whole ``MjData`` kept (the last
    :data:`CLOSINGS_KEPT`); after that the kept data is copied back, state, contacts and solver
    warm start alike, which is what simulating it again gives (deterministic; the scene's model
    is never changed after it is built). With ``p.early_exit`` the state after the first stage
    (pregrasp → grasp) is kept the same way, so stages that differ only in their squeeze
    simulate only the second."""
    scene.reset_with_grasp(*palm_world, stages.pregrasp)

    def simulate() -> None:
        if not p.early_exit:
            close(scene, p, stages)
            return
        _restore_or_keep(_grasp_stages, scene, _closing_key(p, palm_world, stages, first_stage_only=True),
                         lambda: _stage(scene, p, stages.pregrasp, stages.grasp))
        _stage(scene, p, stages.grasp, stages.squeeze)

    _restore_or_keep(_closings, scene, _closing_key(p, palm_world, stages), simulate)


def closing_drift(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
                  stages: GraspStages, idle_s: float = 0.5) -> dict[str, tuple[float, float]]:
    """Where a grasp's drift comes from before any push: (metres, radians) from the object's
    pose at the pregrasp, as the benchmark measures it, after the pregrasp → grasp stage
    ("grasp"), after the grasp → squeeze stage ("squeeze") and after ``idle_s`` more seconds
    with the servos at the squeeze and no force ("idle"). Penetration is not checked."""
    m, d = scene.model, scene.data
    scene.reset_with_grasp(*palm_world, stages.pregrasp)
    pos0, quat0 = scene.object_pose()
    out = {}
    _stage(scene, p, stages.pregrasp, stages.grasp)
    out["grasp"] = dgb_drift(pos0, quat0, *scene.object_pose())
    _stage(scene, p, stages.grasp, stages.squeeze)
    out["squeeze"] = dgb_drift(pos0, quat0, *scene.object_pose())
    mujoco.mj_step(m, d, nstep=max(round(idle_s / m.opt.timestep), 0))
    out["idle"] = dgb_drift(pos0, quat0, *scene.object_pose())
    return out


def push(scene: Scene, p: DgbParams, pose0: tuple[np.ndarray, np.ndarray], direction: str,
         after_check: Callable[[], None] | None = None) -> tuple[bool, float, float]:
    """The benchmark's push ``direction`` (a key of :data:`DGB_DIRECTIONS`) from the current
    state: ``force_per_kg``·m newtons at the centre of mass for ``push_time_s``, the drift from
    ``pose0`` (the object's world position and wxyz at the pregrasp) checked every
    ``check_every_steps`` steps. Returns (inside the limits, metres, radians) at the first
    failing check or the last one; ``after_check`` is called after every check still inside the
    limits (a diagnosis reads the state there). The force stays applied."""
    m, d = scene.model, scene.data
    force = p.force_per_kg * scene.obj_mass_kg
    d.xfrc_applied[scene.obj_body, :3] = force * np.asarray(DGB_DIRECTIONS[direction], float)
    checks = max(round(p.push_time_s / m.opt.timestep) // p.check_every_steps, 1)
    ok, disp, rot = True, 0.0, 0.0
    for _ in range(checks):
        mujoco.mj_step(m, d, nstep=p.check_every_steps)
        disp, rot = dgb_drift(*pose0, *scene.object_pose())
        ok = disp < p.max_displacement_m and rot < p.max_rotation_rad
        if not ok:
            break
        if after_check is not None:
            after_check()
    return ok, disp, rot


def run_dgb(scene: Scene, p: DgbParams, palm_world: tuple[np.ndarray, np.ndarray],
            stages: GraspStages, result: ValidationResult,
            after_first_close: Callable[[], None] | None = None) -> None:
    """Run the benchmark on the grasp whose frame_palm sits at ``palm_world`` (world position,
    wxyz) with ``stages``; fills ``result`` (penetration, one phase per tested direction, the
    last measured drift, the verdict). ``after_first_close`` is called once, closed, before the
    first push (to measure contacts)."""
    scene.reset_with_grasp(*palm_world, stages.pregrasp)
    ho, hh = dgb_penetration_m(scene)
    result.penetration_m = max(ho, hh)   # as every protocol reports it: into the object or itself
    if ho > p.max_penetration_m or hh > p.max_penetration_m:
        result.failure = Failure.PENETRATION
        return
    pose0 = scene.object_pose()
    ok, disp, rot = True, 0.0, 0.0
    for i, name in enumerate(DGB_DIRECTIONS):
        closed(scene, p, palm_world, stages)
        if i == 0 and after_first_close is not None:
            after_first_close()
        ok, disp, rot = push(scene, p, pose0, name)
        result.phases[name] = PhaseResult(ok, disp, rot)
        if not ok:
            break
    scene.data.xfrc_applied[scene.obj_body] = 0.0
    result.displacement_m, result.rotation_rad = disp, rot
    result.passed = ok
    result.failure = None if ok else Failure.SLIPPED
