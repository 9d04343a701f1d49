"""The hand–arm–table scene: an arm from its config, the hand on its flange, a table and
optionally a free object, composed with ``mujoco.MjSpec`` (no XML strings).

The hand is attached at the arm's flange site through the hand config's ``[mount]`` pose, so
the same hand fits every arm whose flange site has +z along the tool axis. A ``frame_palm``
site is added on the hand's palm body at the config's palm offset: it is the frame whole-body
IK (:mod:`sim.arm.ik`) puts on a grasp's palm pose. World units: metres, floor at z = 0.
Index maps (qpos addresses of the arm joints in config order, of the hand joints in
``Hand.joint_names`` order, of the object's free joint) let callers write joint vectors
without knowing the model's layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from sim.arm.config import ArmConfig
from sim.errors import ConfigError
from sim.hand.model import Hand
from sim.transforms import pose_mul
from sim.world.hand_spec import ServoSettings, apply_servos
from sim.world.object_spec import FREE_JOINT_NAME, ContactParams
from sim.world.objects import ObjectAsset
from sim.world.scene import HAND_PREFIX, OBJECT_PREFIX, PhysicsOptions

ARM_PREFIX = "arm/"
PALM_SITE = "frame_palm"
TABLE_GEOM = "table"
#: options the composed world sets and its parts are given (MjSpec.attach warns on conflicts)
_OPTION_KEYS = ("timestep", "integrator", "cone", "impratio", "noslip_iterations", "iterations")


@dataclass(frozen=True)
class TableSpec:
    """A box table (metres, world frame): the top at ``top_z_m``, centred at ``center_xy_m``.
    The default puts its near edge 0.25 m in front of an arm base at the origin, so the object
    area 0.45–0.7 m in front of the base lies well inside it."""

    top_z_m: float = 0.75
    center_xy_m: tuple[float, float] = (0.6, 0.0)
    half_size_xy_m: tuple[float, float] = (0.35, 0.6)
    thickness_m: float = 0.04

    @property
    def object_home(self) -> np.ndarray:
        """Where an object starts (metres): over the table centre, 0.1 m above its top."""
        return np.array([*self.center_xy_m, self.top_z_m + 0.1])


def _match_options(world: mujoco.MjSpec, child: mujoco.MjSpec) -> None:
    """Give a part the world's solver options: the composed scene's options rule."""
    for key in _OPTION_KEYS:
        setattr(child.option, key, getattr(world.option, key))


def _collision_geoms(m: mujoco.MjModel, bodies: np.ndarray) -> np.ndarray:
    """Geoms of the given bodies that take part in contacts (visual meshes do not)."""
    mask = bodies[m.geom_bodyid] & ((m.geom_contype != 0) | (m.geom_conaffinity != 0))
    return np.flatnonzero(mask)


class ArmScene:
    """A compiled arm + hand (+ table, + object) model with its index maps.

    ``contact`` goes on the table and the object (as in :class:`sim.world.scene.Scene`);
    ``servos`` (when given) sets the hand's position servos as a validation protocol does.
    Attributes: ``arm_qadr`` / ``arm_dadr`` (arm joints, config order), ``hand_qadr`` /
    ``hand_dadr`` (``Hand.joint_names`` order), ``obj_qadr`` / ``obj_dadr`` (-1 without an
    object), ``palm_site``, ``flange_site``, ``arm_geoms`` / ``hand_geoms`` / ``obj_geoms``
    (collision geom ids),
    ``table_geom`` (-1 without a table).
    """

    def __init__(self, arm: ArmConfig, hand: Hand, obj: ObjectAsset | None = None, *,
                 table: TableSpec | None = TableSpec(), contact: ContactParams | None = None,
                 servos: ServoSettings | None = None) -> None:
        if hand.config.mount is None:
            raise ConfigError(f"{hand.config.file}: mount: hand {hand.name!r} has no [mount] table "
                              "(its pose on an arm's flange), so it cannot go on an arm")
        self.arm, self.hand, self.obj, self.table = arm, hand, obj, table
        self.contact = contact or ContactParams()
        self.servos = servos
        self.spec = self._compose()
        self.model = self.spec.compile()
        self.data = mujoco.MjData(self.model)
        self._index()

    # ------------------------------------------------------------------------------ composition

    def _compose(self) -> mujoco.MjSpec:
        world = mujoco.MjSpec()
        world.modelname = f"dexaug_{self.arm.name}_{self.hand.name}"
        opts = PhysicsOptions()
        world.option.timestep = opts.timestep_s
        world.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        world.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        world.option.impratio = opts.impratio
        world.option.noslip_iterations = opts.noslip_iterations
        world.option.iterations = opts.solver_iterations
        world.worldbody.add_light(name="key", pos=[0.6, -0.8, 2.2], dir=[-0.2, 0.4, -1.0],
                                  diffuse=[0.8, 0.8, 0.8])
        arm_spec = mujoco.MjSpec.from_file(str(self.arm.model_path))
        for key in list(arm_spec.keys):   # the arm's keyframes would not fit the composed qpos
            arm_spec.delete(key)
        _match_options(world, arm_spec)
        arm_model = arm_spec.compile()
        base = world.worldbody.add_frame(pos=self.arm.base_pos_m, quat=self.arm.base_quat_wxyz)
        world.attach(arm_spec, prefix=ARM_PREFIX, frame=base)
        self._add_pedestal(world)

        # the flange in its body frame as MuJoCo compiles it: the spec keeps the XML's raw
        # orientation (UR5e: quat="-1 1 0 0", unnormalised; other files use euler/axisangle)
        flange = arm_model.site(self.arm.flange_site)
        site = world.site(ARM_PREFIX + self.arm.flange_site)
        mount = self.hand.config.mount
        assert mount is not None   # __init__ refused a hand without one
        pos, quat = pose_mul(flange.pos.copy(), flange.quat.copy(), mount.pos, mount.quat_wxyz)
        hand_frame = site.parent.add_frame(pos=pos, quat=quat)
        hand_spec = self.hand.spec()
        _match_options(world, hand_spec)
        if self.servos is not None:   # the hand's servos as a protocol simulates them
            apply_servos(hand_spec, self.servos)
        world.attach(hand_spec, prefix=HAND_PREFIX, frame=hand_frame)
        palm_cfg = self.hand.config.palm
        world.body(HAND_PREFIX + palm_cfg.body).add_site(
            name=PALM_SITE, pos=palm_cfg.pos, quat=palm_cfg.quat_wxyz, size=[0.005, 0, 0], group=4,
            rgba=[0.2, 0.8, 0.2, 1])

        # the arm's controller compensates the weight of arm and hand, as an industrial arm's
        # does (and as the hand-only validator's floating hand is): without it the Menagerie
        # servos sag 8° under the hand and sweep it into the object (measured, UR5e)
        for body in world.bodies:
            if body.name.startswith((ARM_PREFIX, HAND_PREFIX)):
                body.gravcomp = 1.0
        if self.table is not None:
            t = self.table
            world.worldbody.add_geom(
                name=TABLE_GEOM, type=mujoco.mjtGeom.mjGEOM_BOX,
                size=[*t.half_size_xy_m, t.thickness_m / 2],
                pos=[*t.center_xy_m, t.top_z_m - t.thickness_m / 2], rgba=[0.55, 0.45, 0.35, 1.0],
                friction=list(self.contact.friction), solref=list(self.contact.solref))
        if self.obj is not None:
            home = self.table.object_home if self.table is not None else np.array([0.6, 0.0, 0.1])
            obj_spec = self.obj.spec(self.contact)
            _match_options(world, obj_spec)
            world.attach(obj_spec, prefix=OBJECT_PREFIX,
                         frame=world.worldbody.add_frame(pos=home))
        return world

    def _add_pedestal(self, world: mujoco.MjSpec) -> None:
        """A drawn (contact-free) column from the floor to the arm base: what it stands on."""
        height = float(self.arm.base_pos_m[2])
        if height > 1e-3:
            world.worldbody.add_geom(
                name="pedestal", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.09, height / 2, 0],
                pos=[*self.arm.base_pos_m[:2], height / 2], contype=0, conaffinity=0,
                rgba=[0.3, 0.3, 0.33, 1.0])

    def _index(self) -> None:
        m = self.model
        self.arm_qadr = np.array([m.joint(ARM_PREFIX + j).qposadr[0] for j in self.arm.joints])
        self.arm_dadr = np.array([m.joint(ARM_PREFIX + j).dofadr[0] for j in self.arm.joints])
        self.hand_qadr = np.array([m.joint(HAND_PREFIX + j).qposadr[0] for j in self.hand.joint_names])
        self.hand_dadr = np.array([m.joint(HAND_PREFIX + j).dofadr[0] for j in self.hand.joint_names])
        self.hand_ik_free = self._ik_free_joints()
        names = [m.body(b).name for b in range(m.nbody)]
        arm_bodies = np.array([n.startswith(ARM_PREFIX) for n in names])
        hand_bodies = np.array([n.startswith(HAND_PREFIX) for n in names])
        self.arm_geoms = _collision_geoms(m, arm_bodies)
        self.hand_geoms = _collision_geoms(m, hand_bodies)
        self.obj_geoms = _collision_geoms(m, np.array([n.startswith(OBJECT_PREFIX) for n in names]))
        self.palm_site = m.site(PALM_SITE).id
        self.flange_site = m.site(ARM_PREFIX + self.arm.flange_site).id
        self.table_geom = m.geom(TABLE_GEOM).id if self.table is not None else -1
        if self.obj is not None:
            joint = m.joint(OBJECT_PREFIX + FREE_JOINT_NAME)
            self.obj_qadr, self.obj_dadr = int(joint.qposadr[0]), int(joint.dofadr[0])
        else:
            self.obj_qadr = self.obj_dadr = -1
        self.lower = m.jnt_range[:, 0]  # joint limits (rad / m) of every joint, for clipping
        self.upper = m.jnt_range[:, 1]

    def _ik_free_joints(self) -> np.ndarray:
        """Indices (``Hand.joint_names`` order) of the mount's ``ik_free_joints``, each checked
        against the hand's joints (a misspelt one would silently stay frozen)."""
        mount = self.hand.config.mount
        assert mount is not None   # __init__ refused a hand without one
        unknown = [j for j in mount.ik_free_joints if j not in self.hand.joint_names]
        if unknown:
            raise ConfigError(f"{self.hand.config.file}: [mount] ik_free_joints: expected joints "
                              f"of the hand, got unknown {unknown}")
        return np.array([self.hand.joint_names.index(j) for j in mount.ik_free_joints], int)

    # ---------------------------------------------------------------------------- joint vectors

    def qpos(self, arm_q: np.ndarray | None = None, hand_q: np.ndarray | None = None) -> np.ndarray:
        """A full qpos: the model's defaults with the arm joints (config order, rad; home when
        None) and the hand joints (``Hand.joint_names`` order; the hand's open pose when None)."""
        q = self.model.qpos0.copy()
        q[self.arm_qadr] = self.arm.home_rad if arm_q is None else np.asarray(arm_q, float)
        q[self.hand_qadr] = self.hand.open_pose if hand_q is None else np.asarray(hand_q, float)
        return q

    def arm_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper limits (rad) of the arm joints in config order (±inf if unlimited)."""
        m = self.model
        ids = np.array([m.joint(ARM_PREFIX + j).id for j in self.arm.joints])
        limited = m.jnt_limited[ids].astype(bool)
        return (np.where(limited, m.jnt_range[ids, 0], -np.inf),
                np.where(limited, m.jnt_range[ids, 1], np.inf))

    def site_pose(self, qpos: np.ndarray, site: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """World pose (metres, wxyz) of a site (frame_palm by default) at a full qpos."""
        site = self.palm_site if site is None else site
        d = self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, d.site_xmat[site])
        return d.site_xpos[site].copy(), quat

    def table_clearance_m(self, qpos: np.ndarray, cap_m: float = 1.0) -> float:
        """Smallest distance (metres) between the arm + hand collision geoms and the table at a
        full qpos (negative: penetration); ``inf`` without a table or when all exceed ``cap_m``."""
        if self.table_geom < 0:
            return float("inf")
        d = self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        fromto = np.zeros(6)
        dists = [mujoco.mj_geomDistance(self.model, d, int(g), self.table_geom, cap_m, fromto)
                 for g in np.concatenate([self.arm_geoms, self.hand_geoms])]
        return min((x for x in dists if x < cap_m), default=float("inf"))
