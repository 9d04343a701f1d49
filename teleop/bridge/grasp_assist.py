"""Grasp assist: once the thumb and a finger touch the object, the fingers near it squeeze
(:class:`GraspAssist`), and whether the grasp is stable enough to mark (:class:`GraspCue`).

Why. Contact-aware retargeting puts the robot's pad targets *on* the object's surface
(:mod:`teleop.retarget.snap`): an operator pressing into the virtual object, which nothing
stops, means "touch it". But a position-servoed finger aimed exactly at the surface pushes with
~0 N, so a grasp that touches everywhere still slips as soon as it is lifted — the operator has
no touch feedback to squeeze harder, as they would on a real object. Once the hand's lead finger
(the thumb) and one more finger have touched ``engage_s`` ago (simulated seconds since the
grasp began, :attr:`GraspCue.grasp_s`; losses up to the cue's ``max_gap_s`` do not end it, as
a light touch flickers), the assist ramps,
over ``ramp_s``, a press of ``press_m`` metres *into* the object onto every pad target the
retargeter snaps (the pads within its snap range; fingers away from the object are untouched).
The servos then push with about gain × press / lever (≈ 2–3 N per Shadow fingertip at 1 cm).
It lets go, ramping down, once the grasp has been gone (the cue's ``max_gap_s``) for a further
``release_s``; opening the hand takes the pads out of snap range, which ends the press anyway.

The cue. :class:`GraspCue` says whether the grasp meets what demo extraction needs for a
stable grasp (the lead finger and ``min_fingers − 1`` others in contact for ``min_duration_s``,
:class:`teleop.record.demos.DemoParams`), so the page can tell the operator "stable — mark it".

The press makes contact; the force that holds a heavy object comes from the squeeze that
ramps in with it (:mod:`teleop.bridge.grasp_squeeze`: the validator's grip, sized by the
object's weight, on the joint targets; ``squeeze`` False leaves the press alone).

Times are the simulation's (seconds), so a deterministic replay assists exactly as the live
session did. ``press_m`` 0 switches the assist off (the cue stays).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

from teleop.record.demos import DemoParams

__all__ = ["AssistSettings", "GraspAssist", "GraspCue"]


@dataclass(frozen=True)
class AssistSettings:
    """``[bridge]`` ``assist_*`` keys (module docstring): press_m metres, the rest seconds."""

    press_m: float = 0.01
    engage_s: float = 0.05
    ramp_s: float = 0.15
    release_s: float = 0.2
    #: with the press, the validator's force-sized squeeze on the joint targets
    #: (:mod:`teleop.bridge.grasp_squeeze`), ramped by the same level
    squeeze: bool = True


class GraspAssist:
    """The assist's state: :meth:`update` with how long the grasp has held (the cue's) at a
    simulated time gives the press (metres) to put on the snapped pad targets."""

    def __init__(self, settings: AssistSettings) -> None:
        self.settings = settings
        self.engaged = False
        self.level = 0.0          # 0 … 1, the fraction of press_m applied
        self._last_t: float | None = None
        self._off_since: float | None = None

    def update(self, t_s: float, held_s: float) -> float:
        """The press (metres) at simulated time ``t_s``, the grasp having held for ``held_s``
        (seconds; 0: no grasp, :meth:`GraspCue.update`); True in :attr:`engaged` while
        squeezing."""
        s = self.settings
        if s.press_m <= 0.0:
            return 0.0
        dt = 0.0 if self._last_t is None else max(t_s - self._last_t, 0.0)
        self._last_t = t_s
        was = self.engaged
        if held_s >= s.engage_s:
            self.engaged, self._off_since = True, None
        elif self.engaged and held_s <= 0.0:
            self._off_since = t_s if self._off_since is None else self._off_since
            if t_s - self._off_since >= s.release_s:
                self.engaged, self._off_since = False, None
        if self.engaged != was:   # the ramp starts now
            dt = 0.0
        rate = dt / s.ramp_s if s.ramp_s > 0.0 else 1.0
        self.level = min(1.0, self.level + rate) if self.engaged else max(0.0, self.level - rate)
        return self.level * s.press_m


class GraspCue:
    """Whether the grasp is stable enough to mark: the lead finger and ``min_fingers − 1``
    others *in contact* for ``min_duration_s`` in all, breaks of at most ``max_gap_s`` allowed
    but not counted (:class:`teleop.record.demos.DemoParams`, the demo extraction's rule).

    Why time in contact and not time since the first touch: a fingertip resting on the object
    touches and leaves it from step to step, and counting through the gaps called a grasp of
    0.06 s of real contact "stable" (10 of 52 real runs whose longest contact was 0.01–0.12 s).
    A gap longer than ``max_gap_s`` ends the grasp: the count starts again."""

    def __init__(self, lead_finger: str, params: DemoParams | None = None) -> None:
        self.lead = lead_finger
        self.params = params or DemoParams()
        self._held_s = 0.0
        self._start: float | None = None
        self._last_ok: float | None = None
        self._prev: tuple[float, bool] | None = None   # the previous update's time, its ok
        #: seconds since the current grasp began, gaps included (0: none) — what the assist
        #: engages on: a person lifts 0.12–0.64 s after first contact, so the squeeze must
        #: start at the first firm touch; engaged on contact time alone, it came later and
        #: the human-timed benchmark lifted 11 of 34 instead of 13
        self.grasp_s = 0.0

    def update(self, t_s: float, touching: Collection[str]) -> tuple[bool, float]:
        """(stable, held_s): whether the grasp has been in contact long enough at ``t_s`` and
        for how long (seconds of contact, gaps not counted; 0 when not grasping)."""
        p = self.params
        ok = self.lead in touching and len(set(touching) - {self.lead}) >= p.min_fingers - 1
        if self._last_ok is None or t_s - self._last_ok > p.max_gap_s:
            self._held_s, self._start = 0.0, None   # no grasp, or the last one ended
        elif ok and self._prev is not None and self._prev[1]:
            self._held_s += max(t_s - self._prev[0], 0.0)
        if ok:
            self._last_ok = t_s
            self._start = t_s if self._start is None else self._start
        self._prev = (t_s, ok)
        self.grasp_s = 0.0 if self._start is None else t_s - self._start
        return self._held_s >= p.min_duration_s, self._held_s
