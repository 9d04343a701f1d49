"""Scene composition: a floating hand, a free object and an optional table, built with MjSpec.

The hand's base gets a free joint and is welded to a mocap body, so the hand is moved by moving
the mocap target (6-DoF pose control) while contacts still see the hand's real velocity (a hand
that *is* a mocap body has zero velocity in the solver, which makes friction fight the lift).
Hand bodies are gravity-compensated, as a real arm-mounted hand's controller would do. All
composition goes through ``mujoco.MjSpec``; no XML strings are pasted together.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from sim.hand.model import Hand
from sim.world.object_spec import ContactParams
from sim.world.objects import ObjectAsset

HAND_PREFIX = "hand/"
OBJECT_PREFIX = "obj/"
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
    weld_solref: tuple[float, float] = (0.01, 1.0)
    #: constraint Jacobians stored sparse: the hand's fingers are separate kinematic branches,
    #: so a contact row touches a few of the ~36 dofs; measured on 60 screwdriver lift-drop
    #: validations: 89–105 ms per grasp against 114 dense, same outcomes
    sparse_jacobian: bool = True


_INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER,
                "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
                "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
                "rk4": mujoco.mjtIntegrator.mjINT_RK4}
_CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}


class Scene:
    """A compiled hand + object (+ table) world and the index maps to drive and read it."""

    def __init__(self, hand: Hand, obj: ObjectAsset | None, *, table: bool = False,
                 contact: ContactParams | None = None,
                 physics: PhysicsOptions | None = None) -> None:
        self.hand = hand
        self.obj = obj
        self.table = table
        self.physics = physics or PhysicsOptions()
        self.contact = contact or ContactParams()
        self.model = self._compose().compile()
        self.data = mujoco.MjData(self.model)
        self._index()

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
        world.option.jacobian = (mujoco.mjtJacobian.mjJAC_SPARSE if opts.sparse_jacobian
                                 else mujoco.mjtJacobian.mjJAC_DENSE)
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
        for key in ("timestep", "integrator", "cone", "impratio", "noslip_iterations"):
            setattr(hand_spec.option, key, getattr(world.option, key))  # the scene's options rule
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
        if self.table:
            world.worldbody.add_geom(
                name="table", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.5, 0.5, 0.02],
                pos=[0.0, 0.0, TABLE_TOP_Z - 0.02], rgba=[0.55, 0.45, 0.35, 1.0],
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

    def scale_servo_stiffness(self, scale: float) -> None:
        """Multiply the hand's position-servo stiffness kp (N·m/rad or N/m per actuator) by
        ``scale`` in this scene's model (it multiplies: once per scene); force limits, damping
        and the other actuators stay."""
        acts = self.hand_act[self.position_servos()]
        self.model.actuator_gainprm[acts, 0] *= scale
        self.model.actuator_biasprm[acts, 1] *= scale

    def _index(self) -> None:
        m = self.model
        self.mocap_id = m.body("hand_target").mocapid[0]
        self.base_qadr = m.joint("hand_free").qposadr[0]
        self.base_dadr = m.joint("hand_free").dofadr[0]
        self.hand_qadr = np.array([m.joint(HAND_PREFIX + n).qposadr[0]
                                   for n in self.hand.joint_names])
        self.hand_dadr = np.array([m.joint(HAND_PREFIX + n).dofadr[0]
                                   for n in self.hand.joint_names])
        self.hand_act = np.array([m.actuator(HAND_PREFIX + self.hand.model.actuator(a).name).id
                                  for a in range(self.hand.model.nu)], dtype=int)
        body_names = [m.body(b).name for b in range(m.nbody)]
        self.hand_body_mask = np.array([n == "hand_base" or n.startswith(HAND_PREFIX)
                                        for n in body_names])
        self.hand_geom_mask = self.hand_body_mask[m.geom_bodyid]
        # hand body id (scene) → hand model body id, for mapping contacts to fingers
        self.scene_to_hand_body = {m.body(HAND_PREFIX + self.hand.model.body(b).name).id: b
                                   for b in range(1, self.hand.model.nbody)}
        if self.obj is not None:
            self.obj_body = m.body(OBJECT_PREFIX + "object").id
            self.obj_qadr = m.joint(OBJECT_PREFIX + "object_free").qposadr[0]
            self.obj_dadr = m.joint(OBJECT_PREFIX + "object_free").dofadr[0]
            self.obj_geom_mask = m.geom_bodyid == self.obj_body
            self.obj_mass_kg = float(m.body_subtreemass[self.obj_body])
        else:
            self.obj_geom_mask = np.zeros(m.ngeom, bool)
        self.table_geom = m.geom("table").id if self.table else -1

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

    def set_hand_joints(self, q: np.ndarray) -> None:
        self.data.qpos[self.hand_qadr] = q
        self.data.qvel[self.hand_dadr] = 0.0

    def set_hand_ctrl(self, q_target: np.ndarray) -> None:
        self.data.ctrl[self.hand_act] = self.hand.ctrl_for(q_target)

    def object_pose(self) -> tuple[np.ndarray, np.ndarray]:
        q = self.data.qpos
        return q[self.obj_qadr:self.obj_qadr + 3].copy(), q[self.obj_qadr + 3:self.obj_qadr + 7].copy()

    def set_object_pose(self, pos: np.ndarray, quat: np.ndarray) -> None:
        self.data.qpos[self.obj_qadr:self.obj_qadr + 3] = pos
        self.data.qpos[self.obj_qadr + 3:self.obj_qadr + 7] = quat
        self.data.qvel[self.obj_dadr:self.obj_dadr + 6] = 0.0

    def palm_world_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """frame_palm in the world, from the simulated hand state."""
        d, cfg = self.data, self.hand.config.palm
        b = self.model.body(HAND_PREFIX + cfg.body).id
        pos = d.xpos[b] + d.xmat[b].reshape(3, 3) @ cfg.pos
        quat = np.empty(4)
        mujoco.mju_mulQuat(quat, d.xquat[b], cfg.quat_wxyz)
        return pos, quat
