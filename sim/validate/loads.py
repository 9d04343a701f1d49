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

Each protocol states its own (:meth:`sim.validate.protocols.Protocol.hold_loads`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sim.validate.config import ValidateConfig
from sim.validate.protocols.registry import get

if TYPE_CHECKING:
    from sim.metrics.holding import HoldLoads
    from sim.world.objects import ObjectAsset

__all__ = ["hold_loads"]


def hold_loads(obj: ObjectAsset, protocol: str = "lift-drop",
               config: ValidateConfig | None = None) -> HoldLoads:
    """The loads ``protocol`` puts on ``obj`` held in a grasp, with that protocol's friction
    (``config``: default ``configs/validate.toml``; each protocol's ``hold_loads``)."""
    chosen = get(protocol)   # an unknown name raises, listing the registered ones
    return chosen.hold_loads(obj, config or ValidateConfig.load())
