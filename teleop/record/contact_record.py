"""One hand–object contact as a session records it (``/contacts``), in three frames at once.

Why a record of its own: the bridge (:mod:`teleop.bridge.scene_contacts`) and the scripted
recorder make these from MuJoCo contacts, the recorder writes them (and draws them,
:func:`teleop.record.foxglove.contact_entity`), and demo extraction reads their JSON back: the
object-frame point is what the augmenter needs, the fingertip-frame point is what AutoWS centres
its contact faces on. Units: metres, unit normals from the hand into the object, newtons.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim import transforms
from teleop.record.schemas import finite_list

__all__ = ["ContactRecord", "contacts_payload"]

Array = np.ndarray


@dataclass
class ContactRecord:
    """One hand–object contact as recorded on ``/contacts``.

    Positions metres, normals unit vectors from the hand into the object (the direction of the
    force the hand applies, as :mod:`sim.world.contacts`), each expressed in the world, in the object
    frame (``frame_obj``) and in the frame of ``hand_body`` (the fingertip body for fingertip
    contacts: what AutoWS needs). ``dist_m`` is the signed distance (negative = penetration),
    ``force_n`` the normal force in newtons (NaN when not computed).
    """

    finger: str | None
    hand_body: str
    pos_world_m: Array
    normal_world: Array
    pos_object_m: Array
    normal_object: Array
    pos_hand_body_m: Array
    normal_hand_body: Array
    dist_m: float
    force_n: float = float("nan")

    @classmethod
    def from_world(cls, *, finger: str | None, hand_body: str, pos_world_m: Any,
                   normal_world: Any, dist_m: float, object_pos_m: Any, object_quat_wxyz: Any,
                   body_pos_m: Any, body_quat_wxyz: Any,
                   force_n: float = float("nan")) -> ContactRecord:
        """Express a world contact in the object and hand-body frames, given both frames'
        world poses (metres, quaternions wxyz)."""
        p = np.asarray(pos_world_m, dtype=float)
        n = np.asarray(normal_world, dtype=float)
        inv_obj_p, inv_obj_q = transforms.pose_inv(np.asarray(object_pos_m, float),
                                                        np.asarray(object_quat_wxyz, float))
        inv_body_p, inv_body_q = transforms.pose_inv(np.asarray(body_pos_m, float),
                                                          np.asarray(body_quat_wxyz, float))
        return cls(finger=finger, hand_body=hand_body, pos_world_m=p, normal_world=n,
                   pos_object_m=inv_obj_p + transforms.rotate(inv_obj_q, p),
                   normal_object=transforms.rotate(inv_obj_q, n),
                   pos_hand_body_m=inv_body_p + transforms.rotate(inv_body_q, p),
                   normal_hand_body=transforms.rotate(inv_body_q, n),
                   dist_m=float(dist_m), force_n=float(force_n))

    def to_json(self) -> dict[str, Any]:
        """The ``dexaug.Contact`` JSON object."""
        force = float(self.force_n)
        dist = float(self.dist_m)
        return {"finger": self.finger, "hand_body": self.hand_body,
                "pos_world_m": finite_list(self.pos_world_m),
                "normal_world": finite_list(self.normal_world),
                "pos_object_m": finite_list(self.pos_object_m),
                "normal_object": finite_list(self.normal_object),
                "pos_hand_body_m": finite_list(self.pos_hand_body_m),
                "normal_hand_body": finite_list(self.normal_hand_body),
                "dist_m": dist if np.isfinite(dist) else None,
                "force_n": force if np.isfinite(force) else None}

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> ContactRecord:
        """Inverse of :meth:`to_json` (``None`` numbers come back as NaN)."""
        def arr(key: str) -> Array:
            return np.array([np.nan if v is None else v for v in obj[key]], dtype=float)

        def num(key: str) -> float:
            v = obj.get(key)
            return float("nan") if v is None else float(v)

        return cls(finger=obj.get("finger"), hand_body=obj["hand_body"],
                   pos_world_m=arr("pos_world_m"), normal_world=arr("normal_world"),
                   pos_object_m=arr("pos_object_m"), normal_object=arr("normal_object"),
                   pos_hand_body_m=arr("pos_hand_body_m"),
                   normal_hand_body=arr("normal_hand_body"), dist_m=num("dist_m"),
                   force_n=num("force_n"))


def contacts_payload(contacts: Sequence[ContactRecord], *, t_s: float, seq: int | None,
                     object_name: str | None) -> dict[str, Any]:
    """A ``/contacts`` payload (``dexaug.Contacts``, possibly with no contact); shared by the
    recorder and the bridge's live Foxglove server, so both publish the same JSON."""
    return {"t_s": float(t_s), "seq": None if seq is None else int(seq),
            "contacts": [c.to_json() for c in contacts], "object": object_name}
