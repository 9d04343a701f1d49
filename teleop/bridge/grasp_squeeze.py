"""The grasp assist's squeeze: the validator's force-sized grip, put on the hand's joint targets.

Why. The assist's press (:class:`teleop.bridge.grasp_assist.GraspAssist`) moves the snapped pad
targets a fixed depth into the object, so the IK closes the fingers onto it — it makes contact,
but the force it gives is whatever the servos make of a centimetre, the same for a 30 g lemon
and a 1.1 kg bleach bottle, and partly along the surface or down into the table. Measured on
the human-timed benchmark (``benchmarks/bench_teleop_loop.py --operator human``, 34 episodes),
the free-object lift held in 13: a press of 2 cm lifted 14, of 3.5 cm none of the 14 heavy-object
episodes, while 20 of the 32 demo grasps hold in the validator's own lift-drop. The validator
sizes its squeeze by force (:mod:`sim.validate.targets`): each hand body near the object gets
the normal force that lets friction carry ``grip_safety`` times the object's weight and its
moment, turned into joint-target deflections by the servos' stiffness (``K_q⁺ Jᵀ f``) and
capped by their force limits. The bridge asks it for exactly that, at the contacts the operator
made, and adds the deflection (times the assist's level, so it ramps in and out with the press)
to the retargeted joint targets: a person's grip scales with the load in the same way.

When. :meth:`GraspSqueeze.plan` runs once when the assist engages (a few milliseconds: one
collision pass with a search margin and a small least-squares solve), against the scene as it
is then; the deflection stays until the assist has let go (:meth:`GraspSqueeze.reset`), so the
hand does not re-plan while the object moves in it. No body near the object, or a plan that
fails, gives no squeeze (the press alone, as before). Joint values in radians.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from sim.hand.model import Hand
    from sim.world.objects import ObjectAsset
    from sim.world.scene import Scene

__all__ = ["GraspSqueeze"]

log = logging.getLogger(__name__)


class GraspSqueeze:
    """The squeeze of one scene's object (module docstring); ``enabled`` False: never any."""

    def __init__(self, hand: Hand, obj: ObjectAsset, enabled: bool = True) -> None:
        from sim.validate.validator import Validator

        self._validator = Validator(hand, obj) if enabled else None
        #: joint-target deflection (hand joint vector, radians; None: no squeeze planned)
        self.dq: np.ndarray | None = None
        #: the total normal force (newtons) the planned squeeze asks of the contacts (0: none)
        self.grip_n = 0.0

    @property
    def planned(self) -> bool:
        return self.dq is not None

    def plan(self, scene: Scene, q_target: np.ndarray) -> None:
        """Plan the squeeze at the hand's simulated joints (``q_target`` for the joints the scene
        does not simulate), sized for the object's weight along −z as lift-drop sizes it."""
        if self._validator is None:
            return
        q = np.array(q_target, float)
        q[scene.hand_joint_kept] = scene.data.qpos[scene.hand_qadr]
        try:
            targets = self._validator.derive_targets(scene, q)
        except (ValueError, np.linalg.LinAlgError) as exc:   # a degenerate contact set
            log.debug("no squeeze planned: %s", exc)
            return
        if targets.n_bodies_near:
            self.dq = np.asarray(targets.squeeze, float) - q
            self.grip_n = float(targets.grip_force_n) * targets.n_bodies_near

    def reset(self) -> None:
        """The assist let go: the next grasp plans its own squeeze."""
        self.dq, self.grip_n = None, 0.0

    def ctrl(self, q_target: np.ndarray, level: float) -> np.ndarray:
        """The joint targets to servo to: ``q_target`` plus ``level`` (0…1) of the deflection."""
        return q_target if self.dq is None or level <= 0.0 else q_target + level * self.dq
