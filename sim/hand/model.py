"""The ``Hand``: a MuJoCo hand model bound to its config.

It answers the questions every other part asks of a hand, for any joint vector: where are the
fingertips and the finger links (forward kinematics, batched), where is the palm frame, which
actuator controls hold a joint vector (including coupled tendon actuators), and how to place the
hand's root so that the palm lands on a wanted pose. Joint vectors always hold all of the
model's joints in model order (radians for hinges, metres for slides).
"""

from __future__ import annotations

from functools import cached_property
from itertools import pairwise
from pathlib import Path

import mujoco
import numpy as np

from sim.errors import AssetError, ConfigError, GraspInputError
from sim.hand.config import HandConfig, load_hand_config
from sim.hand.conventions import palm_frame_problems
from sim.hand.kinematics import TreeKinematics
from sim.hand.model_checks import check_model
from sim.paths import ensure_menagerie_root
from sim.transforms import pose_inv, pose_mul, quat_to_mat


def hand_model_path(config: HandConfig) -> Path:
    """The MJCF file of a hand config, resolved through ``mujoco_menagerie`` when named there."""
    if config.model_path is not None:
        if not config.model_path.is_file():
            raise AssetError(f"{config.file}: model.path {config.model_path} does not exist")
        return config.model_path
    ensure_menagerie_root()
    import mujoco_menagerie

    try:
        robot = mujoco_menagerie.get(config.menagerie)
        path = robot.xml(config.entry)
    except mujoco_menagerie.MenagerieError as exc:
        raise AssetError(f"{config.file}: cannot resolve Menagerie model {config.menagerie!r} "
                         f"(entry {config.entry!r}): {exc}") from None
    if not path.is_file():
        raise AssetError(f"{config.file}: Menagerie model file {path} is missing "
                         "(check MENAGERIE_ROOT)")
    return path


