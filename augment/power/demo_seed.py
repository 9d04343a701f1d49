"""A power demo as the seed of the power-grasp generator: the person's posture and palm.

Why not FSG: a whole-hand wrap has the palm (or the inner phalanges) on the object, and FSG is
a fingertip (precision) sampler that by design refuses every palm pose whose palm box holds
object points (paper §4.2.1); measured on bridge-recorded wraps it finds no grasp at all
(``docs/decisions/2026-12-07-power-demos.md``). The power generator (:mod:`augment.power`)
closes the whole hand on the object in simulation, and a demo seeds it the way the paper's
demos seed AutoWS (§5.2: the demonstrated joint angles centre the search):

- **Posture.** The fingers approach in the person's posture opened part of the way toward the
  hand's open one (the least opening that clears the object at the placement,
  :data:`APPROACH_SHARES`) and close toward the person's posture carried ``overshoot`` of the
  way on to the hand's closed posture — the fingers that touched; the others toward where
  the person held them — so they stop on the surface in the person's shape, not the generic
  fist, and press a little, as the demo did.
- **Palm.** A share ``seed_share`` of the placements is the demo's own palm frame (object
  frame) turned about the object's centre of mass by up to ``seed_turn_deg`` about a random
  axis and shifted up to ``seed_shift_m``, then moved along the palm normal to the generator's
  standoff: the person's approach, varied. The rest are the generator's own placements over
  the object surface (palm against the surface, a random roll), which augment the approach.
- **Finger set.** A grasp is kept when the thumb and at least as many other fingers as the
  power demo rule needs (two) touch: never a thumbless grasp from a thumb wrap.

Units: metres, radians; quaternions wxyz; frames as :mod:`augment.power.placement`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from augment.power.placement import hand_gaps_m
from sim.demo import POWER, Demo
from sim.errors import DexaugError
from sim.hand.model import Hand
from sim.transforms import axis_angle_to_mat, mat_to_quat, quat_to_mat
from sim.world.scene import Scene

__all__ = ["APPROACH_SHARES", "PowerSeed", "SeedShare", "approach_postures", "place_seeded",
           "seeded_palm", "seeded_target"]

#: other fingers than the thumb a seeded grasp must touch with (the power demo rule's)
MIN_OTHER_FINGERS = 2


@dataclass(frozen=True, eq=False)
class PowerSeed:
    """What the power generator takes of a power demo (:class:`sim.demo.Demo`).

    Attributes:
        id: the demo's id (provenance).
        joints: (nq,) the person's posture, radians, model order.
        fingers: the fingers on the object in the demo (any link).
        palm_pos_m, palm_quat_wxyz: frame_palm in the object frame at the demo.
    """

    id: str
    joints: np.ndarray
    fingers: tuple[str, ...]
    palm_pos_m: np.ndarray
    palm_quat_wxyz: np.ndarray

    @classmethod
    def from_demo(cls, demo: Demo) -> PowerSeed:
        if demo.grasp_type != POWER:
            raise DexaugError(f"demo {demo.id}: a {demo.grasp_type} demo does not seed power "
                              f"grasps (FSG augments it)")
        return cls(demo.id, np.asarray(demo.joints, float), tuple(demo.fingers),
                   np.asarray(demo.palm_pos_m, float), np.asarray(demo.palm_quat_wxyz, float))


def seeded_target(hand: Hand, seed: PowerSeed, q_close: np.ndarray,
                  overshoot: float) -> np.ndarray:
    """The closing target for ``seed`` (module docstring): the person's posture, carried
    ``overshoot`` (0–1) of the way on toward ``q_close`` in the joints of the fingers that
    touched."""
    q = np.asarray(seed.joints, float)
    if q.shape != q_close.shape:
        raise DexaugError(f"demo {seed.id}: {len(q)} joints, hand {hand.name} has "
                          f"{len(q_close)}")
    names = list(hand.joint_names)
    target = q.copy()
    for finger in seed.fingers:
        idx = [names.index(j) for j in hand.config.finger(finger).joints]
        target[idx] = q[idx] + overshoot * (q_close[idx] - q[idx])
    return target


#: how far the approach postures open the person's posture toward the hand's open one, tried
#: in this order at each placement: the least opened that clears the object keeps the
#: person's shape; a wrap from above cannot be approached with the hand fully open (the
#: thumb, sticking out of the palm plane, holds the palm off the object)
APPROACH_SHARES = (0.25, 0.5, 1.0)


def approach_postures(seed: PowerSeed, q_open: np.ndarray) -> list[np.ndarray]:
    """The approach postures to try for ``seed`` (:data:`APPROACH_SHARES`), joints radians."""
    q = np.asarray(seed.joints, float)
    return [q + s * (q_open - q) for s in APPROACH_SHARES]


def seeded_palm(rng: np.random.Generator, seed: PowerSeed, centre_m: np.ndarray,
                turn_deg: float, shift_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(point, outward normal, palm quaternion) for :func:`augment.power.placement.place_palm`:
    the demo's palm frame turned about ``centre_m`` (the object's centre of mass, object frame)
    by an angle up to ``turn_deg`` about a random axis and shifted by up to ``shift_m``; the
    point is that palm origin and the normal its palm normal reversed (frame_palm +y faces the
    object), so the placement slides the hand back along it to the standoff."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    rot = axis_angle_to_mat(axis[None], np.array([math.radians(rng.uniform(0.0, turn_deg))]))[0]
    shift = rng.normal(size=3)
    shift *= rng.uniform(0.0, shift_m) / max(float(np.linalg.norm(shift)), 1e-12)
    palm_rot = rot @ quat_to_mat(seed.palm_quat_wxyz)
    point = centre_m + rot @ (seed.palm_pos_m - centre_m) + shift
    return point, -palm_rot[:, 1], mat_to_quat(palm_rot)


#: how far (metres) :func:`place_seeded` backs the palm off the demo's pose, in this order
_BACK_OFF_M = (0.0, 0.0025, 0.005, 0.01, 0.015)


def place_seeded(scene: Scene, point: np.ndarray, normal: np.ndarray, quat: np.ndarray,
                 approaches: list[np.ndarray], standoff_m: float
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """(palm position, approach posture) for a placement from :func:`seeded_palm`: the palm
    where the person had it (``point``) or backed off along ``normal`` by the least of
    :data:`_BACK_OFF_M`, in the first of ``approaches`` that keeps the whole hand
    ``standoff_m`` clear of the object there; None when none does. Why not the generator's
    own placement (open hand slid back to the standoff, palm then within ``max_palm_gap_m``):
    the demo already says where the palm lies, on the object, and a wrap over a rim or from
    above cannot be approached with the hand fully open."""
    for back in _BACK_OFF_M:
        pos = point + back * normal
        for q in approaches:
            if hand_gaps_m(scene, pos, quat, q)[1] >= standoff_m:
                return pos, q
    return None


class SeedShare:
    """Which kind of placement to try next, the demo's palm varied or a surface point: at
    first ``share`` of them the demo's, then shifted toward the kind whose closings touch with
    the thumb and enough fingers more often (each kind's rate with one success and one
    failure assumed). Why: a demo's approach varied works on some objects (a box wrapped from
    its side: 7 of 10 closings) and not on others (a can's rim wrapped from above: none of
    10), and a closing costs a simulation; the surface placements keep the search going."""

    def __init__(self, share: float) -> None:
        self.share = share
        self.tries = {True: 0, False: 0}
        self.hits = {True: 0, False: 0}

    def rate(self, seeded: bool) -> float:
        return (self.hits[seeded] + 1) / (self.tries[seeded] + 2)

    def pick(self, rng: np.random.Generator) -> bool:
        """True: try the demo's palm next."""
        w_seed, w_surf = self.share * self.rate(True), (1 - self.share) * self.rate(False)
        return bool(rng.uniform() * (w_seed + w_surf) < w_seed) if w_seed + w_surf > 0 else False

    def record(self, seeded: bool, hit: bool) -> None:
        self.tries[seeded] += 1
        self.hits[seeded] += hit
