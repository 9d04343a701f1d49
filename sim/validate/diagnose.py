"""Why grasps slip: replay a grasp under lift-drop and record the forces that hold it.

The validator says *that* a grasp slipped; this says *why*. :func:`diagnose` replays one grasp
exactly as :meth:`sim.validate.validator.Validator.validate` runs it (same scene, targets and
steps, so the same verdict) and samples, after closing and through the lift and hold:

- every hand–object contact: its hand body, normal force fn (N), tangential friction force ft (N)
  and torsional moment (N·m) from ``mj_contactForce``, and the friction it could give, μ·fn
  (sliding) and μ_torsion·fn; ``ft / (μ·fn)`` ≥ ~1 means the contact slides;
- every hand actuator's force against its force limit (``actuator_forcerange``): a servo at its
  limit cannot squeeze harder;
- the object's weight (N) and the vertical share of it each finger carries (the world +z
  component of that finger's contact forces on the object over m·g), and the lever arm from the
  contacts' centroid to the centre of mass (m) with the gravity moment it makes (N·m);
- the object's drift in the palm frame: displacement (m) and rotation (rad), split into a
  direction (palm-frame unit vector) and a rotation axis (palm frame).

:class:`GraspDiagnosis` keeps the samples and summarises the slip: when it started (the first
sample past a quarter of either lift-drop limit, in seconds after gravity was turned on),
whether it was a translation or a rotation (whichever is the larger share of its limit at
failure), which way, and the state of the
contacts and actuators at the onset. :func:`summarise` aggregates many diagnoses into the
findings the ``dexaug diagnose`` command prints. Units: metres, seconds, radians, newtons.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from sim.grasp import Grasp
from sim.transforms import quat_conj, quat_mul
from sim.validate.config import GRAVITY_MPS2
from sim.validate.result import ValidationResult
from sim.validate.stepping import relative_object_pose
from sim.validate.validator import Validator
from sim.world.scene import HAND_PREFIX, Scene

__all__ = ["ContactSample", "GraspDiagnosis", "Sample", "diagnose", "summarise"]

#: share of a lift-drop limit past which the object counts as starting to slip
ONSET_FRACTION = 0.25
#: friction use (ft / μ·fn) and actuator effort (|force| / limit) counted as "at the limit"
AT_LIMIT = 0.95
#: palm-frame axis names (DESIGN §3: +y out of the palm face, toward the pulps)
AXES = ("x", "y", "z")


@dataclass(frozen=True)
class ContactSample:
    """One hand–object contact at one sample: the hand body, forces in newtons (N·m for the
    torsional moment), and the friction coefficients MuJoCo uses for it."""

    body: str
    fn: float
    ft: float
    torsion: float
    mu: float
    mu_torsion: float

    @property
    def friction_use(self) -> float:
        """ft / (μ·fn): 1 is the edge of the friction cone (a sliding contact)."""
        return self.ft / (self.mu * self.fn) if self.fn > 1e-9 and self.mu > 0 else float("inf")


@dataclass(frozen=True)
class Sample:
    """The grasp at one instant: simulated time (s), phase ("closed", "lift", "hold"), drift in
    the palm frame (displacement m and its vector, rotation rad and its rotation vector), the
    contacts, every hand actuator's |force| / limit (NaN without a limit) and per finger the share
    of the weight it carries vertically."""

    t_s: float
    phase: str
    displacement_m: float
    rotation_rad: float
    translation_palm: np.ndarray
    rotvec_palm: np.ndarray
    contacts: tuple[ContactSample, ...]
    effort: np.ndarray
    support: dict[str, float]
    lever_arm_m: float


@dataclass
class GraspDiagnosis:
    """One replayed grasp: the validation result (the same verdict as ``validate``), the samples,
    the object's weight (N), the lift-drop limits (m, rad), and the actuator names."""

    result: ValidationResult
    samples: list[Sample]
    weight_n: float
    max_displacement_m: float
    max_rotation_rad: float
    actuators: tuple[str, ...]
    findings: dict[str, Any] = field(default_factory=dict)

    def onset(self) -> Sample | None:
        """The first sample past :data:`ONSET_FRACTION` of either limit, or None."""
        for s in self.samples:
            if (s.displacement_m > ONSET_FRACTION * self.max_displacement_m
                    or s.rotation_rad > ONSET_FRACTION * self.max_rotation_rad):
                return s
        return None

    def summary(self) -> dict[str, Any]:
        """Plain-data findings: verdict, slip onset time and phase, mode (translation or
        rotation) and direction (palm frame), friction use and actuator effort at the onset (or
        at the start of the lift when nothing slipped), weight support per finger, lever arm."""
        first_lift = next((s for s in self.samples if s.phase == "lift"), None)
        onset = self.onset()
        at = onset or first_lift or (self.samples[-1] if self.samples else None)
        out: dict[str, Any] = {"passed": self.result.passed, "failure": self.result.failure,
                               "weight_n": self.weight_n}
        if at is None:
            return out
        last = self.samples[-1]
        trans_share = last.displacement_m / self.max_displacement_m
        rot_share = last.rotation_rad / self.max_rotation_rad
        mode = "translation" if trans_share >= rot_share else "rotation"
        vec = last.translation_palm if mode == "translation" else last.rotvec_palm
        norm = float(np.linalg.norm(vec))
        direction = vec / norm if norm > 0 else np.zeros(3)
        k = int(np.argmax(np.abs(direction)))
        uses = np.array([c.friction_use for c in at.contacts]) if at.contacts else np.zeros(0)
        eff = at.effort[np.isfinite(at.effort)]
        sat = [self.actuators[i] for i in np.flatnonzero(np.nan_to_num(at.effort) >= AT_LIMIT)]
        out.update({
            "onset_after_gravity_s": None if onset is None else onset.t_s - self.samples[0].t_s,
            "onset_phase": None if onset is None else onset.phase,
            "mode": mode, "direction_palm": direction.round(3).tolist(),
            "axis": f"{'+' if direction[k] >= 0 else '-'}{AXES[k]}",
            "n_contacts": len(at.contacts),
            "fn_total_n": float(sum(c.fn for c in at.contacts)),
            "friction_use_median": float(np.median(uses)) if len(uses) else float("nan"),
            "contacts_sliding": int((uses >= AT_LIMIT).sum()),
            "effort_max": float(eff.max()) if len(eff) else float("nan"),
            "actuators_at_limit": sat,
            "support": {f: round(v, 3) for f, v in at.support.items()},
            "lever_arm_m": at.lever_arm_m,
            "gravity_moment_nm": self.weight_n * at.lever_arm_m,
        })
        return out


