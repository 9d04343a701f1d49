"""Subcommand ``repair``: a readable copy of a killed or damaged session recording.

The work is :func:`teleop.record.repair.repair`; this module only parses and prints.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from dexaug.commands.guards import require_writable
from dexaug.commands.registry import command

__all__ = ["repair_cmd"]


def _repair_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="the MCAP session to repair (never modified)")
    p.add_argument("--out", type=Path, metavar="FIXED.mcap",
                   help="where the repaired copy goes (default: NAME.repaired.mcap beside the "
                   "source); an existing file is not replaced")


@command("repair", _repair_args)
def repair_cmd(args: argparse.Namespace, console: Console) -> int:
    """Write a readable copy of a killed or damaged recording (every intact record kept).

    A recorder killed mid-session leaves a file without summary or footer, which the plain
    mcap reader and Foxglove's seeking refuse. The copy holds every schema, channel, metadata
    record and message that can be trusted (CRC-checked chunks up to the cut; around damage,
    reading resumes at the next intact chunk), with a summary and footer. It says what was
    found and where the file was cut or damaged. The source is never written to.
    """
    from teleop.record.repair import default_output, repair

    require_writable(args.out or default_output(args.file), "--out")
    report = repair(args.file, args.out)
    for line in report.lines():
        console.print(line, markup=False, highlight=False)
    return 0
