"""``dexaug``: one command with subcommands for every stage of the pipeline.

Libraries never print; this module turns their results into tables and progress bars, and turns
dexaug's own errors into one clear line (exit status 2) instead of a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import signal
import sys
import threading

from rich.console import Console

from dexaug.commands.registry import COMMANDS
from sim.errors import DexaugError

#: the command modules, in the order ``dexaug --help`` lists their subcommands (the data flow:
#: assets and validation, the demo, capture, augmentation, the dashboard)
COMMAND_MODULES = tuple(f"dexaug.commands.{m}" for m in (
    "assets", "validate", "demo", "workspace", "teleop", "augment", "stream", "ui"))


def build_parser() -> argparse.ArgumentParser:
    for module in COMMAND_MODULES:   # importing a command module registers its subcommands
        importlib.import_module(module)

    parser = argparse.ArgumentParser(
        prog="dexaug", description="Teleoperation-to-dataset system for dexterous robot hands: "
        "capture and replay demonstrations, augment them into many grasps (AutoWS + FSG), and "
        "validate every grasp in MuJoCo.")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (setup, fn) in COMMANDS.items():
        doc = (fn.__doc__ or "").strip()
        p = sub.add_parser(name, help=doc.splitlines()[0] if doc else None, description=doc,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        setup(p)
        p.set_defaults(handler=fn)
    return parser


def _exit_on_sigterm() -> None:
    """SIGTERM (a service manager, ``kill``) ends the command like Ctrl-C: the interpreter exits
    normally, so recordings are closed and worker pools shut down instead of being cut off."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _exit_on_sigterm()
    console = Console(width=None if sys.stdout.isatty() else 160)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return args.handler(args, console)
    except DexaugError as exc:
        Console(stderr=True).print(f"[bold red]error:[/] {exc}", highlight=False)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
