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

Resting poses (:func:`rest_home`): the object need not stand upright. Its stable resting poses
(:func:`sim.world.resting.resting_poses`, found by dropping it in the scene's physics and
cached) are offered by index, best first; the chosen one, turned by a yaw about the table
normal, is put on the object's spot with its lowest point 1 mm above the table and then placed
as above (demo: dropped in that orientation, settled, held). Index None is the home pose
(upright at the config's ``object_yaw_deg``). Every placement names the pose it used
(:class:`RestChoice`, ``object_rest`` in :meth:`Placement.to_json`).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from sim.world.resting import RestPoses, rest_placement, resting_poses
from sim.world.scene import Scene
from teleop.bridge.config import BridgeConfig

__all__ = ["Placement", "RestChoice", "place_object", "rest_home", "rest_request",
           "scene_rest_poses", "table_record"]

logger = logging.getLogger(__name__)
Array = np.ndarray


@dataclass(frozen=True)
class RestChoice:
    """The resting pose an object was put in: ``index`` into its resting poses (None: the home
    pose, upright), ``yaw_deg`` about the table normal, the orientation it was put down in
    (``quat_wxyz``, before any drop), whether that is ``upright``, the pose's ``share`` of the
    drops that reached it (None for the home pose) and ``poses_key`` (the first 16 hex digits of
    the resting-pose computation's key: an index means that computation's pose)."""

    index: int | None
    yaw_deg: float
    quat_wxyz: tuple[float, ...]
    upright: bool
    share: float | None = None
    poses_key: str | None = None

    def to_json(self) -> dict[str, Any]:
        return {"index": self.index, "yaw_deg": round(self.yaw_deg, 6),
                "quat_wxyz": [round(v, 6) for v in self.quat_wxyz], "upright": self.upright,
                "share": self.share, "poses_key": self.poses_key}


@dataclass(frozen=True)
class Placement:
    """How the object was placed: its mode, and in demo mode how the drop went (``settled``:
    it came to rest within the timeout; ``settle_s``: simulated seconds of the drop;
    ``speed_mps``: its fastest point's speed when held; no drop without a table: ``settled``
    None; ``rest``: the resting pose it was put in)."""

    mode: str
    settled: bool | None = None
    settle_s: float = 0.0
    speed_mps: float = 0.0
    rest: RestChoice | None = None

    def to_json(self) -> dict[str, Any]:
        """The event payload fields (``object_mode``, the resting pose as ``object_rest`` and,
        in demo mode, the drop's outcome)."""
        out: dict[str, Any] = {"object_mode": self.mode}
        if self.rest is not None:
            out["object_rest"] = self.rest.to_json()
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


def scene_rest_poses(scene: Scene) -> RestPoses:
    """The resting poses of the scene's object in the scene's own physics and contact settings
    (computed on first use, then read from the cache)."""
    if scene.obj is None:
        raise ValueError("this scene has no object to rest")
    return resting_poses(scene.obj, physics=scene.physics, contact=scene.contact)


def rest_request(command: str, args: dict[str, Any], *,
                 only_rest: bool = False) -> tuple[int | None, float | None]:
    """The resting pose ``rest`` (an int index, or absent/None) and ``yaw_deg`` (a finite number
    of degrees wrapped to [-180, 180), or absent) of ``command``'s arguments; ValueError naming
    the field (and with ``only_rest`` any other argument). The index's range depends on the
    object and is checked where its poses are known (:func:`rest_home`)."""
    refused = sorted(k for k in args if k not in ("rest", "yaw_deg")) if only_rest else []
    if refused:
        raise ValueError(f"{command}: {refused} not accepted; pass 'rest' (a resting pose index) "
                         "and optionally 'yaw_deg'")
    rest, yaw = args.get("rest"), args.get("yaw_deg")
    if rest is not None and (isinstance(rest, bool) or not isinstance(rest, int)):
        raise ValueError(f"{command}: rest: expected a resting pose index (an integer), got "
                         f"{str(rest)[:80]!r}")
    if yaw is None:
        return rest, None
    if rest is None:
        raise ValueError(f"{command}: yaw_deg needs a resting pose index 'rest' (the upright "
                         "home pose turns by the config's object_yaw_deg)")
    if isinstance(yaw, bool) or not isinstance(yaw, int | float) or not math.isfinite(yaw):
        raise ValueError(f"{command}: yaw_deg: expected a finite number of degrees, got "
                         f"{str(yaw)[:80]!r}")
    return rest, (float(yaw) + 180.0) % 360.0 - 180.0


def rest_home(scene: Scene, home: tuple[Array, Array], index: int | None,
              yaw_deg: float) -> tuple[tuple[Array, Array], RestChoice]:
    """Where to put the object for resting pose ``index`` turned by ``yaw_deg`` on the spot of
    ``home`` (the bridge's upright home pose; index None: ``home`` itself, whose yaw is the
    config's ``yaw_deg``), and the choice as recorded (module docstring). ValueError when
    ``index`` names no pose of the object."""
    if index is None:
        return home, RestChoice(None, yaw_deg, tuple(map(float, home[1])), upright=True)
    poses = scene_rest_poses(scene)
    pose = poses[poses.check_index(index, "object_rest")]
    table = table_record(scene)
    if table is not None and scene.obj is not None:
        pos, quat = rest_placement(scene.obj, pose, home[0][:2], yaw_deg, top_z_m=table["top_z_m"])
    else:   # nothing to rest on: at the home height, in the pose's orientation
        pos, quat = np.array(home[0], float), pose.quat_at_yaw(yaw_deg)
    return (pos, quat), RestChoice(index, yaw_deg, tuple(map(float, quat)), pose.upright,
                                   pose.share, poses.key[:16])


def place_object(scene: Scene, home: tuple[Array, Array], mode: str,
                 cfg: BridgeConfig, rest: RestChoice | None = None) -> Placement:
    """Put the object at ``home`` (world position, wxyz) for ``mode`` (module docstring);
    ``rest``: the resting pose ``home`` puts it in, recorded in the placement."""
    scene.release_object()
    scene.set_object_pose(*home)
    name = scene.obj.name if scene.obj is not None else "object"
    if mode == "free":
        placement = Placement("free", rest=rest)
    elif scene.table_geom < 0:
        placement = Placement("demo", rest=rest)
        scene.hold_object()
        logger.info("%s held at its home pose (no table to drop it onto)", name)
    else:
        pos, quat, placement = _settle(scene, cfg)
        placement = dataclasses.replace(placement, rest=rest)
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
