"""Subcommand ``validate``: a hand's reference grasps validated in MuJoCo, as a results table.

:func:`run_reference_validation` is the job itself (also callable without the CLI parser).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console
from rich.progress import Progress
from rich.table import Table
from rich.text import Text

from dexaug.commands.guards import object_name, require_writable
from dexaug.commands.options import hand_arg
from dexaug.commands.registry import command

if TYPE_CHECKING:
    from sim.validate.result import ValidationResult

__all__ = ["run_reference_validation", "validate"]


def _validate_args(p: argparse.ArgumentParser) -> None:
    hand_arg(p)
    p.add_argument("--object", type=object_name, help="only grasps of this object")
    p.add_argument("--grasps", type=Path, help="reference-grasp TOML (default: "
                   "configs/hands/<hand>/grasps.toml)")
    from sim.validate.config import PROTOCOLS

    p.add_argument("--protocol", choices=(*PROTOCOLS, "all"), default="all",
                   help="lift-drop, six-dir, dgb (DexGraspBench's protocol) or all; default %(default)s")
    p.add_argument("--render", type=Path, metavar="DIR",
                   help="write a PNG of each grasp after closing (contacts marked) into DIR")
    p.add_argument("--json", type=Path, help="write the full results as JSON")


def _result_table(rows: Sequence[tuple[str, str, tuple[ValidationResult, float]]]) -> Table:
    table = Table(title="grasp validation")
    for col in ("grasp", "object", "protocol", "result", "reason", "contacts", "pen. (mm)",
                "disp. (mm)", "rot. (°)", "GWS ε", "GWS vol.", "time (s)"):
        table.add_column(col, justify="right" if col[0] in "cpdrGt" else "left")
    for name, obj, (res, seconds) in rows:
        verdict = Text("pass", style="green") if res.passed else Text("fail", style="red")
        table.add_row(name, obj, res.protocol, verdict,
                      res.failure or "", str(res.n_contacts), f"{res.penetration_m * 1e3:.1f}",
                      f"{res.displacement_m * 1e3:.1f}", f"{np.degrees(res.rotation_rad):.1f}",
                      f"{res.epsilon:.4f}", f"{res.volume:.2e}", f"{seconds:.2f}")
    return table


def run_reference_validation(hand_name: str, console: Console, *, object_name: str | None = None,
                             grasps_path: Path | None = None, protocols: tuple[str, ...] = (
                                 "lift-drop", "six-dir", "dgb"), render_dir: Path | None = None,
                             json_path: Path | None = None) -> int:
    """Validate the hand's reference grasps and print a results table; returns the exit code."""
    from sim.hand.model import Hand
    from sim.hand.reference_grasps import load_reference_grasps
    from sim.io import write_bytes_atomic
    from sim.validate.validator import Validator
    from sim.world.objects import load_object

    hand = Hand.load(hand_name)
    refs = [r for r in load_reference_grasps(hand, grasps_path)
            if object_name in (None, r.object)]
    if not refs:
        console.print(f"no reference grasps for hand {hand_name!r}"
                      + (f" and object {object_name!r}" if object_name else ""))
        return 1
    validators: dict[str, Validator] = {}
    rows = []
    with Progress(console=console, transient=True) as progress:
        task = progress.add_task("validating", total=len(refs) * len(protocols))
        for ref in refs:
            if ref.object not in validators:
                validators[ref.object] = Validator(hand, load_object(ref.object))
            validator = validators[ref.object]
            for protocol in protocols:
                start = time.perf_counter()
                res = validator.validate(ref.grasp, protocol)
                rows.append((ref.name, ref.object, (res, time.perf_counter() - start)))
                progress.advance(task)
            if render_dir is not None:
                from sim.world.render import save_png

                path = render_dir / f"{ref.name}.png"
                save_png(path, validator.render(ref.grasp))
                console.print(f"wrote {path}")
    console.print(_result_table(rows))
    if json_path is not None:
        payload = [{"grasp": n, "object": o, "seconds": t, **r.summary()} for n, o, (r, t) in rows]
        write_bytes_atomic(json_path, json.dumps(payload, indent=2, default=float).encode())
        console.print(f"wrote {json_path}")
    passed = sum(r.passed for _, _, (r, _) in rows)
    console.print(f"{passed}/{len(rows)} validations passed")
    return 0


@command("validate", _validate_args)
def validate(args: argparse.Namespace, console: Console) -> int:
    """Validate grasps in MuJoCo: lift-drop, six-dir and/or dgb (DexGraspBench), DESIGN §5.

    Without --grasps, validates the hand's hand-built reference grasps
    (configs/hands/<hand>/grasps.toml). Prints per grasp: pass/fail and why, contact count,
    penetration, object displacement and rotation, and the GWS ε/volume of the simulated contacts.
    """
    from sim.validate.config import PROTOCOLS

    protocols = PROTOCOLS if args.protocol == "all" else (args.protocol,)
    if args.json:
        require_writable(args.json, "--json")
    if args.render:
        require_writable(args.render, "--render", folder=True)
        from sim.world.render import select_gl_backend

        select_gl_backend()
    return run_reference_validation(args.hand, console, object_name=args.object,
                                    grasps_path=args.grasps, protocols=protocols,
                                    render_dir=args.render, json_path=args.json)
