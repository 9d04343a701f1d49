"""Edits a validation protocol makes to the hand before a scene is compiled.

A protocol states the servo gains and force limits it simulates (DESIGN §5: "what a config says
is simulated is what MuJoCo simulates"), and the benchmark protocol floats the hand at its palm
the way DexGraspBench's hand assets do (no wrist joints, no forearm). These edits work on any
hand's ``MjSpec`` so the protocols stay hand-agnostic. Units: N·m/rad (or N/m) for kp, N·m (or N)
for force limits.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco

__all__ = ["ServoSettings", "apply_servos", "detach_palm"]


@dataclass(frozen=True)
class ServoSettings:
    """The hand's position servos as a protocol simulates them.

    ``kp`` sets every servo's stiffness to one value (DexGraspBench: 5 on all finger actuators);
    otherwise ``kp_scale`` multiplies each servo's own kp. ``force_limit`` (when given) sets a
    symmetric force limit on every servo, ``ctrl_limited = False`` removes the control ranges
    (DexGraspBench's squeeze targets may lie past the joint range). Actuators that are not
    position servos (fixed gain, affine bias) are left alone.
    """

    kp_scale: float = 1.0
    kp: float | None = None
    force_limit: float | None = None
    ctrl_limited: bool = True

    def __post_init__(self) -> None:
        if self.kp_scale <= 0 or (self.kp is not None and self.kp <= 0):
            raise ValueError(f"ServoSettings: kp and kp_scale must be > 0, got {self.kp}, {self.kp_scale}")
        if self.force_limit is not None and self.force_limit <= 0:
            raise ValueError(f"ServoSettings.force_limit: expected > 0, got {self.force_limit}")


def _is_position_servo(act: mujoco.MjsActuator) -> bool:
    return (act.gaintype == mujoco.mjtGain.mjGAIN_FIXED
            and act.biastype == mujoco.mjtBias.mjBIAS_AFFINE)


def apply_servos(spec: mujoco.MjSpec, servos: ServoSettings) -> None:
    """Set the position servos of ``spec`` (a hand) to ``servos``: gain and position bias
    (force = gain·ctrl + bias₁·length − kv·velocity keeps its kv; a set kp makes gain = −bias₁
    = kp, so the control is the target length), force limits and control ranges."""
    for act in spec.actuators:
        if not _is_position_servo(act):
            continue
        gain, bias = list(act.gainprm), list(act.biasprm)
        if servos.kp is not None:   # a position servo in the joint's (tendon's) own units
            gain[0], bias[1] = servos.kp, -servos.kp
        else:                       # the stiffness scaled, whatever units the control has
            gain[0], bias[1] = servos.kp_scale * gain[0], servos.kp_scale * bias[1]
        act.gainprm, act.biasprm = gain, bias
        if servos.force_limit is not None:
            act.forcerange = [-servos.force_limit, servos.force_limit]
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        if not servos.ctrl_limited:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE


def detach_palm(spec: mujoco.MjSpec, palm_body: str) -> mujoco.MjsBody:
    """Prepare ``spec`` so its palm body can be attached as a rigid root: the joints on the
    palm body (a wrist joint) and the actuators driving them are deleted, and the palm body is
    returned for ``MjsFrame.attach_body`` (which carries its subtree and the actuators, tendons
    and exclusions that refer to it; the bodies above it — wrist, forearm — stay behind)."""
    palm = spec.body(palm_body)
    if palm is None:
        raise ValueError(f"no body {palm_body!r} in the hand model")
    dropped = {j.name for j in palm.joints}
    for act in list(spec.actuators):
        if act.trntype == mujoco.mjtTrn.mjTRN_JOINT and act.target in dropped:
            spec.delete(act)
    for joint in list(palm.joints):
        spec.delete(joint)
    return palm
