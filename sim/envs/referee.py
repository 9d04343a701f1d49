"""Lift-drop judging actions it does not choose: the environment's reward and termination.

Why: the environment should reward what the validator would pass, and the validator's
verdict is its lift-drop program (:mod:`sim.validate.lift_drop`), which reads the scene and
decides — after the closing, whether anything touches; through the lift and the hold,
whether the object stayed in the palm; at the release, whether it left the opened hand. The
:class:`Referee` starts that very program on the environment's scene
(:meth:`sim.validate.validator.Validator.start`: the validator's placement, penetration check
and targets) and carries it out with a :class:`sim.episodes.cursor.ProgramCursor` that does
not drive: gravity and the other conditions are the protocol's, the hand's controls and its
base's target are the policy's. So the episode lasts as the protocol's timeline does (about
3 s) and ends with the protocol's verdict, and replaying an episode that
:func:`sim.episodes.rollout.rollout` recorded gives the validator's run again.

The environment's scene may differ from the validator's by a table (:func:`env_scene`):
the protocol's state is carried over by value (mjSTATE_INTEGRATION), which a table changes
nothing of.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.episodes.approach import approach_path, back_off
from sim.episodes.cursor import ProgramCursor
from sim.episodes.rollout import APPROACH_SETTLE_S, PROTOCOL
from sim.grasp import Grasp
from sim.validate.program import STATE_SPEC, Program, save_state
from sim.validate.protocols.registry import get_closing
from sim.validate.result import ValidationResult
from sim.validate.validator import Validator
from sim.world.scene import Scene

__all__ = ["Referee", "env_scene"]


def env_scene(validator: Validator, *, table: bool) -> Scene:
    """The scene an environment simulates: the validator's lift-drop scene — its contacts,
    physics and servos — built anew (its own model and data, so the validator's own runs and
    the environment's never share a simulation), with ``table`` the table under it (top at
    z = 0, 30 cm below the object's home, where it catches what falls)."""
    protocol = get_closing(PROTOCOL)
    return Scene(validator.hand, validator.obj, table=table, contact=validator.config.common.contact,
                 physics=protocol.physics(validator.config), servos=validator.servos,
                 contact_on_hand=True)


class Referee:
    """Lift-drop on ``scene`` (:func:`env_scene` of ``validator``), judging someone else's
    actions (module docstring)."""

    def __init__(self, validator: Validator, scene: Scene) -> None:
        self.validator = validator
        self.scene = scene
        self.result: ValidationResult | None = None
        self.cursor = ProgramCursor(scene, None, drive=False)
        self._pending: Program | None = None
        self._wait = 0

    def start(self, grasp: Grasp, approach_m: float = 0.0, approach_s: float = 0.5) -> None:
        """Put ``scene`` where lift-drop starts ``grasp`` (at its pregrasp, at rest, gravity
        off; or where the validator placed it when it decided without simulating) and start
        judging from there. ``approach_m`` > 0: the hand starts that far out along its palm
        normal instead, and the protocol starts judging after the steps an approach of
        ``approach_s`` takes (:func:`sim.episodes.approach.approach_path`), from wherever
        the actions have brought the hand by then."""
        result, program = self.validator.start(grasp, PROTOCOL, scene=self.scene)
        source = self.validator.scene(PROTOCOL)
        if source.data is self.scene.data:
            raise ValueError("the referee's scene must be its own simulation (env_scene)")
        m, d = self.scene.model, self.scene.data
        mujoco.mj_resetData(m, d)
        mujoco.mj_setState(m, d, save_state(source), STATE_SPEC)
        m.opt.gravity[:] = source.model.opt.gravity
        mujoco.mj_forward(m, d)
        self.result = result
        self._wait = 0
        if approach_m > 0.0 and program is not None:
            self._wait = len(approach_path(self.scene, approach_m, approach_s, APPROACH_SETTLE_S))
            back_off(self.scene, approach_m)
        self._pending = program
        self.cursor = ProgramCursor(self.scene, None if self._wait else program, drive=False)

    @property
    def done(self) -> bool:
        """Whether the protocol has given its verdict."""
        return self._wait == 0 and self.cursor.done

    @property
    def passed(self) -> bool:
        """The verdict: the protocol ended and the grasp passed (False while it runs)."""
        return self.done and self.result is not None and bool(self.result.passed)

    def before_step(self) -> None:
        if not self._wait:
            self.cursor.before_step()

    def after_step(self) -> None:
        """After one step: on the approach, count it down (the program starts when it is
        through); else the program's step."""
        if self._wait:
            self._wait -= 1
            if not self._wait:
                self.cursor = ProgramCursor(self.scene, self._pending, drive=False)
            return
        self.cursor.after_step()

    @property
    def failure(self) -> str | None:
        """Why the grasp failed, once the protocol has ended (None: it passed or runs)."""
        if not self.done or self.result is None or self.result.failure is None:
            return None
        return str(self.result.failure)

    def start_quat(self) -> np.ndarray:
        """The hand base target's orientation (wxyz) the protocol started the grasp with."""
        return self.scene.data.mocap_quat[self.scene.mocap_id].copy()
