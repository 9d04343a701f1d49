"""The operator's tracked hand smoothed before retargeting: a One-Euro filter
(:class:`OneEuro`; Casiez, Roussel & Vogel, CHI 2012) on the wrist pose and on the hand's shape
(:class:`HandInputFilter`).

Why. Hand tracking is noisy at the millimetre level frame to frame (the synthetic operator's
sensor: 2.5 mm per joint per axis and 2° per joint; ``configs/teleop.toml`` ``[synth]``). Through
the retargeter that noise becomes pad targets jumping a few millimetres every frame, and a
position-servoed robot finger resting on an object then touches and leaves it from one physics
step to the next: on three natural-speed grasps the set of fingers in contact changed at 28–30
of 36 states after the grasp moment with the noise and at 0–13 without it
(``benchmarks/bench_teleop_loop.py``, docs/teleoperation.md, "Grasping at human speed"). A fixed low-pass
filter strong enough to remove that jitter lags a 0.3 s human closure; the One-Euro filter's
cutoff rises with the signal's speed (fc = min_cutoff + beta · |ẋ|), so a still hand is smoothed
hard and a moving one barely delayed.

What is filtered. The wrist position and orientation (the hand's pose in the world) and every
joint position *in the wrist frame* (the hand's shape), each with its own speed, so a fast reach
does not open the fingers' filter and a fast closure does not open the wrist's. Joint
orientations pass through (the retargeter only uses them to find the pad side of a fingertip).
A gap in time longer than ``reset_gap_s`` (tracking lost) restarts the filter at the next
sample, as does an invalid joint for that joint.

Units: metres, seconds, Hz; ``beta`` in Hz per m/s (positions) or Hz per rad/s (orientation).
Quaternions wxyz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sim.transforms import quat_to_mat1
from teleop.messages import WRIST, HandState

__all__ = ["HandInputFilter", "InputFilterSettings", "OneEuro"]

Array = np.ndarray


def _alpha(cutoff_hz: Array | float, dt_s: float) -> Array:
    """Exponential smoothing factor of a first-order low-pass at ``cutoff_hz`` for step dt."""
    tau = 1.0 / (2.0 * math.pi * np.asarray(cutoff_hz, float))
    return 1.0 / (1.0 + tau / dt_s)


class OneEuro:
    """One-Euro filter over rows of a (n, k) array: each row is one signal whose speed is the
    norm of its derivative (a 3-D point moves as one). Rows with ``valid`` False keep their
    state and are restarted when they come back."""

    def __init__(self, min_cutoff_hz: float, beta: float, d_cutoff_hz: float) -> None:
        self.min_cutoff_hz, self.beta, self.d_cutoff_hz = min_cutoff_hz, beta, d_cutoff_hz
        self.x: Array | None = None
        self.dx: Array | None = None
        self.fresh: Array | None = None

    def reset(self) -> None:
        self.x = self.dx = self.fresh = None

    def __call__(self, x: Array, dt_s: float, valid: Array | None = None) -> Array:
        x = np.asarray(x, float)
        ok = np.ones(len(x), bool) if valid is None else np.asarray(valid, bool)
        if self.x is None or self.dx is None or self.fresh is None or dt_s <= 0.0:
            self.x, self.dx = x.copy(), np.zeros_like(x)
            self.fresh = ~ok
            return x.copy()
        restart = ok & self.fresh
        dx = (x - self.x) / dt_s
        a_d = _alpha(self.d_cutoff_hz, dt_s)
        dx_hat = self.dx + a_d * (dx - self.dx)
        cutoff = self.min_cutoff_hz + self.beta * np.linalg.norm(dx_hat, axis=1)
        a = _alpha(cutoff, dt_s)[:, None]
        out = self.x + a * (x - self.x)
        out[restart] = x[restart]
        dx_hat[restart] = 0.0
        self.x = np.where(ok[:, None], out, self.x)
        self.dx = np.where(ok[:, None], dx_hat, self.dx)
        self.fresh = self.fresh & ~ok
        return self.x.copy()


@dataclass(frozen=True)
class InputFilterSettings:
    """``[retarget]`` ``input_*`` keys: cutoffs (Hz) and speed gains of the position filters
    (Hz per m/s) and of the wrist orientation filter (Hz per rad/s); ``min_cutoff_hz`` 0 turns
    filtering off."""

    min_cutoff_hz: float = 1.5
    beta: float = 30.0
    d_cutoff_hz: float = 1.0
    beta_rotation: float = 2.0
    reset_gap_s: float = 0.2


class HandInputFilter:
    """A tracked :class:`HandState` in, the same hand with its wrist pose and joint positions
    One-Euro filtered out (module docstring). Stateful: feed samples in time order."""

    def __init__(self, settings: InputFilterSettings) -> None:
        s = settings
        self.settings = s
        self._wrist = OneEuro(s.min_cutoff_hz, s.beta, s.d_cutoff_hz)
        # a unit quaternion moves at half the angular speed: beta per rad/s, doubled
        self._rot = OneEuro(s.min_cutoff_hz, 2.0 * s.beta_rotation, s.d_cutoff_hz)
        self._shape = OneEuro(s.min_cutoff_hz, s.beta, s.d_cutoff_hz)
        self._last_t: float | None = None
        self._last_q: Array | None = None

    @property
    def enabled(self) -> bool:
        return self.settings.min_cutoff_hz > 0.0

    def reset(self) -> None:
        for f in (self._wrist, self._rot, self._shape):
            f.reset()
        self._last_t = self._last_q = None

    def __call__(self, hand: HandState, time_s: float | None) -> HandState:
        """``hand`` (tracked, wrist valid) filtered at device time ``time_s`` (None: no
        timing, the sample passes unfiltered and restarts the filter)."""
        if not self.enabled:
            return hand
        if time_s is None or self._last_t is None or not (
                0.0 < time_s - self._last_t <= self.settings.reset_gap_s):
            self.reset()
        dt = 0.0 if self._last_t is None or time_s is None else time_s - self._last_t
        self._last_t = time_s
        pos, quats = hand.positions, hand.orientations_wxyz
        q_w = quats[WRIST] / np.linalg.norm(quats[WRIST])
        if self._last_q is not None and float(q_w @ self._last_q) < 0.0:
            q_w = -q_w                      # the same rotation, on the filter's side
        r_w = quat_to_mat1(q_w)
        shape = (pos - pos[WRIST]) @ r_w
        p_f = self._wrist(pos[WRIST][None], dt)[0]
        q_f = self._rot(q_w[None], dt)[0]
        q_f /= np.linalg.norm(q_f)
        self._last_q = q_f
        shape_f = self._shape(shape, dt, hand.valid)
        positions = np.where(hand.valid[:, None], p_f + shape_f @ quat_to_mat1(q_f).T, pos)
        positions[WRIST] = p_f
        orientations = quats.copy()
        orientations[WRIST] = q_f
        return replace(hand, positions=positions, orientations_wxyz=orientations)
