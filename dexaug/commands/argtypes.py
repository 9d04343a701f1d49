"""Argument types that check a value's range while the command line is parsed.

Why here and not in the libraries: a count of 0 or a port of 70000 is a typing mistake, and
argparse reports it at once, naming the option, before a command spends seconds loading a hand,
an object or a workspace only to refuse the value there. The libraries keep their own checks
for callers that do not come through the CLI. Each function raises
:class:`argparse.ArgumentTypeError`, which argparse turns into ``argument --OPTION: MESSAGE``.
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable

__all__ = ["count", "free_port", "int_at_least", "port", "positive", "rate", "rig_name"]

#: a rig name is one plain zenoh key chunk: no separators, wildcards or spaces
_RIG_NAME = re.compile(r"[A-Za-z0-9_-]+")


def int_at_least(low: int) -> Callable[[str], int]:
    """The type of a whole number >= ``low`` (``count`` is ``int_at_least(1)``)."""

    def whole(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {low}, got {text!r}") from None
        if n < low:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {low}, got {n}")
        return n

    return whole


#: a number of things >= 1 (grasps, workers, tries)
count = int_at_least(1)


def positive(text: str) -> float:
    """A finite number > 0 (seconds, frames per second): ``nan`` and ``inf`` are refused, as a
    budget of ``inf`` would never stop and ``nan`` compares false with every limit."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return x


def rate(text: str) -> float | str:
    """A playback speed factor: a finite number > 0 (:func:`positive`), or ``max`` (as fast
    as possible)."""
    if text == "max":
        return text
    try:
        return positive(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected a finite speed factor > 0 or 'max', "
                                         f"got {text!r}") from None


def _tcp_port(text: str, low: int) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number {low}-65535, got {text!r}") from None
    if not low <= n <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number {low}-65535, got {n}")
    return n


def port(text: str) -> int:
    """A port number 1–65535 (one that is connected to, or printed as the address)."""
    return _tcp_port(text, 1)


def free_port(text: str) -> int:
    """A port to listen on, 0–65535, where 0 lets the system pick a free one."""
    return _tcp_port(text, 0)


def rig_name(text: str) -> str:
    """A rig name: one zenoh key chunk of letters, digits, ``_`` and ``-`` (it becomes the
    ``dexaug/<rig>/…`` key prefix, where ``/`` would add levels and ``*`` match other rigs)."""
    if not _RIG_NAME.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected a rig name of letters, digits, '_' and '-', "
                                         f"got {text!r}")
    return text
