"""Hand-built reference grasps (``configs/hands/<hand>/grasps.toml``): known-good grasps used as the
validator's ground truth, by ``make demo`` and by the tests. Joints are given by name (radians);
joints not named are 0, coupled followers are filled from their leaders when not named."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.config import load_toml
from sim.errors import ConfigError
from sim.grasp import Grasp
from sim.hand.config import hand_dir
from sim.hand.model import Hand


@dataclass(frozen=True)
class ReferenceGrasp:
    name: str
    object: str
    grasp: Grasp
    note: str


def load_reference_grasps(hand: Hand, path: Path | None = None) -> list[ReferenceGrasp]:
    path = path or hand_dir(hand.name) / "grasps.toml"
    root = load_toml(path)
    root.reject_unknown({"grasps"})
    out = []
    for sec in root.sections("grasps"):
        sec.reject_unknown({"name", "object", "palm_pos", "palm_quat_wxyz", "joints", "note"})
        joints = sec.section("joints")
        q = np.zeros(hand.nq)
        named = set()
        for joint in joints.data:
            if joint not in hand.joint_names:
                raise ConfigError(f"{joints.where(joint)}: unknown joint of hand {hand.name!r}")
            q[hand.joint_names.index(joint)] = joints.float(joint)
            named.add(joint)
        filled = hand.fill_coupled(q)
        q = np.array([q[i] if n in named else filled[i] for i, n in enumerate(hand.joint_names)])
        out.append(ReferenceGrasp(
            name=sec.str("name"), object=sec.str("object"), note=sec.str("note", ""),
            grasp=Grasp.from_arrays(sec.floats("palm_pos", 3), sec.floats("palm_quat_wxyz", 4), q)))
    return out
