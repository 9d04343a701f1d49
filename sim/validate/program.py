"""A validation protocol written once, as a program of simulation requests, and run here.

Why: the same protocol runs on one scene (this process, stepped by MuJoCo from Python) and on
many grasps at once in C threads (:mod:`sim.validate.batched`). Written as plain code against
one scene, the two would drift apart; written as a generator that *yields* what it needs the
simulation to do — :class:`Advance` (step, optionally ramping the hand's controls, pinning the
object, setting gravity, the hand's mocap target or a force on the object) or
:class:`SetState` (restore a saved state) — and *reads* the scene between requests, the protocol
has one definition and each executor only has to carry the requests out exactly. :func:`run_here`
is the executor for one scene; the batched one matches it bit for bit (a test checks).

A program never writes the simulation itself; it reads the scene it was given (state and
derived fields, contacts) as they stand after the last request.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass

import mujoco
import numpy as np

from sim.world.scene import Scene

__all__ = ["Advance", "Program", "Request", "SetState", "run_here", "save_state"]

#: the state a program saves and restores (everything an mj_step continues from)
STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass(frozen=True)
class Advance:
    """Step ``nstep`` times. Before the first step: set ``gravity`` (m/s², the model's
    ``opt.gravity``), the hand's mocap target position ``mocap_pos`` (metres, world) and the force
    on the object's centre of mass ``object_force`` (newtons, world; ``xfrc_applied``), each when
    given. With ``ctrl_from``/``ctrl_to`` (the scene's hand controls, over ``hand_act``) step k of
    n sets them to the linear blend at (k + 1)/n first; with ``pin`` (position metres, wxyz) the
    object is put back at that pose, at rest, after every step."""

    nstep: int
    gravity: np.ndarray | None = None
    mocap_pos: np.ndarray | None = None
    object_force: np.ndarray | None = None
    ctrl_from: np.ndarray | None = None
    ctrl_to: np.ndarray | None = None
    pin: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def per_step(self) -> bool:
        """Whether Python has work between steps (a ramp or a pin)."""
        return self.ctrl_from is not None or self.pin is not None

    def ctrl_at(self, k: int) -> np.ndarray:
        """The hand controls of step k (0-based) of the ramp."""
        assert self.ctrl_from is not None and self.ctrl_to is not None, "not a ramp"
        alpha = (k + 1) / self.nstep
        return (1 - alpha) * self.ctrl_from + alpha * self.ctrl_to


@dataclass(frozen=True)
class SetState:
    """Restore a state saved with :func:`save_state` (mjSTATE_INTEGRATION)."""

    state: np.ndarray


Request = Advance | SetState
#: a protocol: yields requests, reads its scene between them, returns nothing (fills a result)
Program = Generator[Request, None, None]


def save_state(scene: Scene) -> np.ndarray:
    """The scene's current state (mjSTATE_INTEGRATION), for a later :class:`SetState`."""
    m, d = scene.model, scene.data
    state = np.empty(mujoco.mj_stateSize(m, STATE_SPEC))
    mujoco.mj_getState(m, d, state, STATE_SPEC)
    return state


def _advance_here(scene: Scene, req: Advance) -> None:
    m, d = scene.model, scene.data
    if req.gravity is not None:
        m.opt.gravity[:] = req.gravity
    if req.mocap_pos is not None:
        d.mocap_pos[scene.mocap_id] = req.mocap_pos
    if req.object_force is not None:
        d.xfrc_applied[scene.obj_body, :3] = req.object_force
        d.xfrc_applied[scene.obj_body, 3:] = 0.0
    if req.nstep <= 0:
        return
    if not req.per_step:
        mujoco.mj_step(m, d, nstep=req.nstep)
        return
    for k in range(req.nstep):
        if req.ctrl_from is not None:
            d.ctrl[scene.hand_act] = req.ctrl_at(k)
        mujoco.mj_step(m, d)
        if req.pin is not None:
            scene.set_object_pose(*req.pin)


def run_here(scene: Scene, program: Program) -> None:
    """Run ``program`` on ``scene`` in this thread, each request as it comes."""
    for req in program:
        if isinstance(req, SetState):
            mujoco.mj_setState(scene.model, scene.data, req.state, STATE_SPEC)
        else:
            _advance_here(scene, req)
