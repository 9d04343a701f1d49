"""The retargeter's output low-pass filter on the joint vector (:class:`JointFilter`).

Why after the IK and not on the targets: the IK is warm-started and converges over frames, so
filtering its output smooths both tracking noise and the solver's own steps; coupling and
joint limits are re-applied exactly afterwards, so the filtered vector is always a valid
command. Radians, seconds.
"""

from __future__ import annotations

import math

import numpy as np

from sim.hand.model import Hand
from teleop.retarget.config import RetargetConfig

__all__ = ["JointFilter"]

Array = np.ndarray


class JointFilter:
    """y += α (x − y), with α = 1 − exp(−Δt/τ) from the frames' timestamps
    (``filter_time_constant_s``; ``dt_s`` when a frame has no usable time) or the fixed
    ``filter_alpha``; the first frame passes through. Coupling and limits of ``hand`` are then
    applied exactly."""

    def __init__(self, hand: Hand, config: RetargetConfig) -> None:
        self.hand = hand
        self.config = config
        self.reset()

    def reset(self) -> None:
        self.q: Array | None = None
        self.last_time_s: float | None = None

    def __call__(self, q_in: Array, time_s: float | None) -> Array:
        cfg = self.config
        if self.q is None:
            q = q_in
        else:
            if cfg.filter_alpha is not None:
                alpha = cfg.filter_alpha
            else:
                tau = cfg.filter_time_constant_s or 0.0
                last = self.last_time_s
                dt = (time_s - last if time_s is not None and last is not None and time_s > last
                      else cfg.dt_s)
                alpha = 1.0 if tau <= 0.0 else 1.0 - math.exp(-dt / tau)
            q = self.q + alpha * (q_in - self.q)
        q = self.hand.fill_coupled(self.hand.clip(q))
        self.q = q
        if time_s is not None:
            self.last_time_s = time_s
        return q
