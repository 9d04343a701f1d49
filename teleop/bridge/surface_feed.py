"""The object's surface for contact-aware retargeting, kept where the bridge's object is.

Why a mixin of its own: the retargeter snaps finger-pad targets onto the object
(:mod:`teleop.retarget.snap`), so it needs the object's surface in its own world (the bridge's
world minus ``world_offset_m``) at the pose the simulated object has *now* — the object drops,
settles, is reset, is lifted in free mode. :meth:`SurfaceFeed._attach_surface` builds the
surface when a scene is built (6–23 ms, once per object), and :meth:`SurfaceFeed._retarget`
moves it to the object's current pose before each frame is retargeted. The surface is part of
the scene state a failed ``choose_object`` restores, and the retargeter is always pointed at the
bridge's current surface.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from teleop.retarget.surface import ObjectSurface

if TYPE_CHECKING:
    from sim.world.objects import ObjectAsset
    from sim.world.scene import Scene
    from teleop.bridge.config import BridgeConfig
    from teleop.messages import HandFrame
    from teleop.retarget.result import RetargetResult
    from teleop.retarget.retargeter import Retargeter

__all__ = ["SurfaceFeed"]


class SurfaceFeed:
    """Mixin of :class:`teleop.bridge.bridge.Bridge` (the attributes annotated are the bridge's)."""

    scene: Scene
    config: BridgeConfig
    retargeter: Retargeter
    _surface: ObjectSurface

    def _attach_surface(self, obj: ObjectAsset) -> None:
        """The surface of the scene's new object (the retargeter takes it at the next frame)."""
        self._surface = ObjectSurface.from_object(obj)

    def _retarget(self, frame: HandFrame) -> RetargetResult:
        """``frame`` retargeted with the object's surface at its current simulated pose."""
        pos, quat = self.scene.object_pose()
        self._surface.set_pose(np.asarray(pos, float) - self.config.world_offset_m,
                               np.asarray(quat, float))
        if self.retargeter.surface is not self._surface:
            self.retargeter.set_object(self._surface)
        return self.retargeter.step_frame(frame)
