"""A ``dm_env.Environment`` of the grasp scene: hand, object, table; lift-drop judges.

Built with dm-control's ``rl.control``: a :class:`GraspPhysics` over the scene's own MjModel
and MjData (:func:`sim.envs.referee.env_scene`) and a :class:`GraspTask`. Each episode starts
at a grasp's pregrasp as the validator starts it (grasps chosen at random from the list
given, or the one :meth:`GraspTask.select` names; with ``approach_m``, the hand that far out
along its palm normal, and the protocol's timeline starts after the approach) and runs on
lift-drop's timeline: gravity is off while the fingers close, pulls from the lift on, and
turns along the palm normal at the release. The protocol's verdict ends the episode
(discount 0) with reward 1 if the grasp passed, else 0; every other step is rewarded 0.

Action (one flat vector, :func:`action_spec_of`): the hand's actuator targets (its servos'
joint or tendon positions, bounded by the actuators' control ranges), then the hand base's
mocap target position (metres, world; the object's home ± :data:`REACH_M`) and its rotation
from the episode's start orientation (rotation vector, radians). The base carries the arm's
part of the hand (the Shadow Hand's two wrist joints are among its actuator targets).
:func:`episode_actions` turns a recorded episode (:mod:`sim.episodes`) into these actions.

Observations (float64): the hand's joint positions and velocities, frame_palm's and the
object's world poses (position, wxyz quaternion), per fingertip whether it touches the object
and its contacts' normal force (newtons; :mod:`sim.episodes.observe`); with ``camera=(h, w)``
an RGB image of the scene's overview camera (uint8).
"""

from __future__ import annotations

import logging
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

try:
    import dm_env
    from dm_control import mujoco as dm_mujoco
    from dm_control.mujoco import wrapper
    from dm_control.rl import control
    from dm_env import specs
except ImportError as exc:   # the optional extra
    raise ImportError("sim.envs needs dm-control: pip install 'dexaug[envs]'") from exc

from sim.envs.referee import Referee, env_scene
from sim.episodes.episode import Episode
from sim.episodes.observe import fingertip_bodies, read_state
from sim.episodes.rollout import CAMERA
from sim.grasp import Grasp
from sim.validate.validator import Validator
from sim.world.scene import OBJECT_HOME, Scene

__all__ = ["REACH_M", "GraspPhysics", "GraspTask", "action_spec_of", "episode_actions",
           "grasp_env", "run_actions", "turned"]

log = logging.getLogger(__name__)

#: how far (metres, per axis) the hand base's target may go from the object's home
REACH_M = 0.5
#: an actuator without a control range or a limited joint gets this range (radians)
_FALLBACK_RANGE = (-np.pi, np.pi)


class GraspPhysics(dm_mujoco.Physics):
    """dm-control's Physics over a grasp scene's MjData, stepping with ``mj_step`` (the
    validator's stepping) and letting the referee carry out the protocol between steps."""

    referee: Referee | None = None

    def after_reset(self) -> None:
        """Derived quantities of the reset state with the actuators on: dm-control's default
        turns them off for this ``mj_forward``, but a grasp's reset holds real servo targets
        (the pregrasp), and the first observation's contact forces should be the run's."""
        mujoco.mj_forward(self.model.ptr, self.data.ptr)

    def step(self, nstep: int = 1) -> None:
        m, d, ref = self.model.ptr, self.data.ptr, self.referee
        for _ in range(nstep):
            if ref is not None:
                ref.before_step()
            mujoco.mj_step(m, d)
            if ref is not None:
                ref.after_step()


