"""What the commands and reports need to know of a validation protocol, asked of the registry.

Why: a command that branches on a protocol's name (``if protocol == "dgb"``) must be edited for
every new protocol; asked here, a protocol is one plug-in (:mod:`sim.validate.protocols`) and
nothing else. Everything is read from the plug-ins: which protocols a batch backend steps (those
that run as one program, :class:`~sim.validate.protocols.base.ClosingProtocol`), the
registration order the choices keep, and three class attributes of
:class:`~sim.validate.protocols.base.Protocol`:

* ``drift_reference`` — where a verdict's displacement and rotation are measured from:
  ``"palm"`` (relative to the hand: lift-drop, six-dir) or ``"start"`` (from the object's
  initial world pose: ``dgb``, as DexGraspBench measures);
* ``diagnosis`` — the module and the ``diagnose``/``summarise`` pair that replay a grasp under
  the protocol and explain its verdict (``dexaug diagnose``); protocols without one are not
  offered there;
* ``fsg_hold_oversample`` — the :class:`augment.fsg.params.FsgParams` field that says how many
  grasps FSG finds per grasp wanted before ranking them by the effort this protocol's loads
  need (``dgb``: ``dgb_hold_oversample``, its loads being the benchmark's light ones).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar, cast

from sim.validate.protocols import registry
from sim.validate.protocols.base import ClosingProtocol

if TYPE_CHECKING:
    from augment.fsg.params import FsgParams

__all__ = ["DEFAULT_PROTOCOL", "Diagnosis", "batch_protocols", "diagnosable", "diagnosis",
           "drift_reference", "hold_oversample", "spoken"]

#: the protocol used where none is named: lift-drop, the user's own test (DESIGN §5)
DEFAULT_PROTOCOL = "lift-drop"

T = TypeVar("T")

def _fact(protocol: str, attribute: str, default: T) -> T:
    """The plug-in's ``attribute``; a name the registry does not know (an old dataset's) gets
    ``default``."""
    if protocol not in registry.names():
        return default
    return cast(T, getattr(registry.get(protocol), attribute))


def batch_protocols() -> tuple[str, ...]:
    """The protocols a batch backend (``mujoco.batch``, MuJoCo Warp) steps: those that run as
    one program, in registration order (``("lift-drop", "six-dir")``)."""
    return tuple(n for n in registry.names() if isinstance(registry.get(n), ClosingProtocol))


def drift_reference(protocol: str) -> str:
    """``"palm"`` or ``"start"``: what a verdict's drift is measured against (module docstring)."""
    return _fact(protocol, "drift_reference", "palm")


@dataclass(frozen=True)
class Diagnosis:
    """How ``dexaug diagnose`` replays a grasp under a protocol: ``diagnose(validator, grasp)``
    gives one grasp's findings, ``summarise(diagnoses)`` an object's summary (plain data);
    ``module`` is where both live, which also says how the summary is laid out."""

    module: str
    diagnose: Callable[..., Any]
    summarise: Callable[..., dict[str, Any]]


def diagnosable() -> tuple[str, ...]:
    """The protocols with a diagnosis, in registration order (``("lift-drop", "dgb")``)."""
    return tuple(n for n in registry.names()
                 if _fact(n, "diagnosis", None) is not None)


def diagnosis(protocol: str) -> Diagnosis:
    """``protocol``'s diagnosis (:class:`Diagnosis`); a protocol without one raises, naming the
    ones with."""
    found = _fact(protocol, "diagnosis", None)
    if found is None:
        raise ValueError(f"protocol {protocol!r} has no diagnosis; expected one of {diagnosable()}")
    module, diagnose, summarise = found
    mod = importlib.import_module(module)
    return Diagnosis(module, getattr(mod, diagnose), getattr(mod, summarise))


def hold_oversample(params: FsgParams, protocol: str) -> float:
    """How many grasps FSG finds per grasp wanted before ranking by ``protocol``'s loads (a
    factor on n): the ``FsgParams`` field the protocol names (module docstring)."""
    return float(getattr(params, _fact(protocol, "fsg_hold_oversample",
                                       "hold_oversample")))


def spoken(names: tuple[str, ...]) -> str:
    """``("a", "b", "c")`` → ``"a, b and c"``: a list of protocols in a sentence."""
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"
