"""Placing the bridge's object for the operator: settled and held (demo mode) or free.

Why (DESIGN §6, the paper's demonstration mode): an operator's approach is never perfect, and
a light object knocked over or pushed away before the fingers close ruins the demonstration.
In ``"demo"`` mode every placement (scene build, ``choose_object``, ``reset_object``,
``set_object_mode``) drops the object from its home pose onto the table, simulates it until it settles and
then welds it to the world (:meth:`sim.world.scene.Scene.hold_object`), so the hand's contacts
and contact forces act on a fixed object. In ``"free"`` mode the object is put at its home pose
and stays a free body, to be lifted for real.

The drop runs in a scratch copy of the scene's data: the live simulation's clock, hand and
controls are untouched, so a placement during a recording adds no simulated time and the next
``/state`` already records the settled pose. Settled means the fastest point of the object
(linear speed plus angular speed times its bounding radius, m/s) stayed below
``settle_speed_mps`` for ``settle_still_s``; after ``settle_timeout_s`` of simulated time it is
held where it is, with a warning. A scene without a table has nothing to drop onto: there the
object is held at its home pose.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from sim.world.scene import Scene
from teleop.bridge.config import BridgeConfig

__all__ = ["Placement", "place_object", "table_record"]

logger = logging.getLogger(__name__)
Array = np.ndarray


@dataclass(frozen=True)
class Placement:
    """How the object was placed: its mode, and in demo mode how the drop went (``settled``:
    it came to rest within the timeout; ``settle_s``: simulated seconds of the drop;
    ``speed_mps``: its fastest point's speed when held; no drop without a table: ``settled``
    None)."""

    mode: str
    settled: bool | None = None
    settle_s: float = 0.0
    speed_mps: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """The event payload fields (``object_mode`` and, in demo mode, the drop's outcome)."""
        out: dict[str, Any] = {"object_mode": self.mode}
        if self.mode == "demo":
            out.update(settled=self.settled, settle_s=round(self.settle_s, 6),
                       settle_speed_mps=round(self.speed_mps, 6))
        return out


def _radius_m(scene: Scene) -> float:
    """The object's bounding radius about its body origin (metres)."""
    m, geoms = scene.model, np.flatnonzero(scene.obj_geom_mask)
    return float(max(m.geom_rbound[g] + np.linalg.norm(m.geom_pos[g]) for g in geoms))


def _settle(scene: Scene, cfg: BridgeConfig) -> tuple[Array, Array, Placement]:
    """Drop the (released) object from its current pose in a scratch copy of the data; its
    resting pose and how the drop went."""
    m = scene.model
    d = mujoco.MjData(m)
    mujoco.mj_copyData(d, m, scene.data)
    dt = float(m.opt.timestep)
    still_steps = max(1, math.ceil(cfg.settle_still_s / dt))
    max_steps = math.ceil(cfg.settle_timeout_s / dt)
    radius, a = _radius_m(scene), scene.obj_dadr
    still, speed, steps = 0, 0.0, 0
    while steps < max_steps and still < still_steps:
        mujoco.mj_step(m, d)
        steps += 1
        speed = float(np.linalg.norm(d.qvel[a:a + 3]) + radius * np.linalg.norm(d.qvel[a + 3:a + 6]))
        still = still + 1 if speed < cfg.settle_speed_mps else 0
    q = scene.obj_qadr
    pos, quat = d.qpos[q:q + 3].copy(), d.qpos[q + 3:q + 7].copy()
    return pos, quat, Placement("demo", still >= still_steps, steps * dt, speed)


def place_object(scene: Scene, home: tuple[Array, Array], mode: str,
                 cfg: BridgeConfig) -> Placement:
    """Put the object at ``home`` (world position, wxyz) for ``mode`` (module docstring)."""
    scene.release_object()
    scene.set_object_pose(*home)
    name = scene.obj.name if scene.obj is not None else "object"
    if mode == "free":
        placement = Placement("free")
    elif scene.table_geom < 0:
        placement = Placement("demo")
        scene.hold_object()
        logger.info("%s held at its home pose (no table to drop it onto)", name)
    else:
        pos, quat, placement = _settle(scene, cfg)
        scene.set_object_pose(pos, quat)
        scene.hold_object()
        if placement.settled:
            logger.info("%s settled at z = %.4f m after %.3f s (simulated) and is held", name,
                        pos[2], placement.settle_s)
        else:
            logger.warning("%s did not settle within %.1f s (simulated; still at %.3f m/s): held "
                           "where it is, z = %.4f m", name, cfg.settle_timeout_s,
                           placement.speed_mps, pos[2])
    mujoco.mj_forward(scene.model, scene.data)
    return placement


def table_record(scene: Scene) -> dict[str, Any] | None:
    """The scene's table in the world, as sessions record it (``top_z_m``, ``center_m`` [x, y],
    ``half_extents_m`` [hx, hy], metres), read off the compiled table geom; None without one."""
    if scene.table_geom < 0:
        return None
    pos, size = scene.model.geom_pos[scene.table_geom], scene.model.geom_size[scene.table_geom]
    return {"top_z_m": float(pos[2] + size[2]), "center_m": [float(pos[0]), float(pos[1])],
            "half_extents_m": [float(size[0]), float(size[1])]}
