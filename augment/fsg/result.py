"""What FSG returns: one :class:`FsgGrasp` per generated grasp, gathered in an :class:`FsgResult`
with the run's counts (where candidates were rejected, which finger sets were tried).

Plain data, so that the dataset writer and the pipeline depend on these types only, not on the
sampler.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.grasp import Grasp

__all__ = ["FsgGrasp", "FsgResult"]


@dataclass(frozen=True, eq=False)
class FsgGrasp:
    """One generated grasp.

    Attributes:
        grasp: palm pose (frame_palm in the object frame, metres, wxyz) and full joint vector.
        fingers: fingers used, priority order.
        contact_points: (M,3) contacts on the object, object frame, metres.
        contact_normals: (M,3) the object's OUTWARD unit normals there (the GWS uses their
            negatives, the force directions).
        contact_finger: (M,) index into ``fingers`` of the finger touching each contact.
        ws_index: per used finger, the index of its workspace cloud point.
        face_index: per used finger, which contact face of the fingertip (into the finger
            cloud's ``tip_*`` arrays).
        epsilon, volume: GWS Q1 and hull volume of the contacts.
        worker: worker that generated it.
        grip_ratio: least total normal force that holds the caller's loads over the load's
            force (:meth:`sim.metrics.holding.HoldLoads.grip_ratio`; ``inf``: some load cannot
            be held by these contacts; NaN: no loads given).
        actuator_effort: least worst actuator effort, as a fraction of the force limits, that
            holds those loads at the placed grasp (:mod:`sim.validate.effort`; > 1: the
            actuators cannot; NaN: no effort score given).
    """

    grasp: Grasp
    fingers: tuple[str, ...]
    contact_points: np.ndarray
    contact_normals: np.ndarray
    contact_finger: np.ndarray
    ws_index: tuple[int, ...]
    face_index: tuple[int, ...]
    epsilon: float
    volume: float
    worker: int = 0
    grip_ratio: float = float("nan")
    actuator_effort: float = float("nan")


@dataclass
class FsgResult:
    """Grasps (sorted by ε, best first) plus what happened: ``requested`` vs ``len(grasps)``
    (``shortfall``), ``stopped`` ("done", "time budget"), wall time, and counts summed over
    workers: candidates and where they were rejected (palm, table, no_match, contacts, depth,
    link, epsilon, duplicate, penetration, effort: actuators too weak for the loads), accepted
    (``accepted_open`` of them without force closure), ``relaxed`` (workers whose closure filter
    was relaxed), and per finger the k-d tree pairs with opposed normals (``pairs_<finger>``) and
    those left after eq. 2 and the crossing rule (``usable_<finger>``). ``finger_sets`` lists the
    finger sets finger iteration went through. ``stopped`` is also ``"actuators too weak"``
    (:data:`augment.fsg.run.TOO_WEAK`) when the effort filter rejected every grasp found."""

    grasps: list[FsgGrasp]
    requested: int
    stopped: str
    elapsed_s: float
    stats: dict[str, int] = field(default_factory=dict)
    finger_sets: list[tuple[str, ...]] = field(default_factory=list)

    @property
    def closure_relaxed(self) -> bool:
        """Whether any worker relaxed the force-closure filter (:mod:`augment.fsg.run`)."""
        return self.stats.get("relaxed", 0) > 0

    @property
    def shortfall(self) -> int:
        return max(self.requested - len(self.grasps), 0)
