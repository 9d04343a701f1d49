"""``dexaug``: one command with subcommands for every stage of the pipeline.

Libraries never print; this module turns their results into tables and progress bars, and every
error into one line on stderr, never a traceback. Exit statuses:

- 0: done.
- 1: a failing file or socket operation (``OSError``) or anything unforeseen (``-v`` adds the
  traceback to the log), and ``augment`` / ``batch`` when an input or unit failed.
- 2: a usage or input error: a mistyped option is refused while the command line is parsed
  (argparse, before anything is loaded); dexaug's own errors (:class:`~sim.errors.DexaugError`:
  a missing asset, a damaged session, an output folder that cannot be written, checked before
  any work) are printed as one line naming the file or option and what was expected.
- 3: the results were written but fell short: fewer than half of the grasps asked for
  (``--n``; none at all included), see :data:`dexaug.commands.options.SHORT_SHARE`.
- 130: Ctrl-C (143: SIGTERM).

Logging: ``-v/--verbose`` (DEBUG), ``-q/--quiet`` (dexaug's own log from WARNING up) and
``--log-level LEVEL`` are accepted before and after the subcommand (``dexaug -v generate …`` and
``dexaug generate … -v`` are the same). Messages are printed as plain text: a path or name
holding ``[x]`` is shown as it is, not read as rich markup.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import signal
import sys
import threading
from typing import NoReturn

from rich.console import Console
from rich.text import Text

from dexaug.commands.guards import error_hint
from dexaug.commands.options import logging_args
from dexaug.commands.registry import COMMANDS
from dexaug.commands.workers import stop_workers
from dexaug.headless_gl import default_headless_gl
from sim.errors import DexaugError

log = logging.getLogger("dexaug")

#: ``dexaug --help``'s last lines (the module docstring says more)
EXIT_STATUSES = ("exit status: 0 done; 1 a file or socket operation failed, an unforeseen error, "
                 "or an input of augment/batch failed; 2 a usage or input error (one line naming "
                 "the option or file; an output that cannot be written is refused before any "
                 "work); 3 results written but fewer than half of --n grasps; 130 Ctrl-C. "
                 "-v/-q/--log-level go before or after the subcommand.")

#: the packages whose INFO log a command shows (without ``-v``)
OWN_PACKAGES = ("dexaug", "sim", "augment", "teleop")

#: the command modules, in the order ``dexaug --help`` lists their subcommands (the data flow:
#: assets and validation, the demo, capture, augmentation, the dashboard)
COMMAND_MODULES = tuple(f"dexaug.commands.{m}" for m in (
    "assets", "validate", "demo", "workspace", "teleop", "replay", "repair", "generate", "augment", "batch",
    "arm", "diagnose", "export", "stream", "ui", "view"))


def version_text() -> str:
    """``dexaug 0.1.0 (mujoco 3.3.7, mink 0.0.x, …)``: what a result was made with."""
    from sim.versions import package_versions

    versions = package_versions()
    own = versions.pop("dexaug", "unknown")
    return f"dexaug {own} (" + ", ".join(f"{k} {v}" for k, v in versions.items()) + ")"


class _PrintVersion(argparse.Action):
    """``--version``: :func:`version_text` on one line (argparse's own action wraps it)."""

    def __call__(self, parser: argparse.ArgumentParser, *args: object, **kwargs: object) -> None:
        print(version_text())
        parser.exit(0)


def one_line(text: str) -> str:
    """``text`` with every run of whitespace (newlines included) as one space."""
    return " ".join(text.split())


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``dexaug generate: error: argument --n:
    expected a whole number >= 1, got 0``) instead of the usage block and the message."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """The subcommands' help: descriptions as written, and every option's default shown (an
    option whose help does not name its default gets ``(default: X)``; none for flags and
    options without one)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        shown = not (default is None or default is False or default is argparse.SUPPRESS
                     or (isinstance(default, list) and not default))
        if action.option_strings and "default" not in text and shown:
            text += " (default: %(default)s)"
        return text


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of every subcommand; with ``only`` (a subcommand name), the arguments of that
    one alone are set up and the others are listed by name and summary: setting up arguments
    imports the configs their defaults and choices come from (a second for all of them), which
    a mistyped option should not wait for."""
    for module in COMMAND_MODULES:   # importing a command module registers its subcommands
        importlib.import_module(module)

    parser = OneLineParser(
        prog="dexaug", description="Teleoperation-to-dataset system for dexterous robot hands: "
        "capture and replay demonstrations, augment them into many grasps (AutoWS + FSG), and "
        "validate every grasp in MuJoCo.", epilog=EXIT_STATUSES)
    logging_args(parser, top=True)
    parser.add_argument("--version", action=_PrintVersion, nargs=0,
                        help="print dexaug's version and those of the packages results depend on")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (setup, fn) in COMMANDS.items():
        doc = (fn.__doc__ or "").strip()
        p = sub.add_parser(name, help=doc.splitlines()[0] if doc else None, description=doc,
                           formatter_class=HelpFormatter)
        logging_args(p)   # -v, -q, --log-level after the subcommand too
        if only in (None, name):
            setup(p)
        p.set_defaults(handler=fn)
    return parser


#: ``dexaug``'s own options that take a value (as a separate word): skipped when looking for the
#: subcommand's name
_VALUE_OPTIONS = ("--log-level",)


def _command_name(argv: list[str]) -> str | None:
    """The subcommand named in ``argv``: the first word that is neither an option of
    ``dexaug`` nor the value of one (``--log-level LEVEL``), or None."""
    words = iter(argv)
    for a in words:
        if a in _VALUE_OPTIONS:
            next(words, None)
        elif not a.startswith("-"):
            return a
    return None


def _exit_on_sigterm() -> None:
    """SIGTERM (a service manager, ``kill``) ends the command like Ctrl-C: the interpreter exits
    normally, so recordings are closed, instead of being cut off."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(128 + signum))


