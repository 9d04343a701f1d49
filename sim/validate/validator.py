"""Physical grasp validation in MuJoCo (DESIGN §5): one entry point for every protocol.

:class:`Validator` validates grasps of one hand on one object under a protocol named as it is
registered (:mod:`sim.validate.protocols`: ``lift-drop``, ``six-dir``, ``dgb``, or one added
with :func:`sim.validate.protocols.register`). The protocol builds its scene, sizes the
squeeze for its loads and runs its program; the placing, contact and closing services it uses
are :class:`sim.validate.grasp_bench.GraspBench`'s. Protocols that run as one program
(:class:`sim.validate.protocols.ClosingProtocol`: lift-drop, six-dir) also run many grasps at
once on ``mujoco.batch`` or MuJoCo Warp. Simulation is deterministic: the same grasp gives the
same result on any worker.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.metrics.holding import HoldLoads
from sim.validate.batched import BatchRunner, ProgramRunner, validate_batched
from sim.validate.config import ValidateConfig
from sim.validate.grasp_bench import GraspBench
from sim.validate.lift_drop import Observer
from sim.validate.program import Program
from sim.validate.protocols.base import ClosingProtocol, Options
from sim.validate.protocols.registry import get, get_closing, names
from sim.validate.result import ValidationResult
from sim.validate.targets import holds_every_load
from sim.world.contacts import Contacts
from sim.world.objects import ObjectAsset
from sim.world.scene import Scene

__all__ = ["BACKENDS", "BATCH_SIMS", "Validator"]

#: engines the program protocols can step on: MuJoCo (C, mujoco.batch threads), MuJoCo Warp
BACKENDS = ("mujoco", "warp")

#: grasps a validator keeps in flight at once on mujoco.batch (lift-drop, six-dir)
BATCH_SIMS = 16


class Validator(GraspBench):
    """Validates grasps of one hand on one object; owns one scene per protocol (built lazily)."""

    def __init__(self, hand: Hand, obj: ObjectAsset, config: ValidateConfig | None = None) -> None:
        super().__init__(hand, obj, config)
        self._runners: dict[tuple[object, ...], ProgramRunner] = {}

    def holds_every_load(self, near: Contacts, loads: HoldLoads) -> bool:
        # looked up in this module, where the squeeze's contact widening has always found it
        return holds_every_load(near, loads)

    def validate(self, grasp: Grasp, protocol: str = "lift-drop", *,
                 squeeze_convention: str | None = None,
                 observe: Observer | None = None,
                 gravity_dir: np.ndarray | None = None) -> ValidationResult:
        """Validate one grasp under registered protocol ``protocol`` (DESIGN §5).
        ``squeeze_convention`` (dgb) overrides ``[dgb] squeeze_convention``; ``observe``
        (lift-drop, for :mod:`sim.validate.diagnose`) is called with "closed" once the fingers
        have closed and settled, then through the lift and hold; ``gravity_dir`` (lift-drop;
        object frame, default −z): the way gravity pulls during the lift
        (:func:`sim.validate.lift_drop.lift_drop`)."""
        return get(protocol).validate(self, grasp, Options(squeeze_convention, observe, gravity_dir))

    def validate_all(self, grasps: Sequence[Grasp], protocol: str = "lift-drop", *,
                     nthread: int = 1, squeeze_convention: str | None = None,
                     progress: Callable[[int], None] | None = None,
                     backend: str = "mujoco", device: str = "cuda",
                     nworld: int = 1024,
                     gravity_dir: np.ndarray | None = None) -> list[ValidationResult]:
        """Validate ``grasps`` in input order, the results exactly :meth:`validate`'s.

        With ``nthread`` > 1, the program protocols (lift-drop, six-dir) run up to
        :data:`BATCH_SIMS` grasps at once on ``mujoco.batch`` with that many threads
        (:mod:`sim.validate.batched`): one process using several cores. With one thread they
        step grasp by grasp from Python, which measured 12 % faster than a one-thread batch
        (``benchmarks/bench_validate_speed.py``: MuJoCo's step is 75 % of the time either way,
        and one MjData stays in cache); the results are the same bit for bit. dgb always steps
        grasp by grasp. ``backend="warp"`` steps the program protocols as ``nworld`` worlds of
        MuJoCo Warp on ``device`` instead (:mod:`sim.validate.warp_runner`; close to, not
        bit-identical with, the C engine's results). ``progress(n_done)`` is called as grasps
        finish; ``gravity_dir`` as in :meth:`validate`."""
        if backend not in BACKENDS:
            raise ValueError(f"backend {backend!r}: expected one of {BACKENDS}")
        batchable = isinstance(get(protocol), ClosingProtocol)
        if backend != "mujoco" and not batchable:
            runs = tuple(n for n in names() if isinstance(get(n), ClosingProtocol))
            raise ValueError(f"backend {backend!r} runs {' and '.join(runs)}, not {protocol!r}")
        if not batchable or (backend == "mujoco" and nthread == 1):
            out = []
            for g in grasps:
                out.append(self.validate(g, protocol, squeeze_convention=squeeze_convention,
                                         gravity_dir=gravity_dir))
                if progress is not None:
                    progress(len(out))
            return out
        key = (protocol, backend, nthread if backend == "mujoco" else (device, nworld))
        if key not in self._runners:
            if backend == "warp":
                from sim.validate.warp_runner import WarpRunner

                self._runners[key] = WarpRunner(self.scene(protocol), nworld, device)
            else:
                self._runners[key] = BatchRunner(self.scene(protocol), BATCH_SIMS, nthread)
        return validate_batched(self._runners[key], grasps,
                                lambda g, view: self.start(g, protocol, scene=view,
                                                           gravity_dir=gravity_dir), progress)

    def start(self, grasp: Grasp, protocol: str, *, scene: Scene | None = None,
              observe: Observer | None = None, gravity_dir: np.ndarray | None = None,
              ) -> tuple[ValidationResult, Program | None]:
        """Place ``grasp`` in the protocol's scene and decide what can be decided without
        simulating; the result so far and, when simulation must follow, the program that
        finishes it (:meth:`sim.validate.protocols.ClosingProtocol.start`; ``scene``: a batch
        runner's view of its own simulation). Program protocols only (lift-drop, six-dir);
        ``gravity_dir`` as in :meth:`validate`."""
        options = Options(observe=observe, gravity_dir=gravity_dir)
        return get_closing(protocol).start(self, grasp, scene=scene, options=options)
