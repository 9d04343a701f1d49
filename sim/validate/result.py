"""What a validation returns: the verdict, why it failed, and what was measured on the way.

Kept apart from the validator so that code that only stores or reports results (the dataset,
the batch runner, the dashboard) needs no simulation. Units: metres, radians.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import StrEnum

import numpy as np

__all__ = ["Failure", "PhaseResult", "ValidationResult"]


class Failure(StrEnum):
    """Why a grasp failed, checked in this order."""

    PENETRATION = "penetration"        # hand into object or itself above the limit before simulating
    NO_CONTACT = "no_contact"          # no hand body near the object: a grasp on air
    LOST_CONTACT = "lost_contact"      # fingers closed but nothing touches the object
    SLIPPED = "slipped"                # object moved/rotated past the limits while lifted or pushed
    STUCK = "stuck"                    # lift-drop: object stayed in the opened hand (interpenetration)


@dataclass
class PhaseResult:
    passed: bool
    displacement_m: float
    rotation_rad: float


@dataclass
class ValidationResult:
    """Outcome of one grasp under one protocol. Metrics are NaN where the run stopped before
    they could be measured (e.g. penetration rejects before simulating)."""

    protocol: str
    passed: bool
    failure: str | None
    penetration_m: float
    n_contacts: int = 0
    epsilon: float = float("nan")
    volume: float = float("nan")
    displacement_m: float = float("nan")
    rotation_rad: float = float("nan")
    phases: dict[str, PhaseResult] = field(default_factory=dict)
    #: how the fingers closed: "free" or "pinned" (the object held still while closing)
    closing: str | None = None
    #: how pregrasp and squeeze were made ("given", "dexaug", "bodex", "dgb-rule")
    squeeze_convention: str | None = None
    #: the joint vectors closed from and to (radians, full hand vectors), when simulated
    pregrasp: np.ndarray | None = None
    squeeze: np.ndarray | None = None
    #: dgb only: the grasp stage closed through between them (sim.validate.stages)
    touch: np.ndarray | None = None
    #: where an early exit stopped the simulation once the verdict could no longer change (the
    #: protocol's ``early_exit``), e.g. six-dir's "after push +x: slipped"; None:
    #: simulated to the protocol's end. Verdict and failure are those of the full run; what the
    #: rest would have measured (the final or worst drift: ``displacement_m``, ``rotation_rad``)
    #: is NaN, the phase that stopped keeps the drift measured where it stopped, and the phases
    #: after it are absent.
    stopped_early: str | None = None
    contact_pos_obj: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    contact_normal_obj: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def summary(self) -> dict[str, object]:
        """Flat, JSON-friendly view (no arrays) for tables and logs."""
        out = asdict(self)
        for key in ("contact_pos_obj", "contact_normal_obj", "pregrasp", "squeeze", "touch"):
            out.pop(key)
        out["phases"] = {k: asdict(v) for k, v in self.phases.items()}
        return out
