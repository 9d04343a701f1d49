"""What AutoWS takes of a grasp demonstration (:class:`DemoSeed`), and its check against a hand.

A demo centres the joint grids on its own joint angles (:mod:`augment.autows.grids`) and grows
each fingertip's contact face at the demo's contact centroid on that fingertip
(:mod:`augment.autows.fingertip`); its id, joints and contacts enter the cache key.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from augment.autows.params import WorkspaceError
from sim.demo import Demo

if TYPE_CHECKING:
    from sim.hand.model import Hand

__all__ = ["DemoSeed", "check_demo"]


@dataclass(frozen=True, eq=False)
class DemoSeed:
    """What AutoWS needs of a grasp demonstration.

    Attributes:
        joints: (nq,) the full hand joint vector at the grasp moment, radians (model order).
        contacts: finger name → (3,) centroid of that fingertip's contact points in its tip
            BODY frame, metres, or ``None`` when the finger did not touch (its face is then grown
            at the pulp cloud centroid). Fingers not named count as ``None``.
        id: identifier of the demonstration (provenance, cache key).
    """

    joints: np.ndarray
    contacts: Mapping[str, np.ndarray | None]
    id: str

    def __post_init__(self) -> None:
        q = np.array(self.joints, dtype=float)
        if q.ndim != 1 or not np.isfinite(q).all():
            raise WorkspaceError(f"demo {self.id!r}: joints must be a finite 1-D vector "
                                 f"(radians), got shape {q.shape}")
        q.flags.writeable = False
        object.__setattr__(self, "joints", q)
        contacts: dict[str, np.ndarray | None] = {}
        for finger, point in dict(self.contacts).items():
            if point is None:
                contacts[str(finger)] = None
                continue
            c = np.array(point, dtype=float)
            if c.shape != (3,) or not np.isfinite(c).all():
                raise WorkspaceError(f"demo {self.id!r}: contact of finger {finger!r} must be a "
                                     f"finite 3-vector in its tip frame (metres), got {point!r}")
            c.flags.writeable = False
            contacts[str(finger)] = c
        object.__setattr__(self, "contacts", contacts)

    @classmethod
    def from_demo(cls, demo: Demo) -> DemoSeed:
        """The seed of a demonstration: its joints and per-finger tip-frame contact centroids."""
        return cls(demo.joints, dict(demo.tip_contacts), demo.id)

    def contact(self, finger: str) -> np.ndarray | None:
        return self.contacts.get(finger)


def check_demo(hand: Hand, demo: DemoSeed) -> None:
    """Raise :class:`WorkspaceError` when ``demo`` does not fit ``hand`` (joint count, or
    contacts named for fingers the hand does not have)."""
    if demo.joints.shape != (hand.nq,):
        raise WorkspaceError(f"demo {demo.id!r}: {demo.joints.shape[0]} joint values, hand "
                             f"{hand.name!r} has {hand.nq} ({', '.join(hand.joint_names)})")
    unknown = sorted(set(demo.contacts) - set(hand.finger_names))
    if unknown:
        raise WorkspaceError(f"demo {demo.id!r}: contacts for unknown finger(s) {unknown}; "
                             f"hand {hand.name!r} has {list(hand.finger_names)}")
