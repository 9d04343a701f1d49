"""The subcommand registry: each command module registers its subcommands here on import.

Why a module of its own: the command modules and the CLI entry point both need it, and the
entry point imports the command modules, so the registry must sit below both (no import cycle).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from rich.console import Console

Handler = Callable[[argparse.Namespace, Console], int]
Setup = Callable[[argparse.ArgumentParser], None]

#: subcommand name → (argument setup, handler), in registration order
COMMANDS: dict[str, tuple[Setup, Handler]] = {}


def command(name: str, setup: Setup) -> Callable[[Handler], Handler]:
    """Register a subcommand: ``setup`` adds its arguments, the decorated function runs it."""

    def register(fn: Handler) -> Handler:
        COMMANDS[name] = (setup, fn)
        return fn

    return register
