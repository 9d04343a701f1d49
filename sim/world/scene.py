"""Scene composition: a floating hand, a free object and an optional table, built with MjSpec.

The hand's base gets a free joint and is welded to a mocap body, so the hand is moved by moving
the mocap target (6-DoF pose control) while contacts still see the hand's real velocity (a hand
that *is* a mocap body has zero velocity in the solver, which makes friction fight the lift).
Hand bodies are gravity-compensated, as a real arm-mounted hand's controller would do. All
composition goes through ``mujoco.MjSpec``; no XML strings are pasted together.

``object_hold`` adds an object-to-world weld, inactive until :meth:`Scene.hold_object`: the
teleop demonstration mode holds the settled object fixed while the operator grasps it (an
imperfect approach cannot knock it away), and contacts and contact forces work as before. A
scene built without it has no such constraint at all, so its physics is unchanged.

``floor_z_m`` adds a floor plane at that height (metres; below the table top): the teleop
bridge's object that falls off the table lands on it instead of falling forever. Off by
default: the validation scenes have none.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np

from sim.hand.model import Hand
from sim.transforms import pose_inv, pose_mul
from sim.world.hand_spec import ServoSettings, apply_servos, detach_palm
from sim.world.object_spec import ContactParams, apply_contact
from sim.world.objects import ObjectAsset

HAND_PREFIX = "hand/"
OBJECT_PREFIX = "obj/"
_HOLD = "object_hold"  # the optional object-to-world weld's name
TABLE_TOP_Z = 0.0
OBJECT_HOME = np.array([0.0, 0.0, 0.3])  # metres: where a floating object starts, in the world


@dataclass(frozen=True)
class PhysicsOptions:
    """Solver settings of a scene (seconds for the timestep)."""

    timestep_s: float = 0.004
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    impratio: float = 10.0
    noslip_iterations: int = 0
    solver_iterations: int = 100
    weld_solref: tuple[float, float] = (0.01, 1.0)
    #: the object hold's weld (``Scene(object_hold=True)``): stiff (the shortest time constant
    #: MuJoCo accepts at the default 4 ms step is 2 steps) and nearly hard (impedance 0.999+),
    #: so a hand driven into the held object is stopped by it: a teleop hand swept into a held
    #: 0.25 kg box moves it 0.2 mm at most, 1.3 mm with impedance 0.99, 10 mm with MuJoCo's 0.9
    hold_solref: tuple[float, float] = (0.008, 1.0)
    hold_solimp: tuple[float, float, float] = (0.999, 0.9999, 0.001)
    #: constraint Jacobians stored sparse: the hand's fingers are separate kinematic branches,
    #: so a contact row touches a few of the ~36 dofs; measured on 60 screwdriver lift-drop
    #: validations: 89–105 ms per grasp against 114 dense, same outcomes. None: MuJoCo's
    #: automatic choice (dense below 60 dofs), what the benchmark's scenes use.
    sparse_jacobian: bool | None = True
    #: collision: MuJoCo's convex–convex CCD iterations and whether it returns several contacts
    #: per convex pair (multi-CCD). None: this MuJoCo's defaults (4.x: 35 iterations, multi-CCD
    #: on); a protocol that reproduces a benchmark run on another MuJoCo sets that one's
    #: (DexGraspBench's 3.3.2: 50, off; sim/validate/protocols/dgb.py)
    ccd_iterations: int | None = None
    multiccd: bool | None = None
    #: the constraint solver per island of touching bodies. None: this MuJoCo's default (4.x:
    #: on; 3.3.x: off unless enabled, which DexGraspBench never does)
    islands: bool | None = None


_INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER,
                "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
                "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                "rk4": mujoco.mjtIntegrator.mjINT_RK4}
_CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}


def _set_jacobian_and_collision(option: mujoco.MjOption, opts: PhysicsOptions) -> None:
    """Set ``opts``' Jacobian storage, CCD iterations, multi-CCD and islands on a spec's options
    (None: MuJoCo's automatic choice, its default)."""
    option.jacobian = {True: mujoco.mjtJacobian.mjJAC_SPARSE, False: mujoco.mjtJacobian.mjJAC_DENSE,
                       None: mujoco.mjtJacobian.mjJAC_AUTO}[opts.sparse_jacobian]
    if opts.ccd_iterations is not None:
        option.ccd_iterations = opts.ccd_iterations
    for on, flag in ((opts.multiccd, mujoco.mjtDisableBit.mjDSBL_MULTICCD),
                     (opts.islands, mujoco.mjtDisableBit.mjDSBL_ISLAND)):
        if on is not None:
            option.disableflags = (option.disableflags & ~int(flag)) | (0 if on else int(flag))


class Scene:
    """A compiled hand + object (+ table) world and the index maps to drive and read it.

    ``contact`` goes on the object's (and the table's) collision geoms, and with
    ``contact_on_hand`` on the hand's too, so that it is what every hand–object contact
    simulates (a validation scene); without it the hand keeps its model's own values (the
    teleop scenes, whose hand is driven hard by the operator's tracking). ``servos`` sets the
    hand's position servos (gains, force and control limits). ``floating_palm`` makes the palm
    body the floating root: the joints on and above it are gone (the benchmark's wrist-less
    hand). ``object_mass_kg`` rescales the object's mass and inertia to that mass (centre of
    mass unchanged, as a uniform change of density does). ``floor_z_m``: a floor plane at that
    height (module docstring). Joint vectors and controls given to
    a scene always hold all of the hand model's joints (``Hand.joint_names``); a joint the
    scene does not have is ignored.
    """

    def __init__(self, hand: Hand, obj: ObjectAsset | None, *, table: bool = False,
                 contact: ContactParams | None = None,
                 physics: PhysicsOptions | None = None, servos: ServoSettings | None = None,
                 floating_palm: bool = False, object_mass_kg: float | None = None,
                 contact_on_hand: bool = False, object_hold: bool = False,
                 floor_z_m: float | None = None) -> None:
        self.hand = hand
        self.obj = obj
        self.table = table
        self.physics = physics or PhysicsOptions()
        self.contact = contact or ContactParams()
        self.servos = servos
        self.floating_palm = floating_palm
        self.contact_on_hand = contact_on_hand
        self.object_hold = object_hold and obj is not None
        self.floor_z_m = floor_z_m
        self.model = self._compose().compile()
        self.data = mujoco.MjData(self.model)
        self._index()
        if object_mass_kg is not None and obj is not None:
            self._set_object_mass(object_mass_kg)

    # ------------------------------------------------------------------------------ composition

    def _compose(self) -> mujoco.MjSpec:
        opts = self.physics
        world = mujoco.MjSpec()
        world.modelname = f"dexaug_{self.hand.name}_{self.obj.name if self.obj else 'empty'}"
        world.option.timestep = opts.timestep_s
        world.option.integrator = _INTEGRATORS[opts.integrator]
        world.option.cone = _CONES[opts.cone]
        world.option.impratio = opts.impratio
        world.option.noslip_iterations = opts.noslip_iterations
        world.option.iterations = opts.solver_iterations
        _set_jacobian_and_collision(world.option, opts)
        world.visual.global_.offwidth = 1280
        world.visual.global_.offheight = 960
        world.worldbody.add_light(name="key", pos=[0.4, -0.6, 1.2], dir=[-0.3, 0.5, -1.0],
                                  diffuse=[0.8, 0.8, 0.8])
        world.worldbody.add_light(name="fill", pos=[-0.5, 0.5, 1.0], dir=[0.4, -0.4, -1.0],
                                  diffuse=[0.4, 0.4, 0.4])

        world.worldbody.add_body(name="hand_target", mocap=True)
        base = world.worldbody.add_body(name="hand_base")
        base.add_freejoint(name="hand_free")
        hand_spec = self.hand.spec()
        for key in ("timestep", "integrator", "cone", "impratio", "noslip_iterations",
                    "iterations", "jacobian", "ccd_iterations", "disableflags"):
            setattr(hand_spec.option, key, getattr(world.option, key))  # the scene's options rule
        if self.contact_on_hand:
            apply_contact(hand_spec, self.contact)
        if self.servos is not None:
            apply_servos(hand_spec, self.servos)
        if self.floating_palm:
            palm = detach_palm(hand_spec, self.hand.config.palm.body)
            root = base.add_frame().attach_body(palm, HAND_PREFIX, "")
            root.pos, root.quat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]  # base frame = palm body
        else:
            world.attach(hand_spec, prefix=HAND_PREFIX, frame=base.add_frame())
        for body in world.bodies:
            if body.name == "hand_base" or body.name.startswith(HAND_PREFIX):
                body.gravcomp = 1.0
        weld = world.add_equality(name="hand_weld", type=mujoco.mjtEq.mjEQ_WELD,
                                  objtype=mujoco.mjtObj.mjOBJ_BODY, name1="hand_target",
                                  name2="hand_base", solref=list(opts.weld_solref))
        data = np.zeros(len(weld.data))
        data[6] = 1.0   # relpose quaternion: identity (the base sits exactly on the target)
        data[10] = 1.0  # torque scale
        weld.data = data

        if self.obj is not None:
            frame = world.worldbody.add_frame(pos=OBJECT_HOME)
            world.attach(self.obj.spec(self.contact), prefix=OBJECT_PREFIX, frame=frame)
        if self.object_hold:  # body1 = world: the relative pose is the object's world pose
            hold = world.add_equality(name=_HOLD, type=mujoco.mjtEq.mjEQ_WELD,
                                      objtype=mujoco.mjtObj.mjOBJ_BODY, name1="world",
                                      name2=OBJECT_PREFIX + "object",
                                      solref=list(opts.hold_solref),
                                      solimp=[*opts.hold_solimp, 0.5, 2.0])  # MuJoCo midpoint, power
            hold.active = False
        if self.table:
            world.worldbody.add_geom(
                name="table", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5, 0.5, 0.02],
                pos=[0.0, 0.0, TABLE_TOP_Z - 0.02], rgba=[0.55, 0.45, 0.35, 1.0],
                friction=list(self.contact.friction), solref=list(self.contact.solref))
        if self.floor_z_m is not None:   # a plane collides everywhere; its size is what is drawn
            world.worldbody.add_geom(
                name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[2.0, 2.0, 0.05],
                pos=[0.0, 0.0, self.floor_z_m], rgba=[0.35, 0.35, 0.38, 1.0],
                friction=list(self.contact.friction), solref=list(self.contact.solref))
        target = "obj/object" if self.obj is not None else "hand_base"
        world.worldbody.add_camera(name="overview", pos=[0.45, -0.45, 0.65],
                                   mode=mujoco.mjtCamLight.mjCAMLIGHT_TARGETBODY,
                                   targetbody=target, fovy=45.0)
        return world

    def position_servos(self) -> np.ndarray:
        """Mask over ``hand_act``: the actuators that are position servos (fixed gain, affine
        bias: force = kp·(ctrl − q) − kv·q̇), the ones whose stiffness kp holds a pose."""
        m, acts = self.model, self.hand_act
        return ((m.actuator_gaintype[acts] == int(mujoco.mjtGain.mjGAIN_FIXED))
                & (m.actuator_biastype[acts] == int(mujoco.mjtBias.mjBIAS_AFFINE)))

    def _set_object_mass(self, mass_kg: float) -> None:
        """Scale the object body's mass and inertia to ``mass_kg`` (kilograms)."""
        m, b = self.model, self.obj_body
        factor = mass_kg / float(m.body_mass[b])
        m.body_mass[b] *= factor
        m.body_inertia[b] *= factor
        mujoco.mj_setConst(m, self.data)
        self.obj_mass_kg = float(m.body_subtreemass[b])

    def _index(self) -> None:
        m = self.model
        self.mocap_id = m.body("hand_target").mocapid[0]
        self.palm_body = m.body(HAND_PREFIX + self.hand.config.palm.body).id
        self.base_qadr = m.joint("hand_free").qposadr[0]
        self.base_dadr = m.joint("hand_free").dofadr[0]
        joints = {m.joint(j).name for j in range(m.njnt)}
        actuators = {m.actuator(a).name for a in range(m.nu)}
        #: indices into Hand.joint_names / the hand model's actuators of what this scene has
        self.hand_joint_kept = np.array([i for i, n in enumerate(self.hand.joint_names)
                                         if HAND_PREFIX + n in joints], dtype=int)
        self.hand_act_kept = np.array([a for a in range(self.hand.model.nu)
                                       if HAND_PREFIX + self.hand.model.actuator(a).name in actuators],
                                      dtype=int)
        kept_names = [self.hand.joint_names[i] for i in self.hand_joint_kept]
        self.hand_qadr = np.array([m.joint(HAND_PREFIX + n).qposadr[0] for n in kept_names], dtype=int)
        self.hand_dadr = np.array([m.joint(HAND_PREFIX + n).dofadr[0] for n in kept_names], dtype=int)
        self.hand_act = np.array([m.actuator(HAND_PREFIX + self.hand.model.actuator(a).name).id
                                  for a in self.hand_act_kept], dtype=int)
        body_names = [m.body(b).name for b in range(m.nbody)]
        self.hand_body_mask = np.array([n == "hand_base" or n.startswith(HAND_PREFIX)
                                        for n in body_names])
        self.hand_geom_mask = self.hand_body_mask[m.geom_bodyid]
        # hand body id (scene) → hand model body id, for mapping contacts to fingers
        names = {n: i for i, n in enumerate(body_names)}
        self.scene_to_hand_body = {names[HAND_PREFIX + self.hand.model.body(b).name]: b
                                   for b in range(1, self.hand.model.nbody)
                                   if HAND_PREFIX + self.hand.model.body(b).name in names}
        if self.obj is not None:
            self.obj_body = m.body(OBJECT_PREFIX + "object").id
            self.obj_qadr = m.joint(OBJECT_PREFIX + "object_free").qposadr[0]
            self.obj_dadr = m.joint(OBJECT_PREFIX + "object_free").dofadr[0]
            self.obj_geom_mask = m.geom_bodyid == self.obj_body
            self.obj_mass_kg = float(m.body_subtreemass[self.obj_body])
        else:
            self.obj_geom_mask = np.zeros(m.ngeom, bool)
        self.table_geom = m.geom("table").id if self.table else -1
        self.floor_geom = m.geom("floor").id if self.floor_z_m is not None else -1
        self._hold_eq = m.equality(_HOLD).id if self.object_hold else -1

    def over(self, data: mujoco.MjData) -> Scene:
        """This scene read over another MjData of its model: same model, indices and masks,
        ``data`` as its state. What a batch runner gives a protocol for each simulation it
        steps (:mod:`sim.validate.batched`)."""
        view = copy.copy(self)
        view.data = data
        return view

    # ---------------------------------------------------------------------------------- driving

    def set_hand_pose(self, base_pos: np.ndarray, base_quat: np.ndarray, *,
                      teleport: bool = True) -> None:
        """Move the mocap target (and with ``teleport`` the base itself) to a base pose."""
        d = self.data
        d.mocap_pos[self.mocap_id] = base_pos
        d.mocap_quat[self.mocap_id] = base_quat
        if teleport:
            d.qpos[self.base_qadr:self.base_qadr + 3] = base_pos
            d.qpos[self.base_qadr + 3:self.base_qadr + 7] = base_quat
            d.qvel[self.base_dadr:self.base_dadr + 6] = 0.0

    def reset_with_grasp(self, palm_pos: np.ndarray, palm_quat: np.ndarray, q: np.ndarray) -> None:
        """Reset the simulation to a grasp's start: the object at rest at :data:`OBJECT_HOME`
        (identity orientation), frame_palm at (palm_pos, palm_quat) in the world with joints
        and controls at ``q`` (full hand joint vector), gravity off; then ``mj_forward``. How
        every validation protocol (and the demo import) places a grasp."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        m.opt.gravity[:] = 0.0
        self.set_object_pose(OBJECT_HOME, np.array([1.0, 0.0, 0.0, 0.0]))
        self.set_palm_pose(palm_pos, palm_quat, q)
        self.set_hand_joints(q)
        self.set_hand_ctrl(q)
        mujoco.mj_forward(m, d)

    def set_palm_pose(self, palm_pos: np.ndarray, palm_quat: np.ndarray, q: np.ndarray) -> None:
        """Put the hand (mocap target and base) where frame_palm lands on (palm_pos, palm_quat)
        in the world with joints ``q`` (full hand joint vector)."""
        if self.floating_palm:   # the base is the palm body: undo frame_palm's fixed offset
            cfg = self.hand.config.palm
            inv_p, inv_q = pose_inv(cfg.pos, cfg.quat_wxyz)
            base = pose_mul(np.asarray(palm_pos, float), np.asarray(palm_quat, float), inv_p, inv_q)
        else:
            base = self.hand.base_pose_for_palm(palm_pos, palm_quat, q)
        self.set_hand_pose(*base)

    def set_hand_joints(self, q: np.ndarray) -> None:
        """Hand joints from a full hand joint vector (the scene's own joints of it)."""
        self.data.qpos[self.hand_qadr] = np.asarray(q)[self.hand_joint_kept]
        self.data.qvel[self.hand_dadr] = 0.0

    def ctrl_for(self, q_target: np.ndarray) -> np.ndarray:
        """This scene's hand controls (over ``hand_act``) that hold the full joint vector
        ``q_target``, clipped to the control ranges the scene's actuators have."""
        m, acts = self.model, self.hand_act
        ctrl = self.hand.ctrl_for(q_target, clip=False)[self.hand_act_kept]
        limited = m.actuator_ctrllimited[acts].astype(bool)
        lo, hi = m.actuator_ctrlrange[acts, 0], m.actuator_ctrlrange[acts, 1]
        return np.where(limited, np.clip(ctrl, lo, hi), ctrl)

    def set_hand_ctrl(self, q_target: np.ndarray) -> None:
        self.data.ctrl[self.hand_act] = self.ctrl_for(q_target)

    def object_pose(self) -> tuple[np.ndarray, np.ndarray]:
        q = self.data.qpos
        return q[self.obj_qadr:self.obj_qadr + 3].copy(), q[self.obj_qadr + 3:self.obj_qadr + 7].copy()

    def set_object_pose(self, pos: np.ndarray, quat: np.ndarray) -> None:
        self.data.qpos[self.obj_qadr:self.obj_qadr + 3] = pos
        self.data.qpos[self.obj_qadr + 3:self.obj_qadr + 7] = quat
        self.data.qvel[self.obj_dadr:self.obj_dadr + 6] = 0.0

    @property
    def object_held(self) -> bool:
        """The object is welded where :meth:`hold_object` found it."""
        return self._hold_eq >= 0 and bool(self.data.eq_active[self._hold_eq])

    def hold_object(self) -> None:
        """Weld the object to the world at its current pose (qpos; its velocity is zeroed).

        Raises RuntimeError when the scene was built without ``object_hold``."""
        if self._hold_eq < 0:
            raise RuntimeError("this scene was built without object_hold: the object cannot be "
                               "held")
        pos, quat = self.object_pose()
        eq = self.model.eq_data[self._hold_eq]
        eq[:3] = 0.0                              # anchor: the object body's origin
        eq[3:6], eq[6:10] = pos, quat / np.linalg.norm(quat)
        eq[10] = 1.0                              # torque scale
        self.data.qvel[self.obj_dadr:self.obj_dadr + 6] = 0.0
        self.data.eq_active[self._hold_eq] = 1

    def release_object(self) -> None:
        """Let the object move freely again (nothing to do when it is not held)."""
        if self._hold_eq >= 0:
            self.data.eq_active[self._hold_eq] = 0

    def base_world_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """The hand base in the world (position, quaternion wxyz), from the simulated state:
        where the weld has carried it, not the mocap target it follows."""
        q = self.data.qpos[self.base_qadr:self.base_qadr + 7]
        return q[:3].copy(), q[3:].copy()

    def palm_world_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """frame_palm in the world, from the simulated hand state."""
        d, cfg, b = self.data, self.hand.config.palm, self.palm_body
        pos = d.xpos[b] + d.xmat[b].reshape(3, 3) @ cfg.pos
        quat = np.empty(4)
        mujoco.mju_mulQuat(quat, d.xquat[b], cfg.quat_wxyz)
        return pos, quat
