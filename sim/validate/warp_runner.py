"""Validation programs stepped on a GPU with MuJoCo Warp (``mujoco-warp``), one world per grasp.

Why: a GPU steps thousands of worlds at once, where the CPU path (:class:`BatchRunner`) steps a
few per core. The protocols are the same programs (:mod:`sim.validate.program`), so the verdicts
mean the same; they are not bit-identical to MuJoCo's C engine (Warp's collision and solver
differ in detail), which is why agreement is measured (``benchmarks/bench_warp_agreement.py``)
rather than asserted.

Nothing crosses the bus inside a stretch of stepping. A request's control ramp and object pin
are device arrays read by two small kernels that run around ``mujoco_warp.step``, so one step
of every world is the same launch sequence whatever the programs ask: it is captured once as a
graph (a CUDA graph on a GPU) and replayed ``nstep`` times. Per call, each state field is uploaded once for
all worlds and downloaded once (not world by world: ``mujoco_warp.get_data_into`` copies every
device array whole for each world it is asked about, which is quadratic in the worlds).

The host views are authoritative: before each call every world's state is uploaded from its
view, all worlds are stepped, and the worlds of the call get their new state back, their
derived quantities (contacts, body poses, constraint forces) recomputed by ``mj_forward`` on the
host at that state. (The C path's views hold derived fields one step behind the state, as
after ``mj_step``; here they are those of the state itself.) Gravity is a per-world model field
(``opt.gravity``, one row per world). Needs ``pip install mujoco-warp`` and, for
``device="cuda"`` (the default), a CUDA device; ``device="cpu"`` runs Warp's CPU backend, slow,
for checking agreement on machines without a GPU.
"""

from __future__ import annotations

import importlib
import logging
import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from sim.errors import DexaugError
from sim.validate.batched import ProgramRunner
from sim.validate.program import Advance
from sim.world.scene import Scene

__all__ = ["WarpRunner", "WarpUnavailable", "import_warp"]

log = logging.getLogger(__name__)

#: contacts and constraint rows per world the device buffers hold (a grasp: ≈ 10–40 contacts)
CONTACTS_PER_WORLD = 128
CONSTRAINTS_PER_WORLD = 1024
#: the state a call uploads for every world and downloads for the worlds it advanced
_STATE_IN = ("qpos", "qvel", "act", "ctrl", "mocap_pos", "mocap_quat", "xfrc_applied",
             "qfrc_applied", "qacc_warmstart", "time")
_STATE_OUT = ("qpos", "qvel", "act", "ctrl", "qacc_warmstart", "time")


class WarpUnavailable(DexaugError):
    """``--backend warp`` cannot run here (package missing, or no CUDA device)."""


def import_warp(device: str) -> tuple[Any, Any]:
    """(warp, mujoco_warp), or WarpUnavailable saying what is missing."""
    try:
        wp = importlib.import_module("warp")
        mjw = importlib.import_module("mujoco_warp")
    except ImportError as exc:
        raise WarpUnavailable(f"--backend warp needs MuJoCo Warp: pip install mujoco-warp "
                              f"({exc.name} is not installed)") from exc
    wp.config.quiet = True
    wp.init()
    if device.startswith("cuda") and not wp.is_cuda_available():
        raise WarpUnavailable("--backend warp needs a CUDA device and Warp finds none "
                              f"(devices: {[str(d) for d in wp.get_devices()]})")
    return wp, mjw


