"""Play an episode's actions again and give back the states they lead to.

Why: an exported trajectory is only worth training on if its actions, played in the
simulation, give its states. :func:`replay` starts ``scene`` (a scene of the same model, e.g.
a freshly built validator's: nothing of the recording run's MjModel or MjData is reused) at the
episode's initial state and applies, step by step, the recorded actions and conditions
(:mod:`sim.episodes.episode`); :func:`max_joint_error` compares the result with the record.
"""

from __future__ import annotations

import mujoco
import numpy as np

from sim.episodes.episode import Episode
from sim.episodes.observe import STATE_KEYS, fingertip_bodies, read_state
from sim.validate.program import STATE_SPEC
from sim.world.scene import Scene

__all__ = ["max_joint_error", "replay"]


def replay(episode: Episode, scene: Scene) -> dict[str, np.ndarray]:
    """The states (:data:`sim.episodes.observe.STATE_KEYS`, T + 1 rows) that ``episode``'s
    actions give in ``scene`` from its initial state. ``scene`` must be of the model the
    episode was recorded in (same hand, object and protocol physics): the state sizes are
    checked."""
    m, d = scene.model, scene.data
    if mujoco.mj_stateSize(m, STATE_SPEC) != len(episode.initial_state):
        raise ValueError(f"episode of {episode.hand} / {episode.object}: its state does not fit "
                         f"this scene's model ({m.nq} positions)")
    mujoco.mj_resetData(m, d)
    mujoco.mj_setState(m, d, episode.initial_state, STATE_SPEC)
    m.opt.gravity[:] = episode.initial_gravity
    mujoco.mj_forward(m, d)
    tips = fingertip_bodies(scene)
    rows: dict[str, list[np.ndarray]] = {k: [] for k in STATE_KEYS}

    def keep() -> None:
        for k, v in read_state(scene, tips).items():
            rows[k].append(v)

    keep()
    for t in range(len(episode)):
        m.opt.gravity[:] = episode.gravity[t]
        d.xfrc_applied[scene.obj_body, :3] = episode.object_force[t]
        d.ctrl[scene.hand_act] = episode.ctrl[t]
        d.mocap_pos[scene.mocap_id] = episode.base_target_pos[t]
        d.mocap_quat[scene.mocap_id] = episode.base_target_quat[t]
        mujoco.mj_step(m, d)
        pin = episode.pin_pose[t]
        if np.isfinite(pin).all():
            scene.set_object_pose(pin[:3], pin[3:])
        keep()
    return {k: np.array(v) for k, v in rows.items()}


def max_joint_error(episode: Episode, states: dict[str, np.ndarray]) -> float:
    """Largest difference (radians, or metres for a slide joint) between the hand joint
    positions of ``states`` and the episode's own, over every step."""
    want = episode.states["hand_qpos"]
    got = states["hand_qpos"]
    if got.shape != want.shape:
        raise ValueError(f"replayed {got.shape} joint rows, the episode has {want.shape}")
    return float(np.abs(got - want).max(initial=0.0))
