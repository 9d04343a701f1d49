"""The synthetic operator's "headset": a noise-free :class:`GraspMotion` seen through a sensor
model becomes the :class:`teleop.messages.HandFrame` stream a real Quest gives after ingest.

Frames at ``rate_hz`` (Quest: 72–90 Hz) with Gaussian timestamp jitter (kept monotonic) and a
receive latency; per-joint Gaussian position noise and small random rotations of every joint
frame (white, per frame); bursts of lost tracking (hand present, untracked, all joints
invalid) whose long-run fraction of frames is ``dropout_fraction`` (:func:`dropout_mask`). All
randomness comes from one ``numpy.random.Generator``: same generator state, same frames.

Units: metres, seconds, radians (degrees only in ``*_deg`` settings); quaternions wxyz.
"""

from __future__ import annotations

import math

import numpy as np

from sim.transforms import axis_angle_to_mat, mat_to_quat, rotvec_to_mat
from teleop.messages import NUM_JOINTS, HandFrame, HandState
from teleop.synthetic.config import SynthConfig
from teleop.synthetic.episode import GraspMotion
from teleop.synthetic.human_hand import HumanHand

__all__ = ["DEVICE_T0_S", "dropout_mask", "observe"]

Array = np.ndarray

#: Device clock at an episode's first frame (seconds; any epoch works).
DEVICE_T0_S = 10.0


def dropout_mask(n_frames: int, rng: np.random.Generator, fraction: float,
                 burst_frames: tuple[int, int]) -> Array:
    """Boolean (n,) True where the hand is *tracked*. Bursts of lost tracking start with
    probability p per tracked frame and last a uniform number of frames in ``burst_frames``;
    p = f / (L (1 − f)) with L the mean burst length makes the long-run untracked fraction f
    (a tracked run lasts 1/p frames on average, then a burst of L)."""
    tracked = np.ones(n_frames, dtype=bool)
    if fraction <= 0.0 or n_frames == 0:
        return tracked
    lo, hi = burst_frames
    mean_len = 0.5 * (lo + hi)
    p = min(fraction / (mean_len * (1.0 - fraction)), 1.0)
    starts = rng.random(n_frames) < p
    lengths = rng.integers(lo, hi + 1, n_frames)
    i = 0
    while i < n_frames:
        if starts[i]:
            tracked[i:i + lengths[i]] = False
            i += int(lengths[i])
        else:
            i += 1
    return tracked


def observe(motion: GraspMotion, human: HumanHand, cfg: SynthConfig, rng: np.random.Generator,
            source: str) -> tuple[list[HandFrame], Array]:
    """The frames (device times from :data:`DEVICE_T0_S`) of ``human`` performing ``motion``
    as the headset reports them, and per frame whether the hand is tracked. The hand goes on
    the ``human.side`` side of each frame; ``source`` labels the frames."""
    n = math.floor(motion.duration_s * cfg.rate_hz) + 1
    t_nom = np.arange(n) / cfg.rate_hz
    tracked = dropout_mask(n, rng, cfg.dropout_fraction, cfg.dropout_burst_frames)
    jitter = np.clip(rng.normal(0.0, cfg.time_jitter_s, n), -0.4 / cfg.rate_hz,
                     0.4 / cfg.rate_hz)
    t_dev = DEVICE_T0_S + t_nom + jitter
    t_recv = t_dev + cfg.latency_s + np.abs(rng.normal(0.0, cfg.latency_jitter_s, n))
    head_pos = np.asarray(cfg.head_pos_m, float)
    head_q = mat_to_quat(axis_angle_to_mat(np.array([[0.0, 1.0, 0.0]]),
                                           np.array([math.radians(cfg.head_pitch_deg)]))[0])
    sigma_rot = math.radians(cfg.orientation_noise_deg)
    side = human.side
    frames: list[HandFrame] = []
    for i in range(n):
        # noise is drawn for every frame, tracked or not, so that the dropout pattern does
        # not shift the noise of later frames (frames stay comparable across dropout settings)
        pos_noise = rng.normal(0.0, cfg.position_noise_m, (NUM_JOINTS, 3))
        rot_noise = rng.normal(0.0, sigma_rot, (NUM_JOINTS, 3))
        head_noise = rng.normal(0.0, 0.001, 3)
        if tracked[i]:
            p_w, r_w, pose = motion.at(float(t_nom[i]))
            pos, rot = human.joints(pose, p_w, r_w)
            rot = np.einsum("nij,njk->nik", rotvec_to_mat(rot_noise), rot)
            state = HandState(pos + pos_noise, mat_to_quat(rot), human.radii.copy(),
                              np.ones(NUM_JOINTS, bool), tracked=True)
        else:
            state = HandState.untracked()
        frames.append(HandFrame(
            seq=i, device_time_s=float(t_dev[i]), receive_time_s=float(t_recv[i]),
            head_position=head_pos + head_noise, head_orientation_wxyz=head_q,
            left=state if side == "left" else None, right=state if side == "right" else None,
            source=source))
    return frames, tracked