class Hand:
    """A hand model plus its config, validated against each other on construction."""

    def __init__(self, config: HandConfig, *, check_conventions: bool = True) -> None:
        """Build the hand of ``config``; with ``check_conventions`` a config whose palm frame
        contradicts DESIGN §3 (+y out of the palm face, toward the pulps:
        :mod:`sim.hand.conventions`) is refused, naming the file and what was measured."""
        self.config = config
        self.model_path = hand_model_path(config)
        self.model = self.spec().compile()
        m = self.model
        self._validate()
        self.joint_names: tuple[str, ...] = tuple(m.joint(j).name for j in range(m.njnt))
        self.nq = m.nq
        limited = m.jnt_limited.astype(bool)  # joint limits, radians/metres (±inf when unlimited)
        self.lower = np.where(limited, m.jnt_range[:, 0], -np.inf)
        self.upper = np.where(limited, m.jnt_range[:, 1], np.inf)
        self.kinematics = TreeKinematics(m)
        self.palm_body_id = m.body(config.palm.body).id
        self.tip_body_ids = np.array([m.body(f.tip_body).id for f in config.fingers])
        self.tip_site_ids = np.array([m.site(f.site_name).id for f in config.fingers])
        self.finger_qadr = {f.name: np.array([m.joint(j).qposadr[0] for j in f.joints])
                            for f in config.fingers}
        self._coupling = [(m.joint(fol).qposadr[0], m.joint(lead).qposadr[0], coef)
                          for f in config.fingers for fol, (lead, coef) in f.coupled_to.items()]
        if check_conventions and (problems := palm_frame_problems(self)):
            raise ConfigError("; ".join(problems))

    @classmethod
    def load(cls, name_or_path: str | Path) -> Hand:
        return cls(load_hand_config(name_or_path))

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def finger_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.config.fingers)

    def spec(self) -> mujoco.MjSpec:
        """A fresh, editable spec of the hand with the pulp sites of the config added."""
        try:
            spec = mujoco.MjSpec.from_file(str(self.model_path))
        except Exception as exc:
            raise AssetError(f"{self.model_path}: MuJoCo cannot load the hand model: {exc}") from None
        if self.config.root_body:
            root = spec.body(self.config.root_body)
            if root is None:
                raise ConfigError(f"{self.config.file}: model.root_body: no body "
                                  f"{self.config.root_body!r} in {self.model_path.name}")
            # bodies above the root (a forearm, a mounting plate) keep their kinematics but lose
            # their geoms: the floating hand starts at the root body
            kept = {root.name} | {b.name for b in root.find_all(mujoco.mjtObj.mjOBJ_BODY)}
            for geom in list(spec.geoms):
                if geom.parent.name not in kept:
                    spec.delete(geom)
        for finger in self.config.fingers:
            body = spec.body(finger.tip_body)
            if body is None:
                raise ConfigError(f"{self.config.file}: fingers '{finger.name}'.tip_body: no body "
                                  f"{finger.tip_body!r} in {self.model_path.name}")
            body.add_site(name=finger.site_name, pos=finger.tip_site_pos, size=[0.002, 0, 0],
                          group=4, rgba=[1, 0.2, 0.2, 1])
        return spec

    def _validate(self) -> None:
        m, cfg = self.model, self.config
        bodies = {m.body(b).name for b in range(m.nbody)}
        joints = {m.joint(j).name for j in range(m.njnt)}
        meshes = {m.mesh(i).name for i in range(m.nmesh)}
        where = f"{cfg.file}"

        def need(kind: str, key: str, name: str, pool: set[str]) -> None:
            if name not in pool:
                raise ConfigError(f"{where}: {key}: unknown {kind} {name!r} in model "
                                  f"{self.model_path.name} (it has {len(pool)} {kind}s, e.g. "
                                  f"{sorted(pool)[:6]})")

        need("body", "palm.body", cfg.palm.body, bodies)
        if cfg.root_body:
            need("body", "model.root_body", cfg.root_body, bodies)
        for f in cfg.fingers:
            key = f"fingers '{f.name}'"
            need("body", f"{key}.tip_body", f.tip_body, bodies)
            need("mesh", f"{key}.tip_mesh", f.tip_mesh, meshes)
            for b in f.links:
                need("body", f"{key}.links", b, bodies)
            for j in f.joints:
                need("joint", f"{key}.joints", j, joints)
        for posture, values in cfg.postures.items():
            for name in values:
                need("joint", f"grasp.{posture}", name, joints)
        check_model(m, cfg, self.model_path)

    # ----------------------------------------------------------------------------- joint vectors

    def check_q(self, q: np.ndarray | list[float], what: str = "joint vector") -> np.ndarray:
        """Return q as float array (nq,) or (B, nq); wrong length or non-finite → GraspInputError."""
        arr = np.asarray(q, dtype=float)
        if arr.ndim not in (1, 2) or arr.shape[-1] != self.nq:
            raise GraspInputError(f"{what}: expected {self.nq} joint values for hand "
                                  f"{self.name!r} ({', '.join(self.joint_names)}), got shape "
                                  f"{arr.shape}")
        if not np.isfinite(arr).all():
            raise GraspInputError(f"{what}: contains NaN or infinite values")
        return arr

    @property
    def couplings(self) -> list[tuple[int, int, float]]:
        """The config's coupled joints as (follower, leader, coefficient), indices into the
        joint vector: follower = coefficient · leader in the hand data (``coupled_to``)."""
        return list(self._coupling)

    def fill_coupled(self, q: np.ndarray) -> np.ndarray:
        """Set each coupled follower from its leader (the paper's FJ1 = FJ2)."""
        q = np.array(q, dtype=float)
        for follower, leader, coef in self._coupling:
            q[..., follower] = coef * q[..., leader]
        return q

    def clip(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lower, self.upper)

    def posture(self, name: str) -> np.ndarray:
        """A named posture of the config's [grasp] table as a full joint vector (radians)."""
        q = np.zeros(self.nq)
        named = self.config.postures.get(name, {})
        for joint, value in named.items():
            q[self.model.joint(joint).qposadr[0]] = value
        filled = self.fill_coupled(q)
        keep = np.array([n in named for n in self.joint_names])
        return self.clip(np.where(keep, q, filled))

    @cached_property
    def open_pose(self) -> np.ndarray:
        return self.posture("open_pose")

    # ------------------------------------------------------------------------ forward kinematics

    def _batch(self, q: np.ndarray) -> tuple[np.ndarray, bool]:
        q = self.check_q(q)
        return (q[None], True) if q.ndim == 1 else (q, False)

    def body_poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every body's pose in the hand model's base frame: (B, nbody, 3), (B, nbody, 4) wxyz."""
        qb, _ = self._batch(q)
        return self.kinematics.body_poses(qb)

    def palm_pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """frame_palm in the base frame for joint vectors q: (B, 3), (B, 4) wxyz."""
        qb, _ = self._batch(q)
        pos, quat = self.kinematics.body_pose(qb, self.palm_body_id)
        return pose_mul(pos, quat, self.config.palm.pos, self.config.palm.quat_wxyz)

    def fingertip_sites(self, q: np.ndarray, frame: str = "base") -> np.ndarray:
        """Pulp site positions (B, nfingers, 3) metres, in the base frame or frame_palm."""
        pos, quat = self.body_poses(q)
        tips = pos[:, self.tip_body_ids] + np.einsum(
            "bfij,fj->bfi", quat_to_mat(quat[:, self.tip_body_ids]),
            self.model.site_pos[self.tip_site_ids])
        if frame == "palm":
            ppos, pquat = self.palm_pose(q)
            inv_p, inv_q = pose_inv(ppos, pquat)
            tips = inv_p[:, None] + np.einsum("bij,bfj->bfi", quat_to_mat(inv_q), tips)
        elif frame != "base":
            raise ValueError(f"frame must be 'base' or 'palm', got {frame!r}")
        return tips

    def tip_frames_in_palm(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fingertip body poses in frame_palm: (B, nfingers, 3), (B, nfingers, 4) wxyz."""
        pos, quat = self.body_poses(q)
        ppos, pquat = self.palm_pose(q)
        inv_p, inv_q = pose_inv(ppos, pquat)
        nf = len(self.tip_body_ids)
        return pose_mul(np.repeat(inv_p[:, None], nf, 1), np.repeat(inv_q[:, None], nf, 1),
                        pos[:, self.tip_body_ids], quat[:, self.tip_body_ids])

    def skeleton(self, q: np.ndarray, finger: str, spacing_m: float = 0.005) -> np.ndarray:
        """Points every ``spacing_m`` along a finger's links (origin to origin, then to the pulp
        site) in frame_palm: (B, npoints, 3). Used for link penetration checks."""
        f = self.config.finger(finger)
        pos, quat = self.body_poses(q)
        ids = [self.model.body(b).id for b in f.links]
        chain = [pos[:, i] for i in ids]
        tip_q = quat[:, ids[-1]]
        chain.append(pos[:, ids[-1]] + np.einsum("bij,j->bi", quat_to_mat(tip_q), f.tip_site_pos))
        pts = []
        for a, b in pairwise(chain):
            n = max(int(np.ceil(np.max(np.linalg.norm(b - a, axis=-1)) / spacing_m)), 1)
            t = np.linspace(0.0, 1.0, n, endpoint=False)
            pts.append(a[:, None] + t[None, :, None] * (b - a)[:, None])
        pts.append(chain[-1][:, None])
        pts_base = np.concatenate(pts, axis=1)
        ppos, pquat = self.palm_pose(q)
        inv_p, inv_q = pose_inv(ppos, pquat)
        return inv_p[:, None] + np.einsum("bij,bnj->bni", quat_to_mat(inv_q), pts_base)

    def base_pose_for_palm(self, palm_pos: np.ndarray, palm_quat: np.ndarray,
                           q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where to put the hand's base (its model frame) so frame_palm lands on
        (palm_pos, palm_quat) with joints q: T_base = T_palm · (T_base→palm(q))⁻¹."""
        ppos, pquat = self.palm_pose(q)
        inv_p, inv_q = pose_inv(ppos[0], pquat[0])
        return pose_mul(np.asarray(palm_pos, float), np.asarray(palm_quat, float), inv_p, inv_q)

    # ----------------------------------------------------------------------------------- control

    @cached_property
    def _transmission(self) -> np.ndarray:
        """Linear map (nu, nq) from joint vector to actuator length: joint transmissions and
        fixed tendons, times the gear. Other transmissions are refused (not linear in q)."""
        m = self.model
        a_mat = np.zeros((m.nu, m.nq))
        for a in range(m.nu):
            gear = m.actuator_gear[a, 0]
            trn = int(m.actuator_trntype[a])
            target = m.actuator_trnid[a, 0]
            if trn == int(mujoco.mjtTrn.mjTRN_JOINT):
                a_mat[a, m.jnt_qposadr[target]] += gear
            elif trn == int(mujoco.mjtTrn.mjTRN_TENDON) and m.tendon_num[target] > 0 and all(
                    int(m.wrap_type[w]) == int(mujoco.mjtWrap.mjWRAP_JOINT)
                    for w in range(m.tendon_adr[target],
                                   m.tendon_adr[target] + m.tendon_num[target])):
                for w in range(m.tendon_adr[target], m.tendon_adr[target] + m.tendon_num[target]):
                    a_mat[a, m.jnt_qposadr[m.wrap_objid[w]]] += gear * m.wrap_prm[w]
            else:
                raise ConfigError(f"{self.config.file}: actuator {m.actuator(a).name!r} uses a "
                                  "transmission that is not a joint or a fixed tendon")
        return a_mat

    def ctrl_for(self, q: np.ndarray, *, clip: bool = True) -> np.ndarray:
        """Actuator controls whose steady state (zero actuator force at rest) is joint vector q.

        Works for position actuators and general actuators with an affine bias:
        gain·ctrl + b0 + b1·length = 0 ⇒ ctrl = −(b0 + b1·length)/gain, clipped to ctrlrange
        with ``clip`` (a scene whose actuators have other ranges clips itself).
        """
        m = self.model
        length = self._transmission @ self.check_q(q)
        gain = m.actuator_gainprm[:, 0]
        ctrl = -(m.actuator_biasprm[:, 0] + m.actuator_biasprm[:, 1] * length) / gain
        limited = m.actuator_ctrllimited.astype(bool) & clip
        ctrl[limited] = np.clip(ctrl[limited], m.actuator_ctrlrange[limited, 0],
                                m.actuator_ctrlrange[limited, 1])
        return ctrl
