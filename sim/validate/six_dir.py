"""The ``six-dir`` protocol (DESIGN §5): push the held object along ±x, ±y, ±z in turn.

After closing (gravity off), the simulation state is saved and, for each of the six world
directions, restored and a force of ``force_per_kg`` times the object's mass is applied at its
centre of mass for ``push_time_s``. The grasp passes when the object stays within the
displacement and rotation limits in the palm under every push. Units: newtons per kilogram,
seconds, metres, radians.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.validate.config import SixDirParams
from sim.validate.result import Failure, PhaseResult, ValidationResult
from sim.validate.stepping import drift, relative_object_pose
from sim.world.scene import Scene

__all__ = ["SIX_DIRECTIONS", "run_six_dir"]

SIX_DIRECTIONS = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0),
                  "+z": (0, 0, 1), "-z": (0, 0, -1)}


def run_six_dir(scene: Scene, p: SixDirParams, result: ValidationResult) -> None:
    """Push the closed grasp in ``scene`` six ways; fills ``result`` (one phase per direction,
    the worst drift over all of them, the verdict)."""
    m, d = scene.model, scene.data
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, state, spec)
    ref_pos, ref_quat = relative_object_pose(scene)
    force = p.force_per_kg * scene.obj_mass_kg
    steps = max(round(p.push_time_s / m.opt.timestep), 1)
    chunk = max(steps // 20, 1)
    worst = (0.0, 0.0)
    all_ok = True
    for name, direction in SIX_DIRECTIONS.items():
        mujoco.mj_setState(m, d, state, spec)
        d.xfrc_applied[scene.obj_body, :3] = force * np.asarray(direction, float)
        ok = True
        for k in range(0, steps, chunk):
            mujoco.mj_step(m, d, nstep=min(chunk, steps - k))
            disp, rot = drift(scene, ref_pos, ref_quat)
            if disp > p.max_displacement_m or rot > p.max_rotation_rad:
                ok = False
                break
        d.xfrc_applied[scene.obj_body] = 0.0
        result.phases[name] = PhaseResult(ok, disp, rot)
        worst = (max(worst[0], disp), max(worst[1], rot))
        all_ok &= ok
    result.displacement_m, result.rotation_rad = worst
    result.passed = all_ok
    result.failure = None if all_ok else Failure.SLIPPED
