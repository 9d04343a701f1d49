"""A synthetic operator: grasp episodes as hand-tracking frames, without a headset
(:func:`synthesize`).

Why: the teleop chain (retargeting, bridge, recording, demo extraction) needs repeatable input
with a known ground truth — an object, where it stands, when the grasp happens — and real
captures have neither a known object pose nor a grasp moment. The synthetic operator plays the
operator: a parametric human hand (:mod:`teleop.synthetic.human_hand`) takes a grasp pose that
the retargeter maps onto the robot hand's reference grasp of the object
(:mod:`teleop.synthetic.grasp_pose`), performs approach → close → lift → hold → release →
retreat (:mod:`teleop.synthetic.episode`), reaching from where, and in a pre-shape that, keep
it off the table and the object until it closes (:mod:`teleop.synthetic.preshape`), and the
result goes through the same "sensor" a headset is (noise, dropouts, timestamp jitter:
:mod:`teleop.synthetic.sensor`) to become :class:`teleop.messages.HandFrame` objects in the
MuJoCo world, exactly what ingest produces from a real Quest. :mod:`teleop.synthetic.writer`
records an episode as a session.

Settings live in ``configs/teleop.toml`` ``[synth]`` (:mod:`teleop.synthetic.config`). Units:
metres, seconds, radians (degrees only in ``*_deg`` keys); quaternions wxyz in memory.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sim.hand.model import Hand
from sim.transforms import mat_to_quat, quat_to_mat, rpy_deg_to_mat
from teleop.synthetic.config import SynthConfig, load_synth_config
from teleop.synthetic.correspondence import Correspondence
from teleop.synthetic.episode import TOUCH_AT, GraspMotion, SynthEpisode
from teleop.synthetic.grasp_pose import grasp_target
from teleop.synthetic.human_hand import FINGERS, HumanHand, finger_of
from teleop.synthetic.preshape import Obstacles
from teleop.synthetic.sensor import DEVICE_T0_S, observe

__all__ = ["synthesize"]

logger = logging.getLogger(__name__)


def _obstacles(object_name: str, obj_pos: np.ndarray, obj_rot: np.ndarray) -> Obstacles:
    """The object's surface in the world and the table it stands on (its lowest point: the
    bridge rests the object on its table, so this is where the operator sees the table top)."""
    from sim.world.objects import load_object

    mesh = load_object(object_name).surface_mesh()
    pts = obj_pos + np.asarray(mesh.vertices) @ obj_rot.T
    return Obstacles(float(pts[:, 2].min()), pts, np.asarray(mesh.vertex_normals) @ obj_rot.T)


def synthesize(object_name: str, *, hand: Hand | str, seed: int = 0,
               config: SynthConfig | None = None, object_pos_m: Sequence[float] | None = None,
               object_quat_wxyz: Sequence[float] | None = None, grasp_name: str | None = None,
               retarget_config: Path | str | None = None) -> SynthEpisode:
    """Synthesize one grasp episode of ``object_name`` for robot hand ``hand``.

    The operator hand side and the wrist correspondence come from the hand's retargeting
    mapping (``configs/hands/<hand>/retarget.toml``; ``retarget_config``: another teleop.toml
    for ``[retarget]``); the robot grasp imitated is the hand's reference grasp for the object
    (or ``grasp_name``), else a generic side grasp. The object stands at ``object_pos_m`` /
    ``object_quat_wxyz`` (world; default from the config). Deterministic per ``seed``.
    """
    cfg = config or load_synth_config()
    robot = Hand.load(hand) if isinstance(hand, str) else hand
    corr = Correspondence(robot, retarget_config)
    side = corr.mapping.side
    human = HumanHand(cfg.hand_length_m, side)
    scale = corr.scale(human.chain_length_m(finger_of(corr.mapping.fingers[
        corr.mapping.scale_finger])))
    obj_pos = np.asarray(object_pos_m if object_pos_m is not None else cfg.object_pos_m, float)
    obj_rot = (quat_to_mat(np.asarray(object_quat_wxyz, float) /
                           np.linalg.norm(object_quat_wxyz)) if object_quat_wxyz is not None
               else rpy_deg_to_mat(cfg.object_rpy_deg))
    standoff, cfg = _human_draws(cfg, seed)
    target = grasp_target(robot, human, corr, scale, object_name, obj_pos, obj_rot,
                          grasp_name=grasp_name, snap_m=cfg.tip_surface_snap_m,
                          press_m=cfg.press_depth_m, standoff_m=standoff,
                          grip_friction=cfg.grip_friction)

    motion = GraspMotion.plan(cfg, target.wrist_pos_m, target.wrist_rot, target.palm_rot,
                              target.pose, human=human,
                              obstacles=_obstacles(object_name, obj_pos, obj_rot),
                              pressed=target.reference is None and standoff is None
                              and cfg.press_depth_m > 0.0)
    rng = np.random.default_rng(seed)
    frames, tracked = observe(motion, human, cfg, rng, source=f"synth:{object_name}:seed{seed}")
    phases, t0 = motion.phases, DEVICE_T0_S
    logger.info("synthesized %d frames (%.1f s, %d untracked) of %s grasping %s", len(frames),
                motion.duration_s, int((~tracked).sum()), side, object_name)
    ref = target.reference
    return SynthEpisode(
        frames=frames, grasp_time_s=t0 + phases["close"][1],
        phases={k: (t0 + a, t0 + b) for k, (a, b) in phases.items()}, object_name=object_name,
        object_pos_m=obj_pos, object_quat_wxyz=mat_to_quat(obj_rot),
        reference_grasp=ref, grasp_wrist_pos_m=target.wrist_pos_m,
        grasp_wrist_quat_wxyz=mat_to_quat(target.wrist_rot),
        target_palm_pos_m=target.palm_pos_m, target_palm_quat_wxyz=mat_to_quat(target.palm_rot),
        fit_residual_m=target.residual_m, tracked=tracked, side=side, seed=seed,
        metadata={"hand": robot.name, "object": object_name, "synthetic": True, "seed": seed,
                  "reference_grasp": ref, "side": side,
                  "object_pos_m": obj_pos.tolist(),
                  "object_quat_wxyz": mat_to_quat(obj_rot).tolist(),
                  "joint_names": list(robot.joint_names),
                  "fingers": list(robot.finger_names),
                  "standoff_m": None if standoff is None else dict(zip(
                      FINGERS, np.round(standoff, 5).tolist(), strict=True)),
                  "lift_delay_s": _lift_delay(cfg)})


def _human_draws(cfg: SynthConfig, seed: int) -> tuple[np.ndarray | None, SynthConfig]:
    """The episode's human geometry and timing (``standoff_m``, ``lift_delay_s`` of
    :class:`SynthConfig`): per finger (thumb first, :data:`FINGERS`) how far short of the
    surface the tip stops (metres; None when off), and the config with ``settle_s`` set so
    that the lift begins the drawn delay after the fingers reach the object (they reach it at
    :data:`teleop.synthetic.episode.TOUCH_AT` of the close phase). Drawn from their own
    stream of the seed, so switching them on leaves the sensor's noise and dropouts as they
    were."""
    rng = np.random.default_rng([seed, 0x5EED])
    standoff = (rng.uniform(*cfg.standoff_m, len(FINGERS)) if cfg.standoff_m[1] > 0.0
                else None)
    if cfg.lift_delay_s[1] > 0.0:
        delay = float(rng.uniform(*cfg.lift_delay_s))
        cfg = dataclasses.replace(cfg, settle_s=max(delay - (1.0 - TOUCH_AT) * cfg.close_s, 0.0))
    return standoff, cfg


def _lift_delay(cfg: SynthConfig) -> float:
    """Seconds from the fingers reaching the object to the start of the lift."""
    return round((1.0 - TOUCH_AT) * cfg.close_s + cfg.settle_s, 6)
