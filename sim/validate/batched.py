"""Validation programs of many grasps stepped together in C threads (``mujoco.batch``).

Why: a protocol stepped from Python pays the interpreter between steps (a control ramp sets the
controls before every step, the lift checks the object every few steps) and spreads over cores
only as whole processes. :class:`BatchRunner` keeps up to ``nsim`` grasps in flight on one
``mujoco.batch.Batch`` (one MjData per simulation, mjSTATE_INTEGRATION rows): every request of
the programs (:mod:`sim.validate.program`) that asks for the same stretch of stepping is run in
one call over all of them on the batch's threads, and Python only runs between those stretches.

Bit for bit what :func:`sim.validate.program.run_here` gives: MuJoCo's batch steps each
simulation exactly as ``mj_step`` on its own MjData does, every model setting a program changes
(gravity) is per simulation, and after each call a program reads a full copy of its
simulation's MjData (derived fields one step behind the state, as after ``mj_step``) through
:meth:`sim.world.scene.Scene.over`. A test compares every field of the results on a fixed set.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import batch as mjbatch

from sim.grasp import Grasp
from sim.validate.program import STATE_SPEC, Advance, Program, Request, SetState
from sim.validate.result import ValidationResult
from sim.world.scene import Scene

__all__ = ["BatchRunner", "ProgramRunner", "validate_batched"]


@dataclass
class _Slot:
    """One simulation of the batch and what runs on it."""

    view: Scene
    program: Program | None = None
    request: Request | None = None
    index: int = -1          # the caller's index of the grasp running here


class ProgramRunner:
    """Up to ``nsim`` programs of ``scene``'s model in flight, stepped together by a backend
    (a subclass: :class:`BatchRunner`, :class:`sim.validate.warp_runner.WarpRunner`).

    Each simulation has a view (``slots[i].view``, :meth:`Scene.over` of its own MjData) that
    its program reads; a backend keeps what it steps in step with the views."""

    def __init__(self, scene: Scene, nsim: int) -> None:
        self.scene = scene
        self.slots = [_Slot(scene.over(mujoco.MjData(scene.model))) for _ in range(nsim)]

    def free(self) -> list[int]:
        return [i for i, s in enumerate(self.slots) if s.program is None]

    @property
    def busy(self) -> bool:
        return any(s.program is not None for s in self.slots)

    def load(self, sim: int, program: Program, index: int) -> None:
        """Start ``program`` on simulation ``sim`` from the state (and gravity) of
        ``self.scene`` now: the program reads ``self.slots[sim].view``, which must be the
        scene it was made for."""
        src, slot = self.scene, self.slots[sim]
        mujoco.mj_copyData(slot.view.data, src.model, src.data)
        self._loaded(sim)
        slot.program, slot.index = program, index
        self._resume(sim)

    def _resume(self, sim: int) -> None:
        """Run simulation ``sim``'s program to its next request (SetState is carried out at
        once, since it needs no stepping)."""
        slot = self.slots[sim]
        while slot.program is not None:
            try:
                req = next(slot.program)
            except StopIteration:
                slot.program = slot.request = None
                return
            if isinstance(req, SetState):
                mujoco.mj_setState(slot.view.model, slot.view.data, req.state, STATE_SPEC)
                self._state_set(sim, req.state)
                continue
            slot.request = req
            return

    def step_pending(self) -> None:
        """One round: every pending Advance, grouped by length, one backend call per group;
        then each program of the group runs to its next request."""
        groups: dict[int, list[int]] = defaultdict(list)
        pending: dict[int, Advance] = {}
        for sim, slot in enumerate(self.slots):
            if isinstance(slot.request, Advance):
                groups[slot.request.nstep].append(sim)
                pending[sim] = slot.request
        for nstep, ids in sorted(groups.items()):
            self._advance(nstep, ids, [pending[i] for i in ids])
            for sim in ids:
                self._resume(sim)

    # -- what a backend provides
    def _loaded(self, sim: int) -> None:
        """Simulation ``sim``'s view now holds a new start state (and the scene's gravity)."""
        raise NotImplementedError

    def _state_set(self, sim: int, state: np.ndarray) -> None:
        """A program restored ``state`` (already in its view)."""
        raise NotImplementedError

    def _advance(self, nstep: int, ids: list[int], reqs: list[Advance]) -> None:
        """Carry out ``reqs`` (all of ``nstep`` steps) on simulations ``ids``, views refreshed."""
        raise NotImplementedError


class BatchRunner(ProgramRunner):
    """Programs stepped on ``mujoco.batch`` with ``nthread`` threads (the caller's included)."""

    def __init__(self, scene: Scene, nsim: int, nthread: int) -> None:
        super().__init__(scene, nsim)
        self.batch = mjbatch.Batch(scene.model, nsim, nthread=nthread, persistent=True)
        self._gravity = self.batch.expand("opt.gravity")
        self._state = self.batch.state
        self._ctrl = self.batch.bind("ctrl")
        self._mocap = self.batch.bind("mocap_pos")
        self._xfrc = self.batch.bind("xfrc_applied")
        self._qpos = self.batch.bind("qpos")
        self._qvel = self.batch.bind("qvel")

    def _loaded(self, sim: int) -> None:
        src = self.scene
        mujoco.mj_getState(src.model, src.data, self._state[sim], STATE_SPEC)
        self._gravity[sim] = src.model.opt.gravity

    def _state_set(self, sim: int, state: np.ndarray) -> None:
        self._state[sim] = state

    def _apply(self, sim: int, req: Advance) -> None:
        """The settings an Advance makes before its first step, into the simulation's row."""
        sc = self.scene
        if req.gravity is not None:
            self._gravity[sim] = req.gravity
        if req.mocap_pos is not None:
            self._mocap[sim, sc.mocap_id] = req.mocap_pos
        if req.object_force is not None:
            self._xfrc[sim, sc.obj_body, :3] = req.object_force
            self._xfrc[sim, sc.obj_body, 3:] = 0.0

    def _refresh(self, ids: Iterable[int]) -> None:
        """Each program's view after a call: the simulation's whole MjData, its state as the
        row holds it (a pin writes the row after the last step)."""
        for sim in ids:
            view = self.slots[sim].view
            self.batch.get_data(sim, view.data)
            mujoco.mj_setState(view.model, view.data, self._state[sim], STATE_SPEC)

    def _advance(self, nstep: int, ids: list[int], reqs: list[Advance]) -> None:
        for sim, req in zip(ids, reqs, strict=True):
            self._apply(sim, req)
        if nstep <= 0:
            return
        if not any(r.per_step for r in reqs):
            self.batch.step(ids=ids, nstep=nstep)
        else:
            self._step_each(nstep, ids, reqs)
        self._refresh(ids)

    def _step_each(self, nstep: int, ids: list[int], reqs: list[Advance]) -> None:
        """Step one at a time, ramping controls and pinning objects between steps."""
        sc = self.scene
        ramp = [k for k, r in enumerate(reqs) if r.ctrl_from is not None]
        pinned = [(ids[k], r.pin) for k, r in enumerate(reqs) if r.pin is not None]
        for step in range(nstep):
            for k in ramp:
                self._ctrl[ids[k], sc.hand_act] = reqs[k].ctrl_at(step)
            self.batch.step(ids=ids)
            for sim, (pos, quat) in pinned:
                self._qpos[sim, sc.obj_qadr:sc.obj_qadr + 3] = pos
                self._qpos[sim, sc.obj_qadr + 3:sc.obj_qadr + 7] = quat
                self._qvel[sim, sc.obj_dadr:sc.obj_dadr + 6] = 0.0


#: starts one grasp: (grasp, the scene its program is to read) → result so far, program or None
Starter = Callable[[Grasp, Scene], tuple[ValidationResult, Program | None]]


def validate_batched(runner: ProgramRunner, grasps: Sequence[Grasp], start: Starter,
                     progress: Callable[[int], None] | None = None) -> list[ValidationResult]:
    """Validate ``grasps`` on ``runner``, refilling each simulation as its grasp finishes;
    results in input order. ``start`` places a grasp in ``runner.scene`` (the protocol's
    scene) and returns its program over the given view (:meth:`Validator.start`)."""
    results: list[ValidationResult | None] = [None] * len(grasps)
    running: dict[int, ValidationResult] = {}
    todo = iter(range(len(grasps)))
    done = 0

    def finish(index: int) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done)

    while True:
        for sim in runner.free():
            slot = runner.slots[sim]
            if slot.index >= 0:          # a program that just finished
                results[slot.index] = running.pop(slot.index)
                finish(slot.index)
                slot.index = -1
            for i in todo:
                result, program = start(grasps[i], slot.view)
                if program is None:
                    results[i] = result
                    finish(i)
                    continue
                running[i] = result
                runner.load(sim, program, i)
                break
        if not runner.busy:
            break
        runner.step_pending()
    return [r for r in results if r is not None]
