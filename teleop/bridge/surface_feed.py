"""What the retargeter takes from the scene each frame: the object's surface, kept where the
bridge's object is, and the grasp assist's press (:mod:`teleop.bridge.grasp_assist`).

Why a mixin of its own: the retargeter snaps finger-pad targets onto the object
(:mod:`teleop.retarget.snap`), so it needs the object's surface in its own world (the bridge's
world minus ``world_offset_m``) at the pose the simulated object has *now* — the object drops,
settles, is reset, is lifted in free mode. :meth:`SurfaceFeed._attach_surface` builds the
surface when a scene is built (6–23 ms, once per object), and :meth:`SurfaceFeed._retarget`
moves it to the object's current pose before each frame is retargeted, together with where the
simulated hand's base is (snapped pad targets are solved in its frame). The surface is part of
the scene state a failed ``choose_object`` restores, and the retargeter is always pointed at the
bridge's current surface.

The fingers touching the object in the last published state drive the grasp assist (the press
put on the snapped pad targets, and the squeeze planned when it engages:
:mod:`teleop.bridge.grasp_squeeze`) and the page's cue (:attr:`SurfaceFeed.grasp_state`: stable,
how long held, assist level), both started afresh with each new scene.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from teleop.bridge.grasp_assist import GraspAssist, GraspCue
from teleop.bridge.grasp_squeeze import GraspSqueeze
from teleop.retarget.surface import ObjectSurface

if TYPE_CHECKING:
    from sim.world.objects import ObjectAsset
    from sim.world.scene import Scene
    from teleop.bridge.config import BridgeConfig
    from teleop.messages import HandFrame
    from teleop.record.contact_record import ContactRecord
    from teleop.retarget.result import RetargetResult
    from teleop.retarget.retargeter import Retargeter

__all__ = ["SurfaceFeed"]


class SurfaceFeed:
    """Mixin of :class:`teleop.bridge.bridge.Bridge` (the attributes annotated are the bridge's)."""

    scene: Scene
    config: BridgeConfig
    retargeter: Retargeter
    if TYPE_CHECKING:   # the host's read-only property (Bridge.sim_time_s), typed for this mixin
        @property
        def sim_time_s(self) -> float: ...
    _last_contacts: list[ContactRecord]
    _surface: ObjectSurface
    _assist: GraspAssist
    _squeeze: GraspSqueeze
    _cue: GraspCue
    _q_target: np.ndarray | None
    #: For /state and the recording: {"grasp_stable": bool, "grasp_held_s": s, "assist": 0…1,
    #: "grip_n": the planned squeeze's total normal force, N (0: none)}.
    grasp_state: dict[str, float | bool]

    def _attach_surface(self, obj: ObjectAsset) -> None:
        """The surface of the scene's new object (the retargeter takes it at the next frame),
        and the assist and cue started afresh."""
        self._surface = ObjectSurface.from_object(obj)
        lead = self.scene.hand.finger_names[0]
        self._assist = GraspAssist(self.config.assist)
        self._squeeze = GraspSqueeze(self.scene.hand, obj, self.config.assist.squeeze)
        self._cue = GraspCue(lead)
        self.retargeter.press_m = 0.0
        self.grasp_state = {"grasp_stable": False, "grasp_held_s": 0.0, "assist": 0.0,
                            "grip_n": 0.0}

    def _retarget(self, frame: HandFrame) -> RetargetResult:
        """``frame`` retargeted with the object's surface at its current simulated pose."""
        pos, quat = self.scene.object_pose()
        self._surface.set_pose(np.asarray(pos, float) - self.config.world_offset_m,
                               np.asarray(quat, float))
        if self.retargeter.surface is not self._surface:
            self.retargeter.set_object(self._surface)
        t_s = self.sim_time_s
        touching = {c.finger for c in self._last_contacts if c.finger}
        stable, held_s = self._cue.update(t_s, touching)
        self.retargeter.press_m = self._assist.update(t_s, self._cue.grasp_s)
        if self._assist.engaged and not self._squeeze.planned:
            q = self._q_target if self._q_target is not None else self.scene.hand.open_pose
            self._squeeze.plan(self.scene, q)
        elif not self._assist.engaged and self._assist.level <= 0.0:
            self._squeeze.reset()
        self.grasp_state = {"grasp_stable": stable, "grasp_held_s": round(held_s, 3),
                            "assist": round(self._assist.level, 3),
                            "grip_n": round(self._squeeze.grip_n, 2)}
        base_p, base_q = self.scene.base_world_pose()
        sim_base = (base_p - self.config.world_offset_m, base_q)
        return self.retargeter.step_frame(frame, sim_base)
