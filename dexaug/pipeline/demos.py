"""Where a demo comes from when a user names one: a demo file, a session, or a reference grasp.

Why here (the application layer): a session needs :mod:`teleop.record.demos` and a reference
grasp needs the validator's scene, so resolving a user's spec is above both ``teleop`` and
``augment``.
"""

from __future__ import annotations

from pathlib import Path

from sim.demo import Demo, DemoError, load_demo
from sim.hand.model import Hand
from sim.hand.reference_grasps import load_reference_grasps
from sim.validate.validator import Validator
from sim.world.objects import load_object
from teleop.record.demos import extract_demos

__all__ = ["resolve_demo"]


def resolve_demo(spec: str, hand_name: str) -> Demo:
    """A demo from what a user types: a demo file (``.json``), a session (``.mcap``: its
    longest-held demo), or the name of a reference grasp of the hand (its fingertip contacts
    found in MuJoCo)."""
    path = Path(spec)
    if path.suffix == ".json":
        return load_demo(path)
    if path.suffix == ".mcap":
        return max(extract_demos(path), key=lambda d: d.duration_s)
    hand = Hand.load(hand_name)
    refs = {r.name: r for r in load_reference_grasps(hand)}
    if spec not in refs:
        raise DemoError(f"demo {spec!r}: not a .json demo, an .mcap session or a reference grasp "
                        f"of {hand_name} (known: {sorted(refs)})")
    ref = refs[spec]
    tips = Validator(hand, load_object(ref.object)).fingertip_contacts(ref.grasp)
    contacts = {k: v for k, v in tips.items() if v is not None}
    return Demo(id=f"grasp:{ref.name}", hand=hand.name, object=ref.object,
                joints=ref.grasp.joints, palm_pos_m=ref.grasp.palm_pos,
                palm_quat_wxyz=ref.grasp.palm_quat_wxyz, tip_contacts=contacts,
                contact_points_obj={}, source=Path(spec), time_s=0.0, how="reference grasp",
                fingers=tuple(sorted(contacts)))
