"""How the operator reaches for the object: the approach direction and the hand's pre-shape
(:func:`plan_reach`), chosen so that the hand touches neither the table nor the object before
it closes.

Why: people do not reach with a flat open hand along a fixed line and close it only on
arrival. During the transport the hand pre-shapes (the fingers open to an aperture a little
wider than the object) and comes in from where the fingers clear the object, and an operator in
the headset sees the virtual table and keeps the fingers off it, as they would a real one
(Jeannerod's reach-to-grasp). The first synthetic operator reached with the relaxed open hand
(:meth:`HandPose.relaxed`) along the palm normal: for grasps whose fingers point down at the
table (a can wrapped from above its side) its extended fingertips went 2.7 cm *into* the
table on arrival — the robot fingers pushed on it, bent the wrist 0.65 rad and missed the can —
and with the fingers less open, they pushed the can 3.7 cm along the table before closing.

What is chosen. Among a few approach directions (:func:`approach_directions`: back along the
palm normal and up, the old one, first; along the palm normal; back along the fingers; up; and
blends), and per finger an opening (:data:`OPENINGS`: the fraction of the way from the grasp
pose to the relaxed hand), the plan keeps every joint of the human hand (minus its radius)

- during the reach and the closure, at least ``table_clearance_m`` above the table, and
- during the reach, at least ``object_clearance_m`` from the object's surface,

or, where the grasp itself puts a joint nearer (the palm of a wrap touches the object, the
little finger of a low wrap nearly touches the table), as far as it will be in the grasp: no
part comes closer on the way than where it ends up, and nothing passes through.

Per direction, each finger (an independent chain on the wrist) takes its widest opening that
keeps both; a direction is better when more fingers (and the palm) keep them, then when the
smallest clearance left is larger. Where nothing keeps them, the best is still taken: the grasp
is what the operator means to do.

The closure (:func:`contact_progress`): joint-space interpolation from the pre-shape to the
grasp brings the fingers that have least to travel onto the object first, and in free mode a
finger that touches alone pushes the object away before the thumb arrives (the first closed loop
lost the thumb's contact by 2.5 cm this way). People coordinate the closure so that thumb and
fingers meet the object together (within tens of milliseconds), so the episode warps each
finger's closure to touch at the same moment; this gives, per finger, how far along its own
straight joint-space closure it first touches.

Distances to the object come from its surface vertices and their normals (a k-d tree; YCB
meshes carry ~8,000 vertices, so this is within a few millimetres of the exact surface).
Units: metres, seconds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from teleop.messages import JOINT_INDEX, OPENXR_JOINTS
from teleop.synthetic.human_hand import FINGER_LIMITS, LONG_FINGERS, THUMB_LIMITS, HandPose, HumanHand

__all__ = ["OPENINGS", "WIDER", "Obstacles", "ReachPlan", "approach_directions",
           "contact_progress", "plan_reach", "reach_clearance_m"]

Array = np.ndarray

#: Opening fractions tried per finger, widest first (1: the relaxed open hand, 0: the grasp).
OPENINGS: tuple[float, ...] = tuple(float(x) for x in np.round(np.linspace(1.0, 0.0, 11), 2))
#: Openings past the relaxed hand (the same line extended, within the joint limits), tried,
#: least first, for a finger that no opening up to the relaxed hand keeps clear.
WIDER: tuple[float, ...] = (1.25, 1.5, 1.75, 2.0)

#: Slack on the object clearance (metres): the vertex approximation of the surface.
_SLACK_M = 0.002

_FINGERS = ("thumb", *LONG_FINGERS)
_ROWS = {f: [JOINT_INDEX[n] for n in OPENXR_JOINTS if n.startswith(f"{f}_")] for f in _FINGERS}
_PALM_ROWS = [i for i, n in enumerate(OPENXR_JOINTS)
              if n in ("wrist", "palm") or n.endswith("_metacarpal")]


@dataclass(frozen=True)
class Obstacles:
    """The table top (world z, metres) and the object's surface (vertices and outward unit
    normals, world, metres) the operator sees."""

    table_z_m: float
    points_m: Array
    normals: Array
    #: a k-d tree over ``points_m``, built once (``__post_init__``)
    _tree: cKDTree = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_tree", cKDTree(self.points_m))

    def object_clearance_m(self, points_m: Array) -> Array:
        """Signed distance (metres, negative inside) of points (..., 3) from the surface."""
        flat = points_m.reshape(-1, 3)
        d, i = self._tree.query(flat, workers=-1)
        side = np.einsum("ij,ij->i", flat - self.points_m[i], self.normals[i])
        return (np.where(side < 0.0, -d, d)).reshape(points_m.shape[:-1])


@dataclass(frozen=True)
class ReachPlan:
    """The chosen approach direction (unit, world: the wrist starts back along it), the
    pre-shape, and per finger its opening (:data:`OPENINGS`) and whether it keeps the
    clearances (module docstring)."""

    away: Array
    preshape: HandPose
    openings: dict[str, float]
    clear: dict[str, bool]


#: Given an approach direction: wrist position (metres), axes and closure (0 open, 1 grasp)
#: at a time (seconds), and the sample times of the reach and of the closure.
PathFor = Callable[[Array], tuple[Callable[[float], tuple[Array, Array, float]], Array, Array]]


def approach_directions(palm_normal: Array, finger_dir: Array) -> list[Array]:
    """Candidate directions to back off from the grasp along (unit, world), the old default
    (back along the palm normal and up) first. ``palm_normal``: from the palm toward the
    object; ``finger_dir``: from the wrist toward the fingertips."""
    up = np.array([0.0, 0.0, 1.0])
    back, along = -np.asarray(palm_normal, float), -np.asarray(finger_dir, float)
    raw = [back + 0.5 * up, back, along, up, back + along, back + up, along + up]
    out: list[Array] = []
    for d in raw:
        n = float(np.linalg.norm(d))
        if n > 1e-6 and not any(float(d @ o) / n > 0.999 for o in out):
            out.append(d / n)
    return out


_LOWER = np.concatenate([THUMB_LIMITS[0], *[FINGER_LIMITS[0]] * len(LONG_FINGERS)])
_UPPER = np.concatenate([THUMB_LIMITS[1], *[FINGER_LIMITS[1]] * len(LONG_FINGERS)])


def _opened(grasp: HandPose, relaxed: HandPose, a: float) -> HandPose:
    """The hand ``a`` of the way from ``grasp`` to ``relaxed`` (past it for a > 1), within the
    human joint limits."""
    g = grasp.vector()
    return HandPose.from_vector(np.clip(g + a * (relaxed.vector() - g), _LOWER, _UPPER))


def reach_clearance_m(at_grasp_m: Array, object_clearance_m: float, pressed: bool) -> Array:
    """How far (metres) each hand joint must keep off the object during the reach, given its
    clearance in the grasp ``at_grasp_m``: ``object_clearance_m``, or less where the grasp
    itself puts the joint nearer, and, for a ``pressed`` grasp, never less than touching.

    Why. A generic grasp closes the fingertips ``press_depth_m`` *past* the surface on purpose
    (the operator squeezes until the object stops them): that depth is the squeeze, not where
    the hand may be on its way, and taking it as the allowance let the pre-shaped thumb slide
    1–2 cm deep through a tuna can or a pudding box during the whole reach (the simulated
    thumb then shoved the object 1–3 cm before the hand closed). A reference grasp is imitated
    as it is: where its fitted fingers end inside the surface (the human model's finger radius
    on the robot's pulp site), they may come that near on the way — held to touching, the
    fingers that wrap a soup can from above, pointing at the table, had no opening left that
    cleared both and went 1 cm into the table instead."""
    floor = np.maximum(at_grasp_m, 0.0) if pressed else at_grasp_m
    return np.minimum(object_clearance_m, floor)


def _with_fingers(base: HandPose, angles: dict[str, Array]) -> HandPose:
    return HandPose({f: angles.get(f, base.fingers[f]) for f in LONG_FINGERS},
                    angles.get("thumb", base.thumb))


def _angles(pose: HandPose, finger: str) -> Array:
    return pose.thumb if finger == "thumb" else pose.fingers[finger]


def plan_reach(human: HumanHand, grasp: HandPose, path_for: PathFor, obstacles: Obstacles,
               table_clearance_m: float, object_clearance_m: float,
               directions: Sequence[Array], pressed: bool = False) -> ReachPlan:
    """The best approach direction of ``directions`` and its pre-shape (module docstring).

    ``path_for(direction)`` gives the wrist path of the motion that backs off along it and
    the sample times of its reach and its closure; ``pressed``: the grasp closes its
    fingertips past the surface (:func:`reach_clearance_m`)."""
    relaxed = HandPose.relaxed()
    radii = human.radii
    best: tuple[tuple[int, float], ReachPlan] | None = None
    for away in directions:
        path, reach_t, close_t = path_for(away)
        reach = [path(float(t)) for t in reach_t]
        close = [path(float(t)) for t in close_t]
        p_g, r_g, _ = path(float(close_t[-1]))
        at_grasp = human.joints(grasp, p_g, r_g)[0]
        need = reach_clearance_m(obstacles.object_clearance_m(at_grasp) - radii,
                                 object_clearance_m, pressed) - _SLACK_M
        floor = obstacles.table_z_m + np.minimum(table_clearance_m, at_grasp[:, 2] - radii
                                                 - obstacles.table_z_m) - _SLACK_M
        table_low: dict[float, Array] = {}
        object_low: dict[float, Array] = {}
        for a in OPENINGS + WIDER:   # all fingers at opening a: fingers are independent chains
            pre = _opened(grasp, relaxed, a)
            reach_pts = np.stack([human.joints(pre, p, r)[0] for p, r, _ in reach])
            close_pts = np.stack([human.joints(HandPose.from_vector(
                pre.vector() + c * (grasp.vector() - pre.vector())), p, r)[0]
                for p, r, c in close])
            table_low[a] = np.concatenate([reach_pts, close_pts])[..., 2].min(axis=0) \
                - radii - floor
            object_low[a] = (obstacles.object_clearance_m(reach_pts) - radii - need).min(axis=0)
        openings, clear, margins, chosen = {}, {}, [], {}
        for f in _FINGERS:
            rows = _ROWS[f]
            margin = {a: min(float(table_low[a][rows].min()), float(object_low[a][rows].min()))
                      for a in OPENINGS + WIDER}
            ok = [a for a in OPENINGS + WIDER if margin[a] >= 0.0]
            a = ok[0] if ok else max(margin, key=lambda x: margin[x])
            openings[f], clear[f] = a, bool(ok)
            margins.append(margin[a])
            chosen[f] = _angles(_opened(grasp, relaxed, a), f)
        palm = min(float(table_low[0.0][_PALM_ROWS].min()), float(object_low[0.0][_PALM_ROWS].min()))
        clear["palm"] = palm >= 0.0
        score = (sum(clear.values()), min(min(margins), palm))
        plan = ReachPlan(np.asarray(away, float), _with_fingers(grasp, chosen), openings, clear)
        if best is None or score > best[0]:
            best = (score, plan)
    assert best is not None, "no approach direction given"
    return best[1]


def contact_progress(human: HumanHand, preshape: HandPose, grasp: HandPose, wrist_pos_m: Array,
                     wrist_rot: Array, obstacles: Obstacles, touch_m: float,
                     samples: int = 41) -> dict[str, float]:
    """Per finger, the fraction (0–1] of its joint-space closure from ``preshape`` to
    ``grasp`` (wrist fixed at the grasp) at which its tip first comes within ``touch_m``
    (metres, beyond its radius) of the object; fingers that never do are left out."""
    tip = {f: JOINT_INDEX[f"{f}_tip"] for f in _FINGERS}
    a, b = preshape.vector(), grasp.vector()
    s = np.linspace(0.0, 1.0, samples)
    pts = np.stack([human.joints(HandPose.from_vector(a + x * (b - a)), wrist_pos_m, wrist_rot)[0]
                    for x in s])
    out: dict[str, float] = {}
    for f, i in tip.items():
        near = np.flatnonzero(obstacles.object_clearance_m(pts[:, i]) - human.radii[i] <= touch_m)
        if len(near):
            out[f] = float(max(s[near[0]], 1.0 / (samples - 1)))
    return out
