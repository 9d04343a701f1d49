"""Whole-hand wraps in a recorded session: which bridge states are a power grasp.

A person who wraps a can or a box closes the whole hand around it: the palm, or the inner
phalanges of several fingers, lie on the object with the thumb and the fingers. Such a grasp
is not a fingertip (precision) demo: FSG, which places fingertips with the palm clear of the
object (paper §4.2.1, "for precision grasp we filter out cases where the transformed
cloud_full penetrates the palm or collides with it"), refuses every candidate near the
demonstrated one. Extraction marks it as a power demo (:data:`sim.demo.POWER`) and the
augmenter seeds its power-grasp generator with it (:mod:`augment.power.demo_seed`).

The rule, read from the recorded contacts (``/contacts`` tags every hand body, ``finger``
only for fingertip bodies), never from object names: a state is a *wrap* when the hand's lead
finger (the thumb: its first in priority order) touches with any of its links, at least
``min_others`` other fingers touch with any of theirs, and the hand touches with its palm
side — a body that belongs to no finger (the palm, the thumb's base) — or with a non-distal
link of at least ``inner_fingers`` fingers. One finger's middle phalanx brushing a box beside
four fingertips stays a precision grasp. What makes a wrap a demo (it lasts, the hand lifts
it) is decided in :mod:`teleop.record.demos`, with the same lift confirmation as a fingertip
grasp.
"""

from __future__ import annotations

import numpy as np

from sim.hand.model import Hand
from teleop.record.demo_track import Track

__all__ = ["finger_of_body", "link_bodies", "wrap_fingers", "wrap_mask", "wrap_points"]


def finger_of_body(hand: Hand) -> dict[str, str]:
    """Hand body name → the finger it belongs to, for every link of every finger."""
    return {link: f.name for f in hand.config.fingers for link in {*f.links, f.tip_body}}


def wrap_fingers(track: Track, i: int, hand: Hand) -> frozenset[str]:
    """The fingers touching the object at state ``i`` with any of their links."""
    of = finger_of_body(hand)
    return frozenset(of[b] for b in _bodies(track, i) if b in of)


def link_bodies(track: Track, i: int, hand: Hand) -> tuple[str, ...]:
    """The hand bodies other than fingertips (palm, phalanges) touching at state ``i``, sorted."""
    tips = {f.tip_body for f in hand.config.fingers}
    return tuple(sorted(b for b in _bodies(track, i) if b not in tips))


def wrap_mask(track: Track, hand: Hand, min_others: int, inner_fingers: int) -> np.ndarray:
    """(n_states,) bool: which states of ``track`` are a wrap (module docstring)."""
    of = finger_of_body(hand)
    tips = {f.tip_body for f in hand.config.fingers}
    lead = hand.finger_names[0]
    out = np.zeros(len(track.states), bool)
    for i in range(len(track.states)):
        bodies = _bodies(track, i)
        fingers = {of[b] for b in bodies if b in of}
        if lead not in fingers or len(fingers - {lead}) < min_others:
            continue
        palm_side = any(b not in of for b in bodies)
        inner = {of[b] for b in bodies if b in of and b not in tips}
        out[i] = palm_side or len(inner) >= inner_fingers
    return out


def wrap_points(track: Track, i: int, hand: Hand) -> dict[str, np.ndarray]:
    """Finger → (k,3) its contact points in the object frame at state ``i`` (metres), over all
    of its links: where the person's fingers lay on the object."""
    of = finger_of_body(hand)
    pts: dict[str, list[list[float]]] = {}
    for c in track.hand_contacts[i] if i < len(track.hand_contacts) else ():
        finger = of.get(str(c.get("hand_body")))
        if finger is not None:
            pts.setdefault(finger, []).append(c["pos_object_m"])
    return {f: np.asarray(p, float).reshape(-1, 3) for f, p in sorted(pts.items())}


def _bodies(track: Track, i: int) -> frozenset[str]:
    return track.bodies_touching[i] if i < len(track.bodies_touching) else frozenset()