def _ctrl_bounds(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Per hand actuator: its control range, else its joint's range, else the fallback."""
    m, lo, hi = scene.model, [], []
    for a in scene.hand_act:
        joint = int(m.actuator_trnid[a, 0])
        if m.actuator_ctrllimited[a]:
            r = m.actuator_ctrlrange[a]
        elif m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and m.jnt_limited[joint]:
            r = m.jnt_range[joint]
        else:
            r = _FALLBACK_RANGE
        lo.append(float(r[0]))
        hi.append(float(r[1]))
    return np.array(lo), np.array(hi)


def action_spec_of(scene: Scene) -> Any:
    """The bounded action vector of ``scene`` (module docstring)."""
    lo, hi = _ctrl_bounds(scene)
    lo = np.concatenate([lo, OBJECT_HOME - REACH_M, np.full(3, -np.pi)])
    hi = np.concatenate([hi, OBJECT_HOME + REACH_M, np.full(3, np.pi)])
    return specs.BoundedArray(lo.shape, np.float64, lo, hi, name="action")


def turned(quat: np.ndarray, rotvec: np.ndarray) -> np.ndarray:
    """``quat`` (wxyz) turned by ``rotvec`` (radians, in its own frame); ``quat`` itself, bit
    for bit, when there is no turn (a replayed trajectory keeps its exact orientation)."""
    angle = float(np.linalg.norm(rotvec))
    if angle == 0.0:
        return np.array(quat, dtype=float)
    turn = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * np.asarray(rotvec) / angle])
    out = np.empty(4)
    mujoco.mju_mulQuat(out, np.asarray(quat, dtype=float), turn)
    return out / np.linalg.norm(out)


class GraspTask(control.Task):
    """Reset from a grasp's pregrasp, act on the hand, judged by lift-drop (module
    docstring). ``camera``: (height, width) of an overview image observation, or None."""

    def __init__(self, validator: Validator, grasps: Sequence[Grasp], scene: Scene, *,
                 camera: tuple[int, int] | None = None, seed: int | None = None,
                 approach_m: float = 0.0, approach_s: float = 0.5) -> None:
        if not grasps:
            raise ValueError("a grasp environment needs at least one grasp to start from")
        self.random = np.random.default_rng(seed)
        self.grasps = list(grasps)
        self.scene = scene
        self.referee = Referee(validator, scene)
        self.camera = camera
        self.approach_m, self.approach_s = approach_m, approach_s
        self.tips = fingertip_bodies(scene)
        self.grasp_index = -1
        self._next: int | None = None
        self._start_quat = np.array([1.0, 0.0, 0.0, 0.0])
        self._nu = len(scene.hand_act)

    def select(self, index: int) -> None:
        """Start the next episode from grasp ``index`` (else one is drawn at random)."""
        if not 0 <= index < len(self.grasps):
            raise IndexError(f"grasp {index}: the environment has {len(self.grasps)}")
        self._next = index

    @property
    def failure(self) -> str | None:
        """Why the episode's grasp failed, once the protocol has ended."""
        return self.referee.failure

    def initialize_episode(self, physics: GraspPhysics) -> None:
        if self._next is None:
            index = int(self.random.integers(len(self.grasps)))
        else:
            index, self._next = self._next, None
        self.grasp_index = index
        self.referee.start(self.grasps[index], self.approach_m, self.approach_s)
        physics.referee = self.referee
        self._start_quat = self.referee.start_quat()

    def before_step(self, action: Any, physics: GraspPhysics) -> None:
        a = np.asarray(action, dtype=float)
        s, d, nu = self.scene, self.scene.data, self._nu
        d.ctrl[s.hand_act] = a[:nu]
        d.mocap_pos[s.mocap_id] = a[nu:nu + 3]
        d.mocap_quat[s.mocap_id] = turned(self._start_quat, a[nu + 3:nu + 6])

    def holding_action(self) -> np.ndarray:
        """The action that keeps the hand's controls and base target as they are now."""
        s, d = self.scene, self.scene.data
        return np.concatenate([d.ctrl[s.hand_act], d.mocap_pos[s.mocap_id], np.zeros(3)])

    def action_spec(self, physics: GraspPhysics) -> Any:
        return action_spec_of(self.scene)

    def observation_spec(self, physics: GraspPhysics) -> OrderedDict[str, Any]:
        nj, nf = len(self.scene.hand_qadr), len(self.tips)
        shapes = {"hand_qpos": (nj,), "hand_qvel": (nj,), "palm_pos": (3,), "palm_quat": (4,),
                  "object_pos": (3,), "object_quat": (4,), "fingertip_contact": (nf,),
                  "fingertip_force": (nf,)}
        out: OrderedDict[str, Any] = OrderedDict(
            (k, specs.Array(v, np.float64, name=k)) for k, v in shapes.items())
        if self.camera is not None:
            out["camera"] = specs.Array((*self.camera, 3), np.uint8, name="camera")
        return out

    def get_observation(self, physics: GraspPhysics) -> OrderedDict[str, np.ndarray]:
        st = read_state(self.scene, self.tips)
        obs: OrderedDict[str, np.ndarray] = OrderedDict(
            hand_qpos=st["hand_qpos"], hand_qvel=st["hand_qvel"],
            palm_pos=st["palm_pose"][:3], palm_quat=st["palm_pose"][3:],
            object_pos=st["object_pose"][:3], object_quat=st["object_pose"][3:],
            fingertip_contact=st["fingertip_contact"].astype(np.float64),
            fingertip_force=st["fingertip_force"].astype(np.float64))
        if self.camera is not None:
            height, width = self.camera
            obs["camera"] = physics.render(height, width, camera_id=CAMERA)
        return obs

    def get_reward(self, physics: GraspPhysics) -> float:
        return 1.0 if self.referee.passed else 0.0

    def get_termination(self, physics: GraspPhysics) -> float | None:
        return 0.0 if self.referee.done else None


