"""What extraction can say about a demonstration beyond "it touched": where the table was, and
whether the grasp is one worth augmenting.

A demo carries the plane its object rested on, in the object frame, so that its augmentation
keeps palm and fingertips above the table (DESIGN §6); the session records the table in the
world (``table`` metadata: top height, centre, half extents) and the object's pose is known at
the grasp moment. Two quality flags a user should see before augmenting (issue: real operators'
"fragments" of whole-hand wraps augment at a median 8 %):

- **slipped**: in the free-object mode the object must stay in the hand while the grasp lasts;
  one that moves more than ``max_slip_m`` or turns more than ``max_turn_rad`` in the palm after
  the grasp moment was not held;
- **fragment**: only a few fingertips touch while other fingers of the hand are closed as if
  wrapping the object: the contacts are a fragment of a larger grasp.

Units: metres, radians.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sim.hand.model import Hand
from sim.transforms import pose_inv, pose_mul, quat_angle, rotate

__all__ = ["FRAGMENT_CLOSURE", "MAX_SLIP_M", "MAX_TURN_RAD", "fragment_flag", "slip_flag",
           "table_in_object_frame"]

MAX_SLIP_M = 0.02
MAX_TURN_RAD = float(np.deg2rad(15.0))
#: a finger counts as closed when its joints are on average this far from open to their limit
FRAGMENT_CLOSURE = 0.5


def table_in_object_frame(table: Any, obj_pos: np.ndarray,
                          obj_quat: np.ndarray) -> dict[str, np.ndarray] | None:
    """The session's table (``{"top_z_m", "center_m", ...}`` in the world, z up) as the
    demo's plane in the object frame (``{"point_m", "normal"}``), or None without one."""
    if not isinstance(table, Mapping) or "top_z_m" not in table:
        return None
    centre = np.asarray(table.get("center_m", (0.0, 0.0)), float)
    point_w = np.array([centre[0], centre[1], float(table["top_z_m"])])
    inv_p, inv_q = pose_inv(np.asarray(obj_pos, float), np.asarray(obj_quat, float))
    return {"point_m": inv_p + rotate(inv_q, point_w),
            "normal": rotate(inv_q, np.array([0.0, 0.0, 1.0]))}


def _object_in_palm(state: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    inv_p, inv_q = pose_inv(np.asarray(state["palm_pos_m"], float),
                            np.asarray(state["palm_quat_wxyz"], float))
    return pose_mul(inv_p, inv_q, np.asarray(state["object_pos_m"], float),
                    np.asarray(state["object_quat_wxyz"], float))


def slip_flag(states: Sequence[Mapping[str, Any]]) -> str | None:
    """``states`` from the grasp moment to the end of its contact run: a flag when the object
    moved or turned in the palm past the limits, else None."""
    if len(states) < 2:
        return None
    p0, q0 = _object_in_palm(states[0])
    worst_m, worst_rad = 0.0, 0.0
    for s in states[1:]:
        p, q = _object_in_palm(s)
        worst_m = max(worst_m, float(np.linalg.norm(p - p0)))
        worst_rad = max(worst_rad, float(quat_angle(q, q0)))
    if worst_m > MAX_SLIP_M or worst_rad > MAX_TURN_RAD:
        return (f"slipped: the object moved {worst_m * 1e3:.0f} mm and turned "
                f"{np.degrees(worst_rad):.0f}° in the hand during the grasp")
    return None


def fragment_flag(hand: Hand, q: np.ndarray, touching: Sequence[str]) -> str | None:
    """A flag when fingers that do not touch are closed (``FRAGMENT_CLOSURE`` of their range)
    and outnumber those that do beyond the first two: the demo is a fragment of a wrap."""
    closed = []
    for f in hand.config.fingers:
        if f.name in touching:
            continue
        idx = hand.finger_qadr[f.name]
        # open is 0 (or the lower limit when that is above 0), closed the upper limit
        lo, hi = np.maximum(hand.lower[idx], 0.0), hand.upper[idx]
        span = np.where(np.isfinite(hi) & (hi - lo > 1e-6), hi - lo, np.inf)
        if float(np.mean(np.clip((q[idx] - lo) / span, 0.0, 1.0))) >= FRAGMENT_CLOSURE:
            closed.append(f.name)
    if len(closed) >= max(len(touching) - 1, 2):
        return (f"fragment: only {', '.join(touching)} touch while {', '.join(closed)} are "
                f"closed around nothing")
    return None
