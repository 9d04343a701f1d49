"""Another tool's hand in terms of ours: its joint order and its palm body, and the exact
conversion of dexaug grasps into them and back.

A dexaug grasp is frame_palm in the object frame plus every joint of our hand model (DESIGN §3;
24 for the Menagerie Shadow Hand: ``rh_WRJ2``, ``rh_WRJ1`` and the 22 finger joints). The FSG
authors' files and DexGraspBench/BODex place a hand by the pose of a *body* (``rh_palm``) and
list only the 22 finger joints: both of their Shadow Hands float from the palm, with no forearm
and no wrist. :class:`ForeignHand` converts with forward kinematics of our hand model (the pose
of their body in frame_palm for each grasp's own joints), not with hard-coded offsets, and maps
joints by name. Which body and which joints in which order is the hand's own declaration, its
``[formats.<layout>]`` table (``configs/hands/<hand>/hand.toml``, :class:`sim.hand.config.HandFormat`):
a hand that declares none is refused in one line, whatever joints it has.

What is dropped: our joints that are not theirs. They are accepted only when they move nothing
their hand has — joints of the body itself or of bodies above it (the Shadow wrist: ``rh_WRJ1``
turns ``rh_palm`` against ``rh_wrist``, ``rh_WRJ2`` ``rh_wrist`` against the forearm). A grasp
with a bent wrist is therefore converted exactly: its ``rh_palm`` and everything below are
where they were; only the wrist angles, and our wrist body their hand does not have, are lost,
and reading the grasp back gives the wrist at 0. A hand with a joint below the body that they
lack, or without one of their joints or their body, is refused (:class:`sim.errors.DexaugError`
naming the hand, what is missing and the table that declared it).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from augment.dataset import ObjectTable
from sim.errors import DexaugError
from sim.hand.config import hand_format
from sim.hand.model import Hand
from sim.transforms import pose_inv, pose_mul

__all__ = ["ForeignHand", "need_columns", "same_joints", "split_pose"]


def need_columns(table: ObjectTable, names: Sequence[str], where: str, layout: str) -> None:
    """Refuse (one line naming ``where``) a table without the columns a layout needs, or with
    a ``palm_pose`` / ``hand_pose`` of the wrong shape."""
    missing = [c for c in names if c not in table.columns]
    if missing:
        raise DexaugError(f"{where}: no column {', '.join(missing)} (the {layout} layout needs "
                          f"{', '.join(names)})")
    n = len(table)
    shapes = {"palm_pose": (n, 7), "hand_pose": (n, len(table.joint_names)), "gws": (n,)}
    for col in names:
        want = shapes.get(col)
        got = np.shape(table.columns[col])
        if want is not None and got != want:
            raise DexaugError(f"{where}: column {col} has shape {got}, expected {want}")


def same_joints(table: ObjectTable, hand: Hand, where: str) -> None:
    if tuple(table.joint_names) != tuple(hand.joint_names):
        raise DexaugError(f"{where}: the table's joints ({len(table.joint_names)}: "
                          f"{', '.join(table.joint_names[:3])} …) are not hand {hand.name!r}'s")


def split_pose(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[x, y, z, qw, qx, qy, qz]`` rows → positions and unit quaternions (float64)."""
    pose = np.asarray(pose, dtype=float)
    return pose[..., :3], pose[..., 3:] / np.linalg.norm(pose[..., 3:], axis=-1, keepdims=True)