def grasp_env(validator: Validator, grasps: Sequence[Grasp], *, table: bool = True,
              n_sub_steps: int = 1, camera: tuple[int, int] | None = None,
              seed: int | None = None, approach_m: float = 0.0,
              approach_s: float = 0.5) -> Any:
    """The grasp environment of ``validator``'s hand and object, its episodes starting from
    ``grasps`` (e.g. :func:`augment.grasp_table.grasps_of` of a dataset's table): a
    ``dm_control.rl.control.Environment`` (a ``dm_env.Environment``). ``n_sub_steps``: physics
    steps (``[lift_drop] timestep_s`` each) per action; ``table``: the table under the object
    (:func:`sim.envs.referee.env_scene`); ``camera``: (height, width) of an image
    observation; ``seed``: of the random grasp choice at reset; ``approach_m`` > 0: each
    episode starts with the hand that far out along its palm normal, and lift-drop starts
    judging after an approach of ``approach_s`` (:meth:`sim.envs.referee.Referee.start`;
    what :func:`sim.episodes.rollout.rollout` records with the same arguments)."""
    scene = env_scene(validator, table=table)
    task = GraspTask(validator, grasps, scene, camera=camera, seed=seed, approach_m=approach_m,
                     approach_s=approach_s)
    physics = GraspPhysics(wrapper.MjData(scene.data))
    log.info("grasp environment: %s on %s, %d grasps, %d actions, control every %.3f s",
             validator.hand.name, validator.obj.name, len(task.grasps), len(scene.hand_act) + 6,
             n_sub_steps * scene.model.opt.timestep)
    return control.Environment(physics, task, n_sub_steps=n_sub_steps, legacy_step=False)


def episode_actions(episode: Episode) -> np.ndarray:
    """(T, nu + 6) the environment's actions that carry out ``episode``'s recorded ones: the
    hand controls, the base target position and its rotation from the first step's
    orientation (zero, exactly, while it does not turn: lift-drop never turns it)."""
    q0 = episode.base_target_quat[0]
    turns = np.zeros((len(episode), 3))
    for t, q in enumerate(episode.base_target_quat):
        if not np.array_equal(q, q0):
            mujoco.mju_subQuat(turns[t], q, q0)
    return np.hstack([episode.ctrl, episode.base_target_pos, turns])


def run_actions(env: Any, actions: np.ndarray) -> Any:
    """Step ``env`` (just reset) through ``actions`` until the episode ends, holding the hand
    as it is once they run out; the last TimeStep (``reward`` 1.0: the protocol passed the
    grasp)."""
    for a in actions:
        step = env.step(a)
        if step.step_type == dm_env.StepType.LAST:
            return step
    while True:
        step = env.step(env.task.holding_action())
        if step.step_type == dm_env.StepType.LAST:
            return step
