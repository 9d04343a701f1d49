"""Checks that a hand's config follows dexaug's palm-frame convention (DESIGN §3 "Palm frame").

The convention: the palm lies in frame_palm's X-O-Z plane, its origin on the palm face, and +y
is the palm normal pointing out of the palm face toward the fingers' pulp side, where a grasped
object sits. A config with the wrong sign of y still loads and runs, but AutoWS, FSG's palm box
and the table rule then all work on the wrong side of the palm; so this module measures, in
frame_palm, what the convention implies for the real model:

- the palm body's own geoms lie behind the palm face (mean geom centre y ≤ 0);
- the palm box of FSG's palm check is centred behind the face (``box_center`` y < 0);
- with the hand closed, the fingertip pulps lie in front of the palm face (mean pulp y > 0)
  and face back toward it (mean pulp normal ``v_f`` has y < 0): fingers curl over the palm,
  a gripper's pads close in front of its base.

"Closed" is the config's ``close_pose`` when it names one, else every manual AutoWS range at its
upper end. :class:`sim.hand.model.Hand` runs these checks when it is built, so a config with
the wrong palm sign is refused with its file and the reason; this module sees the hand only
through :class:`PalmFrameHand` (what the checks use), so the model does not import it back.
"""

from __future__ import annotations

from typing import Protocol, TypedDict

import mujoco
import numpy as np

from sim.hand.config import HandConfig
from sim.transforms import pose_inv, quat_to_mat

__all__ = ["PalmFrameHand", "closed_posture", "palm_frame_measures", "palm_frame_problems"]


class PalmFrameHand(Protocol):
    """What the checks need of a hand model (:class:`sim.hand.model.Hand` provides it)."""

    config: HandConfig
    model: mujoco.MjModel
    nq: int
    joint_names: tuple[str, ...]
    palm_body_id: int

    @property
    def open_pose(self) -> np.ndarray: ...
    def posture(self, name: str) -> np.ndarray: ...
    def fill_coupled(self, q: np.ndarray) -> np.ndarray: ...
    def clip(self, q: np.ndarray) -> np.ndarray: ...
    def body_poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...
    def palm_pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...
    def fingertip_sites(self, q: np.ndarray, frame: str = "base") -> np.ndarray: ...
    def tip_frames_in_palm(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


def closed_posture(hand: PalmFrameHand) -> np.ndarray:
    """The closed hand as a full joint vector (radians): the config's ``close_pose`` when it
    names joints, else every independent joint with a manual range at the range's upper end
    (coupled followers filled, clipped to the joint limits)."""
    if hand.config.postures.get("close_pose"):
        return hand.posture("close_pose")
    q = np.zeros(hand.nq)
    for finger in hand.config.fingers:
        for joint, (_, hi) in finger.ranges_rad.items():
            q[hand.joint_names.index(joint)] = hi
    return hand.clip(hand.fill_coupled(q))


def _palm_geoms_y(hand: PalmFrameHand, q: np.ndarray) -> float | None:
    """Mean y (metres, frame_palm) of the palm body's geom centres at q; None without geoms."""
    m = hand.model
    geoms = np.flatnonzero(m.geom_bodyid == hand.palm_body_id)
    if geoms.size == 0:
        return None
    pos, quat = hand.body_poses(q)
    b = hand.palm_body_id
    centres = pos[0, b] + m.geom_pos[geoms] @ quat_to_mat(quat[0, b]).T
    ppos, pquat = hand.palm_pose(q)
    inv_p, inv_q = pose_inv(ppos[0], pquat[0])
    return float((inv_p + centres @ quat_to_mat(inv_q).T)[:, 1].mean())


class PalmFrameMeasures(TypedDict):
    """What :func:`palm_frame_measures` returns (a plain dict at run time)."""

    palm_geoms_y: float | None
    palm_box_center_y: float
    closed_pulp_y: float
    closed_v_f_y: float


def palm_frame_measures(hand: PalmFrameHand) -> PalmFrameMeasures:
    """The quantities the convention constrains, in frame_palm (metres; unit vectors):
    ``palm_geoms_y`` (open pose; None when the palm body has no geoms), ``palm_box_center_y``,
    ``closed_pulp_y`` (mean pulp position) and ``closed_v_f_y`` (mean pulp normal)."""
    q = closed_posture(hand)
    pulps = hand.fingertip_sites(q, frame="palm")[0]
    _, tip_quat = hand.tip_frames_in_palm(q)
    rot = quat_to_mat(tip_quat[0])
    v_f = np.einsum("fij,fj->fi", rot, np.array([f.v_f for f in hand.config.fingers]))
    return {
        "palm_geoms_y": _palm_geoms_y(hand, hand.open_pose),
        "palm_box_center_y": float(hand.config.palm.box_center[1]),
        "closed_pulp_y": float(pulps[:, 1].mean()),
        "closed_v_f_y": float(v_f[:, 1].mean()),
    }


def palm_frame_problems(hand: PalmFrameHand) -> list[str]:
    """What in the hand's config contradicts the palm-frame convention (empty when nothing),
    each problem naming the config file and the measured value."""
    m = palm_frame_measures(hand)
    where = f"{hand.config.file}: palm"
    problems = []
    if m["palm_geoms_y"] is not None and m["palm_geoms_y"] > 0:
        problems.append(f"{where}: the palm body {hand.config.palm.body!r} lies in front of the "
                        f"palm face (mean geom centre y = {m['palm_geoms_y']:+.4f} m > 0): +y must "
                        "point out of the palm face, away from the hand")
    if m["palm_box_center_y"] >= 0:
        problems.append(f"{where}.box_center: the palm box is centred at y = "
                        f"{m['palm_box_center_y']:+.4f} m, expected behind the palm face (y < 0)")
    if m["closed_pulp_y"] <= 0:
        problems.append(f"{where}: with the hand closed the fingertip pulps lie behind the palm "
                        f"face (mean pulp y = {m['closed_pulp_y']:+.4f} m ≤ 0): +y must point "
                        "toward the pulps")
    if m["closed_v_f_y"] >= 0:
        problems.append(f"{where}: with the hand closed the pulps face away from the palm face "
                        f"(mean v_f y = {m['closed_v_f_y']:+.3f} ≥ 0): they must face back "
                        "toward it (−y)")
    return problems
