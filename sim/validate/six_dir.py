"""The ``six-dir`` protocol (DESIGN §5): push the held object along ±x, ±y, ±z in turn.

After closing (gravity off), the simulation state is saved and, for each of the six world
directions, restored and a force of ``force_per_kg`` times the object's mass is applied at its
centre of mass for ``push_time_s``. The grasp passes when the object stays within the
displacement and rotation limits in the palm under every push. Units: newtons per kilogram,
seconds, metres, radians.

Early exit (``[six_dir] early_exit``): the verdict is the conjunction of the six directions' and
the failure is ``slipped`` whichever direction fails, so once one direction has failed neither
can change; the pushes after it are not simulated. Only the worst drift over all six is lost:
``displacement_m``/``rotation_rad`` are then NaN and ``stopped_early`` names the direction.
"""

from __future__ import annotations

import numpy as np

from sim.validate.config import SixDirParams
from sim.validate.program import Advance, Program, SetState, save_state
from sim.validate.result import Failure, PhaseResult, ValidationResult
from sim.validate.stepping import drift, relative_object_pose
from sim.world.scene import Scene

__all__ = ["SIX_DIRECTIONS", "six_dir"]

SIX_DIRECTIONS = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0),
                  "+z": (0, 0, 1), "-z": (0, 0, -1)}


def six_dir(scene: Scene, p: SixDirParams, result: ValidationResult) -> Program:
    """Push the closed grasp in ``scene`` six ways (a program, :mod:`sim.validate.program`);
    fills ``result`` (one phase per direction, the worst drift over all of them, the verdict)."""
    m = scene.model
    state = save_state(scene)
    ref_pos, ref_quat = relative_object_pose(scene)
    force = p.force_per_kg * scene.obj_mass_kg
    steps = max(round(p.push_time_s / m.opt.timestep), 1)
    chunk = max(steps // 20, 1)
    worst = (0.0, 0.0)
    all_ok = True
    for name, direction in SIX_DIRECTIONS.items():
        yield SetState(state)
        push = force * np.asarray(direction, float)
        ok = True
        for k in range(0, steps, chunk):
            yield Advance(min(chunk, steps - k), object_force=push if k == 0 else None)
            disp, rot = drift(scene, ref_pos, ref_quat)
            if disp > p.max_displacement_m or rot > p.max_rotation_rad:
                ok = False
                break
        result.phases[name] = PhaseResult(ok, disp, rot)
        worst = (max(worst[0], disp), max(worst[1], rot))
        all_ok &= ok
        if not ok and p.early_exit and name != list(SIX_DIRECTIONS)[-1]:
            result.stopped_early = f"after push {name}: slipped"
            worst = (float("nan"), float("nan"))
            break
    result.displacement_m, result.rotation_rad = worst
    result.passed = all_ok
    result.failure = None if all_ok else Failure.SLIPPED
