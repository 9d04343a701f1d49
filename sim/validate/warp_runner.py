"""Validation programs stepped on a GPU with MuJoCo Warp (``mujoco-warp``), one world per grasp.

Why: a GPU steps thousands of worlds at once, where the CPU path (:class:`BatchRunner`) steps a
few per core. The protocols are the same programs (:mod:`sim.validate.program`), so the verdicts
mean the same; they are not bit-identical to MuJoCo's C engine (Warp's collision and solver
differ in detail), which is why agreement is measured (``benchmarks/bench_warp_agreement.py``)
rather than asserted.

The host views are authoritative: before each call every world's state is uploaded from its
view, all worlds are stepped, and only the worlds of the call are read back (a world that was
not asked to advance is simply uploaded again unchanged next time). Gravity is a per-world
model field (``opt.gravity``, one row per world). Needs ``pip install mujoco-warp`` and, for
``device="cuda"`` (the default), a CUDA device; ``device="cpu"`` runs Warp's CPU backend, slow,
for checking agreement on machines without a GPU.
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from sim.errors import DexaugError
from sim.validate.batched import ProgramRunner
from sim.validate.program import Advance
from sim.world.scene import Scene

__all__ = ["WarpRunner", "WarpUnavailable", "import_warp"]

#: contacts and constraint rows per world the device buffers hold (a grasp: ≈ 10–40 contacts)
CONTACTS_PER_WORLD = 128
CONSTRAINTS_PER_WORLD = 1024
_STATE_FIELDS = ("qpos", "qvel", "act", "ctrl", "mocap_pos", "mocap_quat", "xfrc_applied",
                 "qfrc_applied", "qacc_warmstart", "time")


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

    def __init__(self, scene: Scene, nsim: int, device: str = "cuda") -> None:
        super().__init__(scene, nsim)
        self.wp, self.mjw = import_warp(device)
        self.device = device
        m = scene.model
        with self.wp.ScopedDevice(device):
            self.wm = self.mjw.put_model(m)
            self.wd = self.mjw.make_data(m, nworld=nsim, nconmax=CONTACTS_PER_WORLD,
                                         njmax=CONSTRAINTS_PER_WORLD)
        self._gravity = np.zeros((nsim, 3))

    def _loaded(self, sim: int) -> None:
        self._gravity[sim] = self.scene.model.opt.gravity

    def _state_set(self, sim: int, state: np.ndarray) -> None:
        """Nothing to do: the view holds it and is uploaded before the next call."""

    def _upload(self) -> None:
        """Every world's state from its view, and the per-world gravity."""
        wp = self.wp
        for name in _STATE_FIELDS:
            rows = np.stack([getattr(s.view.data, name) for s in self.slots])
            getattr(self.wd, name).assign(rows)
        self.wm.opt.gravity = wp.array(self._gravity, dtype=wp.vec3, device=self.device)

    def _apply(self, sim: int, req: Advance) -> None:
        """The settings an Advance makes before its first step, into the view (host state)."""
        sc, d = self.scene, self.slots[sim].view.data
        if req.gravity is not None:
            self._gravity[sim] = req.gravity
        if req.mocap_pos is not None:
            d.mocap_pos[sc.mocap_id] = req.mocap_pos
        if req.object_force is not None:
            d.xfrc_applied[sc.obj_body, :3] = req.object_force
            d.xfrc_applied[sc.obj_body, 3:] = 0.0

    def _advance(self, nstep: int, ids: list[int], reqs: list[Advance]) -> None:
        for sim, req in zip(ids, reqs, strict=True):
            self._apply(sim, req)
        if nstep <= 0:
            return
        sc = self.scene
        self._upload()
        ramp = [(sim, r) for sim, r in zip(ids, reqs, strict=True) if r.ctrl_from is not None]
        pinned = [(sim, r.pin) for sim, r in zip(ids, reqs, strict=True) if r.pin is not None]
        with self.wp.ScopedDevice(self.device):
            for step in range(nstep):
                if ramp:
                    ctrl = self.wd.ctrl.numpy()
                    for sim, r in ramp:
                        ctrl[sim, sc.hand_act] = r.ctrl_at(step)
                    self.wd.ctrl.assign(ctrl)
                self.mjw.step(self.wm, self.wd)
                if pinned:
                    qpos, qvel = self.wd.qpos.numpy(), self.wd.qvel.numpy()
                    for sim, (pos, quat) in pinned:
                        qpos[sim, sc.obj_qadr:sc.obj_qadr + 3] = pos
                        qpos[sim, sc.obj_qadr + 3:sc.obj_qadr + 7] = quat
                        qvel[sim, sc.obj_dadr:sc.obj_dadr + 6] = 0.0
                    self.wd.qpos.assign(qpos)
                    self.wd.qvel.assign(qvel)
            self.wp.synchronize()
        for sim in ids:
            self.mjw.get_data_into(self.slots[sim].view.data, sc.model, self.wd, world_id=sim)