def _finger_of_body(scene: Scene, validator: Validator) -> dict[int, str]:
    """Scene body id → finger name (bodies of each finger's chain; palm and others: "palm")."""
    m = scene.model
    out: dict[int, str] = {}
    hand_model = validator.hand.model
    for finger in validator.hand.config.fingers:
        b = hand_model.body(finger.tip_body).id
        while b > 0:
            name = hand_model.body(b).name
            sid = m.body(HAND_PREFIX + name).id
            out.setdefault(sid, finger.name)
            b = hand_model.body_parentid[b]
    return out


class _Recorder:
    """Samples the scene for :func:`diagnose` (the validator's ``observe`` callback)."""

    def __init__(self, validator: Validator, scene: Scene) -> None:
        self.scene = scene
        self.samples: list[Sample] = []
        self.finger_of = _finger_of_body(scene, validator)
        m = scene.model
        self.acts = scene.hand_act
        lo, hi = m.actuator_forcerange[self.acts].T
        limited = m.actuator_forcelimited[self.acts].astype(bool) & (hi > lo)
        self.limit = np.where(limited, np.maximum(np.abs(lo), np.abs(hi)), np.nan)
        self.weight_n = scene.obj_mass_kg * GRAVITY_MPS2
        self.ref: tuple[np.ndarray, np.ndarray] | None = None
        self._buf = np.zeros(6)

    def __call__(self, phase: str) -> None:
        scene, m, d = self.scene, self.scene.model, self.scene.data
        pos, quat = relative_object_pose(scene)
        if self.ref is None:
            self.ref = (pos, quat)
        ref_pos, ref_quat = self.ref
        dq = quat_mul(quat, quat_conj(ref_quat))
        dq = dq if dq[0] >= 0 else -dq
        angle = 2.0 * float(np.arctan2(np.linalg.norm(dq[1:]), dq[0]))
        axis = dq[1:] / (np.linalg.norm(dq[1:]) or 1.0)
        contacts, points = [], []
        support: defaultdict[str, float] = defaultdict(float)   # weight share per finger
        for i in range(d.ncon):
            c = d.contact[i]
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            on_obj = scene.obj_geom_mask[g2] and scene.hand_geom_mask[g1]
            if not (on_obj or (scene.obj_geom_mask[g1] and scene.hand_geom_mask[g2])):
                continue
            if c.dist > 1e-4:
                continue
            mujoco.mj_contactForce(m, d, i, self._buf)
            frame = c.frame.reshape(3, 3)
            f_world = frame.T @ self._buf[:3] * (1.0 if on_obj else -1.0)   # force on the object
            hand_geom = g1 if on_obj else g2
            finger = self.finger_of.get(int(m.geom_bodyid[hand_geom]), "palm")
            contacts.append(ContactSample(
                body=finger, fn=float(self._buf[0]), ft=float(np.hypot(*self._buf[1:3])),
                torsion=float(abs(self._buf[3])), mu=float(c.friction[0]),
                mu_torsion=float(c.friction[2])))
            support[finger] += float(f_world[2]) / self.weight_n
            points.append(c.pos.copy())
        com = d.xipos[scene.obj_body]
        lever = (float(np.linalg.norm((np.mean(points, axis=0) - com)[:2])) if points
                 else float("nan"))
        effort = np.abs(d.actuator_force[self.acts]) / self.limit
        self.samples.append(Sample(
            t_s=float(d.time), phase=phase,
            displacement_m=float(np.linalg.norm(pos - ref_pos)), rotation_rad=angle,
            translation_palm=pos - ref_pos, rotvec_palm=axis * angle,
            contacts=tuple(contacts), effort=effort, support=dict(support), lever_arm_m=lever))