class WarpRunner(ProgramRunner):
    """Up to ``nsim`` programs of ``scene`` as the worlds of one MuJoCo Warp model on
    ``device``."""

    def __init__(self, scene: Scene, nsim: int, device: str = "cuda", capture: bool = True,
                 ) -> None:
        super().__init__(scene, nsim)
        self.capture = capture
        self.wp, self.mjw = wp, mjw = import_warp(device)
        self.device = device
        m = scene.model
        nact = len(scene.hand_act)
        self._gravity = np.zeros((nsim, 3))
        self._nramp = np.zeros(nsim, np.int32)
        self._c0 = np.zeros((nsim, nact), np.float32)
        self._c1 = np.zeros((nsim, nact), np.float32)
        self._pinned = np.zeros(nsim, np.int32)
        self._pose = np.zeros((nsim, 7), np.float32)
        with wp.ScopedDevice(device):
            self.wm = mjw.put_model(m)
            self.wd = mjw.make_data(m, nworld=nsim, nconmax=CONTACTS_PER_WORLD,
                                    njmax=CONSTRAINTS_PER_WORLD)
            # one array for the run: a captured graph holds its address
            self.wm.opt.gravity = wp.zeros(nsim, dtype=wp.vec3)
            #: host rows the step kernels read → their device copies
            self._rows = {name: (arr, wp.zeros(arr.shape, dtype=wp.int32 if arr.dtype == np.int32
                                               else wp.float32))
                          for name, arr in (("nramp", self._nramp), ("c0", self._c0),
                                            ("c1", self._c1), ("pinned", self._pinned),
                                            ("pose", self._pose))}
            self._dev = {name: dev for name, (_, dev) in self._rows.items()}
            self._k = wp.zeros(1, dtype=wp.int32)
            self._act = wp.array(np.asarray(scene.hand_act, np.int32), dtype=wp.int32)
        self._graph: Any = None
        #: device work so far: world-steps launched, and seconds from upload to download; host
        #: seconds spent writing the advanced worlds' states back and running their mj_forward
        self.world_steps = 0
        self.device_s = 0.0
        self.refresh_s = 0.0

    @property
    def graph_captured(self) -> bool:
        """Whether steps replay a captured graph (known after the first call)."""
        return bool(self._graph)

    def _loaded(self, sim: int) -> None:
        self._gravity[sim] = self.scene.model.opt.gravity

    def _state_set(self, sim: int, state: np.ndarray) -> None:
        """Nothing to do: the view holds it and is uploaded before the next call."""

    def _apply(self, sim: int, req: Advance) -> None:
        """The settings an Advance makes before its first step: into the view (host state),
        and its ramp and pin into the rows the step kernels read."""
        sc, d = self.scene, self.slots[sim].view.data
        if req.gravity is not None:
            self._gravity[sim] = req.gravity
        if req.mocap_pos is not None:
            d.mocap_pos[sc.mocap_id] = req.mocap_pos
        if req.object_force is not None:
            d.xfrc_applied[sc.obj_body, :3] = req.object_force
            d.xfrc_applied[sc.obj_body, 3:] = 0.0
        if req.ctrl_from is not None:
            self._nramp[sim] = req.nstep
            self._c0[sim], self._c1[sim] = req.ctrl_from, req.ctrl_to
        if req.pin is not None:
            self._pinned[sim] = 1
            self._pose[sim, :3], self._pose[sim, 3:] = req.pin

    def _upload(self) -> None:
        """Every world's state from its view, the per-world gravity, ramps and pins."""
        for name in _STATE_IN:
            rows = np.stack([getattr(s.view.data, name) for s in self.slots])
            getattr(self.wd, name).assign(rows)
        self.wm.opt.gravity.assign(self._gravity.astype(np.float32))
        for arr, dev in self._rows.values():
            dev.assign(arr)
        self._k.zero_()

    def _one_step(self) -> None:
        """Ramp, step, pin, count: one step of every world, launched on the device."""
        from sim.validate.warp_kernels import count, pin, ramp

        wp, sc, wd = self.wp, self.scene, self.wd
        nsim, dev = len(self.slots), self._dev
        wp.launch(ramp, dim=(nsim, len(sc.hand_act)),
                  inputs=[self._k, dev["nramp"], self._act, dev["c0"], dev["c1"], wd.ctrl])
        self.mjw.step(self.wm, wd)
        wp.launch(pin, dim=(nsim, 7), inputs=[dev["pinned"], dev["pose"], int(sc.obj_qadr),
                                              int(sc.obj_dadr), wd.qpos, wd.qvel])
        wp.launch(count, dim=1, inputs=[self._k])

    def load_kernels(self) -> None:
        """Load every kernel module a step launches (compiling those not in Warp's kernel
        cache), by one eager step of every world; the next call uploads all states again."""
        with self.wp.ScopedDevice(self.device):
            self._upload()
            self._one_step()
            self.wp.synchronize()

    def _stepper(self) -> Callable[[], None]:
        """One step of every world: a replayed graph (Warp captures on CUDA and on the CPU),
        captured on the first call after one step run eagerly, which loads the kernels; the
        launches themselves with ``capture=False`` or where capture fails."""
        if self._graph is None:
            self._graph = False
            if self.capture:
                wp = self.wp
                self.load_kernels()
                self._upload()          # the eager step is undone: every world starts again
                try:
                    with wp.ScopedCapture(force_module_load=False) as capture:
                        self._one_step()
                    self._graph = capture.graph
                except Exception as exc:  # any capture failure: launch eagerly
                    log.warning("MuJoCo Warp: graph capture failed (%s); stepping without", exc)
        if self._graph is False:
            return self._one_step
        return lambda: self.wp.capture_launch(self._graph)

    def _advance(self, nstep: int, ids: list[int], reqs: list[Advance]) -> None:
        self._nramp[:] = 0
        self._pinned[:] = 0
        for sim, req in zip(ids, reqs, strict=True):
            self._apply(sim, req)
        if nstep <= 0:
            return
        t0 = time.perf_counter()
        with self.wp.ScopedDevice(self.device):
            self._upload()
            step = self._stepper()
            for _ in range(nstep):
                step()
            out = {name: getattr(self.wd, name).numpy() for name in _STATE_OUT}
        t1 = time.perf_counter()
        self.device_s += t1 - t0
        self.world_steps += nstep * len(self.slots)
        m = self.scene.model
        for sim in ids:
            d = self.slots[sim].view.data
            for name, rows in out.items():
                if name == "time":
                    d.time = float(rows[sim])
                else:
                    getattr(d, name)[...] = rows[sim]
            mujoco.mj_forward(m, d)
        self.refresh_s += time.perf_counter() - t1
