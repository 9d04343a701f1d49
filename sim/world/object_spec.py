"""The layout every object spec has, and the contact parameters its collision geoms get.

YCB files (:mod:`sim.world.ycb_xml`) and procedural primitives (:mod:`sim.world.primitives`)
both become a ``mujoco.MjSpec`` with one body ``object`` holding the free joint ``object_free``
at the object frame, collision geoms in group 3 and visual geoms in group 2 with no mass;
:func:`finish_spec` applies the groups and a :class:`ContactParams` to such a spec, so every
scene sees objects the same way. Units: seconds (solref time constant), metres (solimp width).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

__all__ = ["BODY_NAME", "COLLISION_GROUP", "FREE_JOINT_NAME", "VISUAL_GROUP", "ContactParams",
           "apply_contact", "finish_spec", "is_collision"]

BODY_NAME = "object"
FREE_JOINT_NAME = "object_free"
VISUAL_GROUP = 2
COLLISION_GROUP = 3


@dataclass(frozen=True)
class ContactParams:
    """Contact parameters of a scene's collision geoms, hand and object alike (MuJoCo
    ``friction``, ``solref``, ``solimp``, ``condim``).

    The defaults replace the raw YCB values (friction 0.1, solref 0.001) that make grasps slip
    and contacts stiff enough to destabilise a 2–4 ms step. ``friction``: sliding, torsional,
    rolling coefficients; ``solref``: time constant (s) and damping ratio; ``solimp``: dmin,
    dmax, width (m).
    """

    friction: tuple[float, float, float] = (0.8, 0.005, 0.0001)
    solref: tuple[float, float] = (0.004, 1.0)
    solimp: tuple[float, float, float] = (0.95, 0.99, 0.001)
    condim: int = 4

    def __post_init__(self) -> None:
        if len(self.friction) != 3 or min(self.friction) < 0:
            raise ValueError(f"ContactParams.friction: expected 3 non-negative numbers, got {self.friction}")
        if len(self.solref) != 2:
            raise ValueError(f"ContactParams.solref: expected 2 numbers, got {self.solref}")
        if len(self.solimp) != 3:
            raise ValueError(f"ContactParams.solimp: expected 3 numbers, got {self.solimp}")
        if self.condim not in (1, 3, 4, 6):
            raise ValueError(f"ContactParams.condim: expected 1, 3, 4 or 6, got {self.condim}")


def is_collision(geom: mujoco.MjsGeom) -> bool:
    return geom.contype != 0 or geom.conaffinity != 0


def apply_contact(spec: mujoco.MjSpec, contact: ContactParams) -> None:
    """Give every collision geom of ``spec`` the contact parameters. A scene sets the same values
    on hand and object geoms, so that MuJoCo's mixing of two geoms' values (the larger friction,
    the mean solref/solimp at equal solmix) yields exactly these on every hand–object contact."""
    for geom in spec.geoms:
        if is_collision(geom):
            geom.friction = list(contact.friction)
            geom.solref = list(contact.solref)
            solimp = list(geom.solimp)
            solimp[:3] = contact.solimp
            geom.solimp = solimp
            geom.condim = contact.condim


def finish_spec(spec: mujoco.MjSpec, contact: ContactParams) -> mujoco.MjSpec:
    """Give collision geoms the contact parameters and group 3, visual geoms group 2 and no mass."""
    apply_contact(spec, contact)
    for geom in spec.geoms:
        if is_collision(geom):
            geom.group = COLLISION_GROUP
        else:
            geom.group = VISUAL_GROUP
            geom.mass = 0.0
    return spec
