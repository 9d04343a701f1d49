"""Hand–object contacts of a scene as recorder records, tagged with the touching fingertip.

One function for every recorder of simulated grasps (the live bridge, scripted
demonstrations), so their ``/contacts`` mean the same thing: world, object-frame and hand-body
positions and normals, and ``finger`` set only when the touching body is a fingertip body.
"""

from __future__ import annotations

from sim.world.contacts import contacts_between
from sim.world.scene import HAND_PREFIX, Scene
from teleop.record.contact_record import ContactRecord

__all__ = ["contact_records", "tip_finger_bodies"]


def tip_finger_bodies(scene: Scene) -> dict[int, str]:
    """Scene body id of each fingertip body → finger name."""
    m, hand = scene.model, scene.hand
    return {int(m.body(HAND_PREFIX + hand.model.body(b).name).id): f
            for b, f in zip(hand.tip_body_ids, hand.finger_names, strict=True)}


def contact_records(scene: Scene, tip_fingers: dict[int, str]) -> list[ContactRecord]:
    """Hand–object contacts of the scene's current state (after a step or ``mj_forward``)."""
    c = contacts_between(scene.model, scene.data, scene.hand_geom_mask, scene.obj_geom_mask)
    if len(c.dist) == 0:
        return []
    opos, oquat = scene.object_pose()
    out = []
    for i in range(len(c.dist)):
        b = int(c.body_a[i])
        name = scene.model.body(b).name
        out.append(ContactRecord.from_world(
            finger=tip_fingers.get(b),
            hand_body=name[len(HAND_PREFIX):] if name.startswith(HAND_PREFIX) else name,
            pos_world_m=c.pos[i], normal_world=c.normal[i], dist_m=float(c.dist[i]),
            object_pos_m=opos, object_quat_wxyz=oquat, body_pos_m=scene.data.xpos[b],
            body_quat_wxyz=scene.data.xquat[b]))
    return out