def _another_interrupt_exits_now(status: int) -> None:
    """While an interrupted command stops its workers (about a second), a further Ctrl-C (an
    impatient user; ``timeout -s INT``, which may deliver it twice) ends the process at once
    with ``status``. Raised inside the handler it printed a traceback and skipped the exit
    status. The workers have been sent SIGTERM or end with their owner."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, lambda signum, frame: os._exit(status))


def log_level(args: argparse.Namespace) -> int:
    """The level of dexaug's own log: ``--log-level`` when given, else DEBUG with ``-v``,
    WARNING with ``-q``, INFO by default."""
    if getattr(args, "log_level", None):
        return logging.getLevelName(args.log_level)
    if getattr(args, "verbose", False):
        return logging.DEBUG
    return logging.WARNING if getattr(args, "quiet", False) else logging.INFO


def _configure_logging(level: int) -> None:
    """dexaug's own log from ``level`` up (:func:`log_level`); other libraries' only from
    WARNING up unless ``level`` is DEBUG (their INFO lines, e.g. PyOpenGL's "No
    OpenGL_accelerate module loaded", say nothing to a user and would bury a command's one-line
    error). Logging configured by the program that calls :func:`main` (a test runner) is left
    as it is."""
    if logging.getLogger().handlers:
        return
    logging.basicConfig(level=logging.DEBUG if level <= logging.DEBUG else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if level > logging.DEBUG:
        for package in OWN_PACKAGES:
            logging.getLogger(package).setLevel(level)


def print_error(message: str) -> None:
    """``error: MESSAGE`` as one line on stderr, the message as plain text (no markup)."""
    text = Text("error: ", style="bold red")
    text.append(one_line(message))
    Console(stderr=True, soft_wrap=True, highlight=False).print(text)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    default_headless_gl()   # before any command module imports MuJoCo (dexaug/headless_gl.py)
    args = build_parser(only=_command_name(argv)).parse_args(argv)
    _exit_on_sigterm()
    # markup off: paths, names and messages print as they are; styled output uses rich Text
    console = Console(width=None if sys.stdout.isatty() else 160, markup=False)
    level = log_level(args)
    _configure_logging(level)
    try:
        return args.handler(args, console)
    except DexaugError as exc:
        print_error(error_hint(str(exc)))
        return 2
    except OSError as exc:    # a file or socket operation failed: the message names it
        print_error(str(exc))
        return 1
    except KeyboardInterrupt:
        _another_interrupt_exits_now(130)
        stop_workers()        # their running tasks would hold the exit until their budget ends
        return 130
    except SystemExit:        # SIGTERM (see _exit_on_sigterm)
        stop_workers()
        raise
    except Exception as exc:  # unforeseen: still one line for the user, the traceback with -v
        log.debug("traceback of the error below", exc_info=True)
        print_error(f"{type(exc).__name__}: {exc}"
                    + ("" if level <= logging.DEBUG else " (run with -v for the traceback)"))
        return 1


if __name__ == "__main__":
    sys.exit(main())
