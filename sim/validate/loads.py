"""What each validation protocol asks a grasp to hold, as :class:`sim.metrics.holding.HoldLoads`.

FSG ranks its candidates by their grip ratio (:meth:`HoldLoads.grip_ratio`) before anything is
simulated; the loads and friction must be the ones the chosen protocol then simulates, or the
ranking would favour grasps for a test that is not run. Read from the protocol's config:

* ``lift-drop``: the object's weight (real mass), straight down in the object frame — the
  validator lifts with the object at its home orientation; contacts ``[common] friction``.
* ``six-dir``: six pushes of ``force_per_kg`` × the real mass along ±x, ±y, ±z (gravity off, as
  it runs); ``[common] friction``.
* ``dgb``: six pushes of ``force_per_kg`` × the benchmark's mass (0.1 kg unless "real"); its
  own friction (0.6 / 0.02).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from sim.metrics.holding import HoldLoads
from sim.validate.config import GRAVITY_MPS2, PROTOCOLS, ValidateConfig

if TYPE_CHECKING:
    from sim.world.objects import ObjectAsset

__all__ = ["hold_loads"]


def _six_pushes(force_n: float) -> np.ndarray:
    axes = np.vstack([np.eye(3), -np.eye(3)]) * force_n
    return np.hstack([axes, np.zeros((6, 3))])


def hold_loads(obj: ObjectAsset, protocol: str = "lift-drop",
               config: ValidateConfig | None = None) -> HoldLoads:
    """The loads ``protocol`` puts on ``obj`` held in a grasp, with that protocol's friction
    (``config``: default ``configs/validate.toml``)."""
    if protocol not in PROTOCOLS:
        raise ValueError(f"unknown protocol {protocol!r}; expected one of {PROTOCOLS}")
    config = config or ValidateConfig.load()
    com = np.asarray(obj.com_m, dtype=float)
    if protocol == "dgb":
        p = config.dgb
        mass_kg = obj.mass_kg if p.object_mass_kg is None else p.object_mass_kg
        return HoldLoads(_six_pushes(p.force_per_kg * mass_kg), com, p.contact.friction[0],
                         p.contact.friction[1], protocol)
    friction = config.common.contact.friction
    if protocol == "six-dir":
        loads = _six_pushes(config.six_dir.force_per_kg * obj.mass_kg)
    else:
        loads = np.array([[0.0, 0.0, -obj.mass_kg * GRAVITY_MPS2, 0.0, 0.0, 0.0]])
    return HoldLoads(loads, com, friction[0], friction[1], protocol)
