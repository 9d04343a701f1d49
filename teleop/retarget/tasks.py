"""The retargeting IK's own mink tasks: the batched point-position task, the coupled-joint
equality constraint and the thumb–finger pinch-distance task.

Point positions
    Every position target of the IK (the fingertip pulp sites, and the phalanx keypoints: the
    origins of the robot's middle and distal phalanx bodies) is one row triple of a single
    :class:`PointsTask`, with a cost per point. Why not one ``mink.FrameTask`` each: a frame
    task computes an SE(3) log and a 6-row Jacobian per point and costs ~50 µs in Python; with
    ten phalanx keypoints added that alone would eat the 1 ms per-frame budget, while the
    position error and ``mj_jacSite``/``mj_jacBody`` rows are all that is needed.

Coupled joints
    Coupled joints (Shadow FJ1 = FJ2, from the hand config's ``coupled_to``) are linear
    equality constraints of the QP (``solve_ik(constraints=...)``), so every IK step already
    moves the pair together and the fingertip tasks are solved *with* the coupling instead of
    being broken by it afterwards (:class:`CouplingConstraint`).

Pinch distances
    While the operator pinches, a thumb–finger *distance* task (:class:`PinchTask`, cost
    ``pinch_cost`` × the pinch weight) makes the IK favour the pinch over the absolute fingertip
    positions (DexPilot's idea): the operator's thumb often sits where the robot's thumb cannot
    go, and the absolute targets alone park the robot thumb at a joint limit ~2 cm from the
    finger. A distance, not a vector, leaves the approach direction to the robot's own pinch
    geometry.

Positions are metres, joint values radians.
"""

from __future__ import annotations

from collections.abc import Sequence

import mink
import mujoco
import numpy as np

__all__ = ["CouplingConstraint", "PinchTask", "PointsTask"]

Array = np.ndarray


class CouplingConstraint(mink.Task):
    """q_follower − coef · q_leader = 0 for every coupled pair, as QP equality rows (passed via
    ``solve_ik(constraints=...)``); the error feedback removes any drift.

    pairs: (follower joint id, leader joint id, coef) per coupled pair."""

    def __init__(self, model: mujoco.MjModel, pairs: Sequence[tuple[int, int, float]]) -> None:
        super().__init__(cost=np.ones(len(pairs)), gain=1.0)
        self._follower_q = np.array([model.jnt_qposadr[f] for f, _, _ in pairs])
        self._leader_q = np.array([model.jnt_qposadr[lead] for _, lead, _ in pairs])
        self._coef = np.array([c for _, _, c in pairs])
        self._jac = np.zeros((len(pairs), model.nv))
        for row, (f, lead, c) in enumerate(pairs):
            self._jac[row, model.jnt_dofadr[f]] += 1.0
            self._jac[row, model.jnt_dofadr[lead]] -= c

    def compute_error(self, configuration: mink.Configuration) -> Array:
        qpos = configuration.data.qpos
        return qpos[self._follower_q] - self._coef * qpos[self._leader_q]

    def compute_jacobian(self, configuration: mink.Configuration) -> Array:
        del configuration
        return self._jac


class PinchTask(mink.Task):
    """Thumb-to-finger pulp distances: |p_finger − p_thumb| − target for every non-thumb
    finger, one row each. Its per-finger cost follows the pinch weight, so while the operator
    pinches the IK cares most about how far apart thumb and finger are, which the robot can
    realise, rather than about absolute fingertip positions, which it often cannot (human and
    robot thumbs differ): the DexPilot idea, on pulp sites. A distance rather than a vector
    leaves the approach direction to the robot's own pinch geometry; a fixed direction taken
    from the operator can pin the thumb against a joint limit on the wrong side of the finger.

    thumb_site, finger_sites: MuJoCo site ids; :attr:`target_m` (metres, per finger) and the
    costs (:meth:`set_weights`) are set before each solve.
    """

    def __init__(self, model: mujoco.MjModel, thumb_site: int,
                 finger_sites: Sequence[int]) -> None:
        n = len(finger_sites)
        super().__init__(cost=np.zeros(n), gain=1.0)
        self._model = model
        self._thumb = thumb_site
        self._fingers = np.asarray(finger_sites)
        self.target_m = np.zeros(n)
        self._jac_thumb = np.empty((3, model.nv))
        self._jac_finger = np.empty((3, model.nv))
        self._jac = np.empty((n, model.nv))

    def set_weights(self, cost_per_finger: Array) -> None:
        self.cost[:] = cost_per_finger

    def _vectors(self, configuration: mink.Configuration) -> tuple[Array, Array]:
        x = configuration.data.site_xpos
        v = x[self._fingers] - x[self._thumb]
        return v, np.sqrt(np.einsum("ij,ij->i", v, v))

    def compute_error(self, configuration: mink.Configuration) -> Array:
        return self._vectors(configuration)[1] - self.target_m

    def compute_jacobian(self, configuration: mink.Configuration) -> Array:
        m, d = self._model, configuration.data
        v, dist = self._vectors(configuration)
        u = v / np.maximum(dist, 1e-9)[:, None]
        mujoco.mj_jacSite(m, d, self._jac_thumb, None, self._thumb)
        for k, sid in enumerate(self._fingers):
            mujoco.mj_jacSite(m, d, self._jac_finger, None, int(sid))
            self._jac_finger -= self._jac_thumb
            np.dot(u[k], self._jac_finger, out=self._jac[k])
        return self._jac


class PointsTask(mink.Task):
    """World positions of MuJoCo sites and body origins minus their targets, three rows per
    point, each point with its own cost (1/m).

    sites / bodies: MuJoCo ids, the sites first in the rows; costs: one per point (sites, then
    bodies). :attr:`target_m` ((n, 3), metres, the model's world = the hand base frame) is
    written in place before each solve.
    """

    def __init__(self, model: mujoco.MjModel, sites: Sequence[int], bodies: Sequence[int],
                 costs: Array, lm_damping: float = 0.0) -> None:
        n = len(sites) + len(bodies)
        costs = np.asarray(costs, dtype=float)
        if costs.shape != (n,):
            raise ValueError(f"expected {n} point costs, got shape {costs.shape}")
        super().__init__(cost=np.repeat(costs, 3), gain=1.0, lm_damping=lm_damping)
        self._model = model
        self._sites = np.asarray(sites, dtype=int)
        self._bodies = np.asarray(bodies, dtype=int)
        self.target_m = np.zeros((n, 3))
        self._jac = np.zeros((3 * n, model.nv))

    def positions(self, data: mujoco.MjData) -> Array:
        """Current world positions (n, 3) of the points, metres."""
        return np.concatenate([data.site_xpos[self._sites], data.xpos[self._bodies]])

    def compute_error(self, configuration: mink.Configuration) -> Array:
        return (self.positions(configuration.data) - self.target_m).ravel()

    def compute_jacobian(self, configuration: mink.Configuration) -> Array:
        m, d = self._model, configuration.data
        jac = self._jac
        ns = len(self._sites)
        for k, sid in enumerate(self._sites):
            mujoco.mj_jacSite(m, d, jac[3 * k:3 * k + 3], None, int(sid))
        for k, bid in enumerate(self._bodies, start=ns):
            mujoco.mj_jacBody(m, d, jac[3 * k:3 * k + 3], None, int(bid))
        return jac