class ForeignHand:
    """Our ``hand`` as the ``layout`` format's hand sees it (module docstring): placed by the
    pose of ``body``, with the joints ``joints`` in that order, both from the hand's
    ``[formats.<layout>]``."""

    def __init__(self, hand: Hand, layout: str) -> None:
        fmt = hand_format(hand.config, layout, hand.joint_names,
                          f"be written in the {layout} layout")
        self.hand, self.layout, self.body, self.joints = hand, layout, fmt.body, fmt.joint_order
        body, their_hand = fmt.body, fmt.their_hand
        declared = f"(as {hand.config.file} [formats.{layout}] declares)"
        m = hand.model
        names = hand.joint_names
        bodies = {m.body(b).name for b in range(m.nbody)}
        missing = [j for j in self.joints if j not in names] + ([body] if body not in bodies else [])
        if missing:
            raise DexaugError(
                f"hand {hand.name!r} cannot be written in the {layout} layout: {their_hand} is "
                f"placed by its body {body!r} and has the {len(self.joints)} joints "
                f"{self.joints[0]} … {self.joints[-1]} {declared}; hand {hand.name!r} lacks "
                f"{', '.join(missing[:4])}{f' and {len(missing) - 4} more' if len(missing) > 4 else ''}")
        self.index = np.array([names.index(j) for j in self.joints])
        self.body_id = m.body(body).id
        above = _self_and_ancestors(m.body_parentid, self.body_id)
        self.dropped = tuple(j for j in names if j not in self.joints)
        for j in self.dropped:
            if int(m.jnt_bodyid[m.joint(j).id]) not in above:
                raise DexaugError(
                    f"hand {hand.name!r} cannot be written in the {layout} layout: its joint "
                    f"{j!r} moves bodies below {body!r}, and {their_hand} has no such joint "
                    f"{declared}")
        if self.body_id not in _self_and_ancestors(m.body_parentid, hand.palm_body_id):
            raise DexaugError(
                f"hand {hand.name!r} cannot be written in the {layout} layout: its frame_palm "
                f"body {hand.config.palm.body!r} is not {body!r} or below it")
        self.dropped_index = np.array([names.index(j) for j in self.dropped], dtype=int)

    # ----------------------------------------------------------------------------- kinematics

    def body_in_palm(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Their body's pose in frame_palm for joint vectors q (N, nq): (N,3), (N,4) wxyz, by
        forward kinematics of our model."""
        pos, quat = self.hand.body_poses(np.atleast_2d(q))
        cfg, b = self.hand.config.palm, self.hand.palm_body_id
        palm = pose_mul(pos[:, b], quat[:, b], cfg.pos, cfg.quat_wxyz)
        return pose_mul(*pose_inv(*palm), pos[:, self.body_id], quat[:, self.body_id])

    def to_body(self, palm_pose: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """frame_palm poses (N,7) with joints q (N,nq) → their body's poses in the same frame."""
        return pose_mul(*split_pose(palm_pose), *self.body_in_palm(q))

    def full_q(self, theirs: np.ndarray) -> np.ndarray:
        """Their joint vectors (N, len(joints)) → ours (N, nq), dropped joints at 0."""
        theirs = np.atleast_2d(np.asarray(theirs, dtype=float))
        q = np.zeros((len(theirs), self.hand.nq))
        q[:, self.index] = theirs
        return q

    def from_body(self, body_pose: np.ndarray, theirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Their body's poses (N,7) and joints (N, len(joints)) → our frame_palm poses (N,7) in
        the same frame and our joint vectors (N,nq) (dropped joints at 0)."""
        q = self.full_q(theirs)
        palm_p, palm_q = pose_mul(*split_pose(body_pose), *pose_inv(*self.body_in_palm(q)))
        return np.c_[palm_p, palm_q], q

    def dropped_moved(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: grasps whose dropped joints are not all at 0."""
        q = np.atleast_2d(q)
        if not len(self.dropped_index):
            return np.zeros(len(q), bool)
        return np.any(q[:, self.dropped_index] != 0.0, axis=1)

    def parent_in_body(self) -> tuple[np.ndarray, np.ndarray]:
        """Where our model hangs the body from: its parent body's frame in the body's frame with
        every joint at 0 (the Shadow Hand: ``rh_wrist``, 34 mm behind ``rh_palm``)."""
        pos, quat = self.hand.body_poses(np.zeros(self.hand.nq))
        parent = int(self.hand.model.body_parentid[self.body_id])
        body_in_parent = pose_mul(*pose_inv(pos[0, parent], quat[0, parent]),
                                  pos[0, self.body_id], quat[0, self.body_id])
        return pose_inv(*body_in_parent)


def _self_and_ancestors(parent: np.ndarray, body: int) -> set[int]:
    out = {body}
    while body:
        body = int(parent[body])
        out.add(body)
    return out
