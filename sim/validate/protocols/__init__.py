"""Validation protocols as plug-ins: :class:`Protocol`, the registry, and the built-in ones
(``lift-drop``, ``six-dir``, ``dgb``, registered in that order on import). See :mod:`.base`."""

# isort: off
from sim.validate.protocols import lift_drop, six_dir, dgb  # noqa: F401  (registers them)
# isort: on
from sim.validate.protocols.base import Bench, ClosingProtocol, Options, Protocol
from sim.validate.protocols.registry import get, get_closing, names, register, unregister

__all__ = ["Bench", "ClosingProtocol", "Options", "Protocol", "get", "get_closing", "names",
           "register", "unregister"]
