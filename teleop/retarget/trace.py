"""Offline retargeting: a whole recording through a :class:`Retargeter`
(:func:`retarget_frames` → :class:`RetargetTrace`) and its error and latency statistics
(:func:`summarise_errors`, what ``dexaug retarget FILE`` reports).

Units: metres, seconds, radians; quaternions wxyz.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict

import numpy as np

from teleop.messages import HandFrame
from teleop.retarget.result import RetargetResult
from teleop.retarget.retargeter import Retargeter

__all__ = ["FingerErrors", "RetargetSummary", "RetargetTrace", "retarget_frames", "summarise_errors"]

Array = np.ndarray


@dataclass(frozen=True)
class RetargetTrace:
    """:func:`retarget_frames` over a recording: per-frame arrays, first axis = frame.

    step_time_s is the wall time of each :meth:`Retargeter.step` call (seconds)."""

    finger_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    t_s: Array
    q: Array
    base_pos_m: Array
    base_quat_wxyz: Array
    palm_pos_m: Array
    palm_quat_wxyz: Array
    tip_targets_m: Array
    tip_positions_m: Array
    tip_errors_m: Array
    held: Array
    step_time_s: Array

    def as_dict(self) -> dict[str, Array]:
        """Plain arrays (for ``np.savez``)."""
        return {k: np.asarray(v) for k, v in self.__dict__.items()}


def retarget_frames(retargeter: Retargeter, frames: Sequence[HandFrame]) -> RetargetTrace:
    """Run ``retargeter`` over a recording (in order, from its current state) and stack the
    results; the per-step wall time is recorded for latency statistics."""
    results: list[RetargetResult] = []
    times = np.empty(len(frames))
    for i, frame in enumerate(frames):
        t0 = time.perf_counter()
        results.append(retargeter.step_frame(frame))
        times[i] = time.perf_counter() - t0
    nf = len(retargeter.finger_names)

    def stack(name: str, shape: tuple[int, ...]) -> Array:
        if not results:
            return np.empty((0, *shape))
        return np.stack([getattr(r, name) for r in results])

    return RetargetTrace(
        finger_names=retargeter.finger_names, joint_names=retargeter.hand.joint_names,
        t_s=np.array([f.device_time_s for f in frames], dtype=float),
        q=stack("q", (retargeter.hand.nq,)), base_pos_m=stack("base_pos_m", (3,)),
        base_quat_wxyz=stack("base_quat_wxyz", (4,)), palm_pos_m=stack("palm_pos_m", (3,)),
        palm_quat_wxyz=stack("palm_quat_wxyz", (4,)),
        tip_targets_m=stack("tip_targets_m", (nf, 3)),
        tip_positions_m=stack("tip_positions_m", (nf, 3)),
        tip_errors_m=stack("tip_errors_m", (nf,)),
        held=np.array([r.held for r in results], dtype=bool), step_time_s=times)


class FingerErrors(TypedDict):
    """One finger's fingertip error over the live frames, metres (NaN when none was live)."""

    median_m: float
    p95_m: float
    max_m: float


class RetargetSummary(TypedDict):
    """What :func:`summarise_errors` returns and ``dexaug retarget`` prints: typed because it
    crosses from ``teleop`` to the CLI and the tests read its keys."""

    frames: int
    held: int
    fingers: dict[str, FingerErrors]
    step_median_s: float
    step_p99_s: float


def summarise_errors(trace: RetargetTrace) -> RetargetSummary:
    """Fingertip error statistics (metres) per finger over the frames not held, plus frame
    counts and per-step latency (seconds): what ``dexaug retarget FILE`` reports."""
    live = ~trace.held
    err = trace.tip_errors_m[live]
    per_finger: dict[str, FingerErrors] = {}
    for k, name in enumerate(trace.finger_names):
        e = err[:, k] if len(err) else np.empty(0)
        per_finger[name] = ({"median_m": float(np.median(e)), "p95_m": float(np.percentile(e, 95)),
                             "max_m": float(e.max())} if len(e) else
                            {"median_m": math.nan, "p95_m": math.nan, "max_m": math.nan})
    st = trace.step_time_s[live]
    return {
        "frames": len(trace.held), "held": int(trace.held.sum()),
        "fingers": per_finger,
        "step_median_s": float(np.median(st)) if len(st) else math.nan,
        "step_p99_s": float(np.percentile(st, 99)) if len(st) else math.nan,
    }
