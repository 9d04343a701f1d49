"""The registered validation protocols, by name (``lift-drop``, ``six-dir``, ``dgb``, …).

Importing :mod:`sim.validate.protocols` registers the built-in ones; a new protocol is one
:class:`~sim.validate.protocols.base.Protocol` subclass passed to :func:`register` (usable as a
class decorator), after which every validator entry point takes its name.
"""

from __future__ import annotations

from typing import TypeVar

from sim.validate.protocols.base import ClosingProtocol, Protocol

__all__ = ["get", "get_closing", "names", "register", "unregister"]

P = TypeVar("P", bound=type[Protocol])

_REGISTERED: dict[str, Protocol] = {}


def register(cls: P, *, replace: bool = False) -> P:
    """Register (an instance of) protocol class ``cls`` under ``cls.name``; returns ``cls``.
    A name already taken raises unless ``replace``."""
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name:
        raise ValueError(f"protocol class {cls.__name__} has no name")
    if name in _REGISTERED and not replace:
        raise ValueError(f"protocol {name!r} is registered already ({type(_REGISTERED[name]).__name__})")
    _REGISTERED[name] = cls()
    return cls


def unregister(name: str) -> None:
    """Remove protocol ``name`` (a test's toy protocol, say)."""
    get(name)
    del _REGISTERED[name]


def names() -> tuple[str, ...]:
    """The registered protocols' names, in registration order."""
    return tuple(_REGISTERED)


def get(name: str) -> Protocol:
    """The protocol registered as ``name``; an unknown name raises, listing the registered ones."""
    try:
        return _REGISTERED[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown protocol {name!r}; expected one of {names()}") from None


def get_closing(name: str) -> ClosingProtocol:
    """Protocol ``name`` when it runs as one program (:class:`ClosingProtocol`), batchable."""
    protocol = get(name)
    if not isinstance(protocol, ClosingProtocol):
        closing = tuple(n for n, p in _REGISTERED.items() if isinstance(p, ClosingProtocol))
        raise ValueError(f"protocol {name!r} has no program; expected one of {closing}")
    return protocol
