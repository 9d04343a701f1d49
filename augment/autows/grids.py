"""AutoWS joint grids (paper section 3.2; DESIGN §4): which joint angles a finger's workspace cloud
is built from.

* **Manual** (no demo): the config's ranges (``ranges_deg``; the paper's Table 1 for the Shadow
  Hand), overridable per joint, on a grid of ``step_deg`` (10°) from the lower bound, the upper
  bound always included.
* **Demo**: each independent joint at its demo angle ± ``demo_steps`` steps of ``demo_step_deg``
  (± 2 × 5°, five values).

Values are clipped to the joint limits (duplicates dropped). :func:`grid_joint_vectors` expands a
finger's grid into full joint vectors: coupled followers follow their leaders (``q_f = c·q_l``, the
paper's FJ1 = FJ2); with a demo they keep the demo's own offset from that rule
(``q_f = d_f + c·(q_l − d_l)``) so that the demonstrated pose itself is in the grid even when the
simulated hand split a tendon-coupled pair unevenly. Every other joint of the hand is 0.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from augment.autows.params import AutoWSParams, WorkspaceError
from augment.autows.seed import DemoSeed

if TYPE_CHECKING:
    from sim.hand.model import Hand

__all__ = ["grid_joint_vectors", "joint_grids"]

log = logging.getLogger(__name__)


def _manual_values(lo: float, hi: float, step: float) -> np.ndarray:
    n = math.floor((hi - lo) / step + 1e-9)
    values = lo + step * np.arange(n + 1)
    if hi - values[-1] > 1e-9:
        values = np.append(values, hi)
    return values


def joint_grids(hand: Hand, params: AutoWSParams, demo: DemoSeed | None = None,
                ranges: Mapping[str, tuple[float, float]] | None = None,
                ) -> dict[str, dict[str, np.ndarray]]:
    """Per finger, the grid values (radians) of each independent joint, in the finger's order.

    Manual ranges come from the hand config (``ranges_deg``), overridden per joint by ``ranges``
    (radians). With a demo, ranges are centred on the demo angles instead (and ``ranges`` must
    not be given).

    Raises:
        WorkspaceError: ranges together with a demo, an empty (lo > hi) or non-finite range, a
            joint with no range and no demo, or a range for a joint that is not an independent
            finger joint.
    """
    overrides = dict(ranges or {})
    if overrides and demo is not None:
        raise WorkspaceError(f"demo {demo.id!r}: manual ranges apply without a demo only (a demo "
                             "centres the grids on its own joint angles)")
    known = {j for f in hand.config.fingers for j in f.independent_joints}
    bad = sorted(set(overrides) - known)
    if bad:
        raise WorkspaceError(f"hand {hand.name!r}: ranges given for {bad}, which are not "
                             f"independent finger joints ({sorted(known)})")
    step = math.radians(params.step_deg)
    dstep = math.radians(params.demo_step_deg)
    grids: dict[str, dict[str, np.ndarray]] = {}
    for finger in hand.config.fingers:
        per_joint: dict[str, np.ndarray] = {}
        for joint in finger.independent_joints:
            j = hand.joint_names.index(joint)
            lo_lim, hi_lim = hand.lower[j], hand.upper[j]
            if demo is not None:
                centre = float(demo.joints[j])
                values = centre + dstep * np.arange(-params.demo_steps, params.demo_steps + 1)
            else:
                if joint in overrides:
                    lo, hi = (float(v) for v in overrides[joint])
                elif joint in finger.ranges_rad:
                    lo, hi = finger.ranges_rad[joint]
                else:
                    raise WorkspaceError(f"{hand.config.file}: fingers '{finger.name}'.ranges_deg: "
                                         f"no range for joint {joint!r} (give one, or a demo)")
                if not (math.isfinite(lo) and math.isfinite(hi)):
                    raise WorkspaceError(f"hand {hand.name!r}, joint {joint!r}: range [{lo}, {hi}] "
                                         "is not finite")
                if lo > hi:
                    raise WorkspaceError(f"hand {hand.name!r}, finger {finger.name!r}, joint "
                                         f"{joint!r}: empty range [{math.degrees(lo):.3g}°, "
                                         f"{math.degrees(hi):.3g}°] (lower > upper)")
                values = _manual_values(lo, hi, step)
            clipped = np.unique(np.clip(values, lo_lim, hi_lim))
            # MJCF limits are often rounded (1.22173 for 70°): warn only beyond 1e-4 rad
            if demo is None and (values.min() < lo_lim - 1e-4 or values.max() > hi_lim + 1e-4):
                log.warning("hand %s, joint %s: range [%.1f°, %.1f°] exceeds the joint limits "
                            "[%.1f°, %.1f°]; grid clipped", hand.name, joint,
                            math.degrees(values.min()), math.degrees(values.max()),
                            math.degrees(lo_lim), math.degrees(hi_lim))
            per_joint[joint] = clipped
        grids[finger.name] = per_joint
    return grids


def grid_joint_vectors(hand: Hand, finger: str, grid: Mapping[str, np.ndarray],
                       demo: DemoSeed | None) -> np.ndarray:
    """(B, nq) joint vectors of every combination of the finger's grid; other joints 0."""
    names = list(grid)
    mesh = np.meshgrid(*(grid[n] for n in names), indexing="ij")
    q = np.zeros((mesh[0].size, hand.nq))
    for name, values in zip(names, mesh, strict=True):
        q[:, hand.joint_names.index(name)] = values.ravel()
    cfg = hand.config.finger(finger)
    followers = [hand.joint_names.index(j) for j in cfg.coupled_to]
    if followers:
        filled = hand.fill_coupled(q)
        if demo is not None:
            offset = demo.joints - hand.fill_coupled(demo.joints)
            filled[:, followers] += offset[followers]
        q[:, followers] = filled[:, followers]
        q[:, followers] = np.clip(q[:, followers], hand.lower[followers], hand.upper[followers])
    return q
