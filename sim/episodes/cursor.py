"""A validation program carried out one physics step at a time.

Why: :func:`sim.validate.program.run_here` steps each request as one ``mj_step(nstep=N)``, and
a trajectory needs every step's state, or another controller's actions in between (the
environment of :mod:`sim.envs`). :class:`ProgramCursor` carries out the same requests
exactly as ``run_here`` does — ``mj_step`` N times is ``mj_step(nstep=N)`` bit for bit — but
leaves the stepping to its caller: :meth:`ProgramCursor.before_step`, one ``mj_step``,
:meth:`ProgramCursor.after_step`. The program reads its scene between requests as it always
does, so the protocol is the validator's, not a copy of it.

With ``drive=False`` the cursor carries out only the protocol's *conditions* (gravity, the
force on the object, the object pinned while closing) and leaves the hand's controls and
mocap target to the caller: the protocol then judges someone else's actions.
"""

from __future__ import annotations

import mujoco

from sim.validate.program import STATE_SPEC, Advance, Program, SetState
from sim.world.scene import Scene

__all__ = ["ProgramCursor"]


class ProgramCursor:
    """The request of ``program`` that the next physics step belongs to, and its step index.

    ``program`` None (a grasp decided without simulating) is done at once."""

    def __init__(self, scene: Scene, program: Program | None, *, drive: bool = True) -> None:
        self.scene = scene
        self.drive = drive
        self._program = program
        self.request: Advance | None = None
        #: index of the coming step within :attr:`request`
        self.k = 0
        #: how many requests have been started (a new one starts a new stretch)
        self.n_requests = 0
        self._pull()

    @property
    def done(self) -> bool:
        """Whether the program has ended (its result holds the verdict)."""
        return self.request is None

    def before_step(self) -> None:
        """Set what the program asks of the coming step: the ramped hand controls (driving)."""
        req = self.request
        if req is not None and self.drive and req.ctrl_from is not None:
            self.scene.data.ctrl[self.scene.hand_act] = req.ctrl_at(self.k)

    def after_step(self) -> None:
        """After one ``mj_step``: pin the object where asked, then go on to the next step,
        running the program to its next request when this one is through."""
        req = self.request
        if req is None:
            return
        if req.pin is not None:
            self.scene.set_object_pose(*req.pin)
        self.k += 1
        if self.k >= req.nstep:
            self._pull()

    def _pull(self) -> None:
        """Run the program to its next request that steps, carrying out on the way what needs
        no stepping (a restored state, the conditions of a zero-step request)."""
        self.request, self.k = None, 0
        if self._program is None:
            return
        scene = self.scene
        for req in self._program:
            if isinstance(req, SetState):
                mujoco.mj_setState(scene.model, scene.data, req.state, STATE_SPEC)
                continue
            self._conditions(req)
            if req.nstep > 0:
                self.request = req
                self.n_requests += 1
                return
        self._program = None

    def _conditions(self, req: Advance) -> None:
        """What :func:`sim.validate.program.run_here` sets before a request's first step."""
        m, d, scene = self.scene.model, self.scene.data, self.scene
        if req.gravity is not None:
            m.opt.gravity[:] = req.gravity
        if self.drive and req.mocap_pos is not None:
            d.mocap_pos[scene.mocap_id] = req.mocap_pos
        if req.object_force is not None:
            d.xfrc_applied[scene.obj_body, :3] = req.object_force
            d.xfrc_applied[scene.obj_body, 3:] = 0.0
