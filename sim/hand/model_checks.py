"""Checks of a hand config against its compiled model that go beyond names: every fingertip can
touch something, and the config's joint coupling is the one the model simulates.

Why: FSG plans with the config (``coupled_to``) and samples the fingertips' collision meshes,
while MuJoCo simulates the model's geoms and equality constraints. A fingertip without collision
geometry never makes a contact (every grasp it is in fails as "lost contact"), and a coupling the
model does not share gives grasps whose joints the simulation immediately pulls elsewhere. Both
are config mistakes, reported as one line naming the hand file and key.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from sim.errors import ConfigError
from sim.hand.config import HandConfig

__all__ = ["check_coupling", "check_fingertip_collision", "check_model"]

#: relative tolerance on a coupling coefficient (the config writes a few significant digits)
COUPLING_RTOL = 1e-3


def check_fingertip_collision(model: mujoco.MjModel, config: HandConfig, model_name: str) -> None:
    """ConfigError unless every finger's ``tip_body`` has a geom that collides (contype or
    conaffinity non-zero)."""
    for f in config.fingers:
        body = model.body(f.tip_body).id
        geoms = np.flatnonzero(model.geom_bodyid == body)
        if not ((model.geom_contype[geoms] | model.geom_conaffinity[geoms]) != 0).any():
            raise ConfigError(f"{config.file}: fingers '{f.name}'.tip_body: body {f.tip_body!r} "
                              f"of {model_name} has no collision geometry ({len(geoms)} geoms, "
                              f"all with contype = conaffinity = 0): it can never touch an object")


def _model_couplings(model: mujoco.MjModel) -> dict[frozenset[str], tuple[str, str, float]]:
    """Linear joint equality constraints q1 = c·q2 of ``model``: {joint pair: (q1, q2, c)}."""
    out = {}
    for e in range(model.neq):
        if int(model.eq_type[e]) != int(mujoco.mjtEq.mjEQ_JOINT) or model.eq_obj2id[e] < 0:
            continue
        a, b = model.joint(model.eq_obj1id[e]).name, model.joint(model.eq_obj2id[e]).name
        out[frozenset((a, b))] = (a, b, float(model.eq_data[e, 1]))
    return out


def check_coupling(model: mujoco.MjModel, config: HandConfig, model_name: str) -> None:
    """ConfigError when the config's ``coupled_to`` and the model's joint equality constraints
    disagree within a finger: a pair the model couples that the config leaves independent, or
    the same pair with another coefficient. Couplings the model drives otherwise (a tendon
    actuator over two joints, as the Shadow Hand's J0) and constraints across fingers (which
    ``coupled_to`` cannot state) are not compared."""
    couplings = _model_couplings(model)
    for f in config.fingers:
        key = f"fingers '{f.name}'.coupled_to"
        joints = set(f.joints)
        for pair, (a, b, coef) in couplings.items():
            if not pair <= joints:
                continue
            follower = a if a in f.coupled_to else b if b in f.coupled_to else None
            if follower is None:
                raise ConfigError(f"{config.file}: {key}: model {model_name} couples {a} = "
                                  f"{coef:.4g} × {b} (an equality constraint), the config "
                                  f"treats both as independent")
            leader, said = f.coupled_to[follower]
            # the model's q_a = coef · q_b, stated for the config's follower
            want = coef if follower == a else (1.0 / coef if coef else np.inf)
            if leader not in pair or not np.isclose(said, want, rtol=COUPLING_RTOL):
                raise ConfigError(f"{config.file}: {key}.{follower}: the config says "
                                  f"[{leader!r}, {said:.4g}], model {model_name} simulates "
                                  f"{a} = {coef:.4g} × {b}")


def check_model(model: mujoco.MjModel, config: HandConfig, model_path: Path) -> None:
    """Both checks of this module."""
    check_fingertip_collision(model, config, model_path.name)
    check_coupling(model, config, model_path.name)