def diagnose(validator: Validator, grasp: Grasp) -> GraspDiagnosis:
    """Replay ``grasp`` under lift-drop, sampling it (module docstring). The verdict is the one
    :meth:`Validator.validate` gives; a grasp rejected before closing (penetration, no contact)
    has no samples."""
    scene = validator.scene("lift-drop")
    recorder = _Recorder(validator, scene)
    result = validator.validate(grasp, "lift-drop", observe=recorder)
    p = validator.config.lift_drop
    names = tuple(scene.model.actuator(int(a)).name.removeprefix(HAND_PREFIX) for a in scene.hand_act)
    diag = GraspDiagnosis(result=result, samples=recorder.samples, weight_n=recorder.weight_n,
                          max_displacement_m=p.max_displacement_m,
                          max_rotation_rad=p.max_rotation_rad, actuators=names)
    diag.findings = diag.summary()
    return diag


def summarise(diagnoses: list[GraspDiagnosis]) -> dict[str, Any]:
    """Findings over many grasps: verdicts, slip modes and axes, when slips start, median
    friction use and actuator effort at the onset, how often a servo is at its limit or a contact
    slides, and which fingers carry the weight (median vertical share, passing vs failing)."""
    rows = [d.findings for d in diagnoses]
    failing = [r for r in rows if not r.get("passed") and "mode" in r]
    passing = [r for r in rows if r.get("passed") and "mode" in r]

    def med(key: str, rs: list[dict[str, Any]]) -> float:
        v = [r[key] for r in rs if r.get(key) is not None and np.isfinite(r[key])]
        return float(np.median(v)) if v else float("nan")

    def support(rs: list[dict[str, Any]]) -> dict[str, float]:
        fingers = sorted({f for r in rs for f in r.get("support", {})})
        return {f: float(np.median([r["support"].get(f, 0.0) for r in rs])) for f in fingers}

    return {
        "grasps": len(rows),
        "verdicts": dict(Counter("pass" if r.get("passed") else str(r.get("failure")) for r in rows)),
        "slip_modes": dict(Counter(f"{r['mode']} {r['axis']}" for r in failing)),
        "slip_onset_phase": dict(Counter(str(r.get("onset_phase")) for r in failing)),
        "failing": {"friction_use_median": med("friction_use_median", failing),
                    "effort_max_median": med("effort_max", failing),
                    "with_actuator_at_limit": sum(bool(r["actuators_at_limit"]) for r in failing),
                    "with_sliding_contact": sum(r["contacts_sliding"] > 0 for r in failing),
                    "fn_total_median_n": med("fn_total_n", failing),
                    "lever_arm_median_m": med("lever_arm_m", failing),
                    "support_median": support(failing)},
        "passing": {"friction_use_median": med("friction_use_median", passing),
                    "effort_max_median": med("effort_max", passing),
                    "fn_total_median_n": med("fn_total_n", passing),
                    "lever_arm_median_m": med("lever_arm_m", passing),
                    "support_median": support(passing)},
    }
