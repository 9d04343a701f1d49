"""The three joint vectors a closing runs through: pregrasp → grasp → squeeze.

DexGraspBench closes a hand from a pregrasp to the grasp and then to a squeeze target, and every
grasp generator makes those two extra vectors its own way; the benchmark's verdicts depend on the
way as much as on the grasp (reference README: 79 / 54 / 27 % with dexaug's targets, 97 / 76 /
35 % with BODex's). A grasp that carries its pregrasp and squeeze is run with them; otherwise a
named convention makes them:

- ``dexaug``: the validator's contact-based targets (:mod:`sim.validate.targets`: contacts
  moved back along their normals, and pressed in with a grip force sized by the weight). For
  the benchmark (``through_touch``) the grasp stage is the grasp with its contacts moved onto
  the surface (``touch``), and the pregrasp and squeeze are derived there: FSG leaves
  fingertips up to its 5 mm contact plane off the surface, so closing pregrasp → grasp left
  the touching fingers pressing the free object while the others still travelled, and the
  benchmark counts the motion that gave it (README "Grasps that hold");
- ``bodex``: BODex's: the pregrasp as ``dexaug`` makes it (or the grasp's own), squeeze =
  2·grasp − pregrasp;
- ``dgb-rule``: DexGraspBench's rule for grasp-only methods: 0.9·grasp and 1.1·grasp.

The convention used is recorded with every result. Units: radians (joint vectors).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sim.errors import GraspInputError
from sim.grasp import Grasp
from sim.validate.config import SQUEEZE_CONVENTIONS
from sim.validate.targets import GraspTargets

__all__ = ["GraspStages", "grasp_stages"]


@dataclass(frozen=True)
class GraspStages:
    """Pregrasp, grasp and squeeze joint vectors (full hand vectors, radians) and how they were
    made: a convention name, or ``"given"`` when the grasp carried both (a ``bodex`` squeeze is
    always made from the pregrasp, given or not). ``grasp`` is the grasp's own joints, except
    in a ``dexaug`` closing through the touching grasp (module docstring).
    ``pregrasp_own_split``: a made ``dexaug`` pregrasp's alternative with the fingers' free
    modes at the grasp's split (:class:`sim.validate.targets.GraspTargets`; None: none)."""

    pregrasp: np.ndarray
    grasp: np.ndarray
    squeeze: np.ndarray
    made_by: str
    pregrasp_own_split: np.ndarray | None = None


def grasp_stages(grasp: Grasp, convention: str, derive: Callable[[np.ndarray], GraspTargets],
                 *, through_touch: bool = False) -> GraspStages:
    """The stages of ``grasp`` under ``convention`` (one of ``SQUEEZE_CONVENTIONS``);
    ``derive(q)`` gives the validator's contact-based targets of the grasp with joints ``q``
    and is only called when needed; ``through_touch``: a ``dexaug`` closing goes through the
    touching grasp (module docstring; the benchmark's)."""
    if convention not in SQUEEZE_CONVENTIONS:
        raise GraspInputError(f"squeeze convention: expected one of {SQUEEZE_CONVENTIONS}, "
                              f"got {convention!r}")
    q = grasp.joints
    if convention == "dgb-rule":
        return GraspStages(0.9 * q, q, 1.1 * q, convention)
    need_squeeze = convention == "dexaug" and grasp.squeeze is None
    targets = derive(q) if grasp.pregrasp is None or need_squeeze else None
    touch = q
    if need_squeeze and through_touch and targets is not None and targets.touch is not None:
        touch = targets.touch
        targets = derive(touch)
    if grasp.pregrasp is not None:
        pregrasp = grasp.pregrasp
    else:
        assert targets is not None  # derived whenever the grasp has no pregrasp
        pregrasp = targets.pregrasp
    if convention == "bodex":
        return GraspStages(pregrasp, q, 2.0 * q - pregrasp, convention)
    if targets is None:
        assert grasp.squeeze is not None  # a dexaug grasp without a squeeze has derived targets
        return GraspStages(pregrasp, q, grasp.squeeze, "given")
    squeeze = grasp.squeeze if grasp.squeeze is not None else targets.squeeze
    own_split = targets.pregrasp_own_split if grasp.pregrasp is None else None
    return GraspStages(pregrasp, touch, squeeze, convention, own_split)
