"""Argument builders shared by several subcommands, so a flag means the same everywhere.

``--hand`` (default: ``configs/hands/default.toml``), the grasp-generation options of
``generate``, ``augment`` and ``ui``, and the ``AugmentOptions`` those options stand for.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from dexaug.pipeline.options import AugmentOptions

__all__ = ["augment_options", "generation_args", "hand_arg"]


def hand_arg(p: argparse.ArgumentParser, help: str = "hand config name (configs/hands/<hand>/)") -> None:
    """``--hand NAME``, defaulting to the default hand (shown in the help)."""
    from sim.hand.config import default_hand_name

    p.add_argument("--hand", default=default_hand_name(), help=f"{help}; default %(default)s")


def generation_args(p: argparse.ArgumentParser) -> None:
    """Options shared by ``generate`` and ``augment``."""
    p.add_argument("--n", type=int, default=200, help="grasps wanted per demo / object")
    from sim.validate.config import PROTOCOLS, SQUEEZE_CONVENTIONS

    p.add_argument("--validate", choices=(*PROTOCOLS, "none"), default="lift-drop",
                   help="simulated validation of every grasp: lift-drop (dexaug's, real mass), "
                   "six-dir (dexaug's stricter pushes, real mass) or dgb (DexGraspBench's "
                   "protocol); default %(default)s")
    p.add_argument("--squeeze-convention", choices=SQUEEZE_CONVENTIONS, default=None,
                   help="dgb: how each grasp's pregrasp and squeeze are made (dexaug: contact "
                   "targets; bodex: squeeze = 2·grasp − pregrasp; dgb-rule: 0.9/1.1 × grasp); "
                   "default: configs/validate.toml [dgb] squeeze_convention")
    p.add_argument("--table", action=argparse.BooleanOptionalAction, default=None,
                   help="object on a table: keep the palm and fingertips above it; default: "
                   "the demo's table when it recorded one (none without a demo)")
    p.add_argument("--no-linkpen", action="store_true", help="skip the link penetration check")
    p.add_argument("--finger-iteration", action=argparse.BooleanOptionalAction, default=None,
                   help="drop the least important finger when a round yields too few grasps "
                   "(the paper's finger iteration); default: on without a demo, off with one "
                   "(the demo's fingers are kept)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=None, help="processes (default: all cores)")
    p.add_argument("--budget", type=float, default=120.0, metavar="SECONDS",
                   help="FSG time budget: the search stops there and reports the shortfall")


def augment_options(args: argparse.Namespace) -> AugmentOptions:
    """The ``AugmentOptions`` of parsed :func:`generation_args` (plus ``--gallery``)."""
    from dexaug.pipeline.options import AugmentOptions
    from sim.validate.batch import default_workers

    return AugmentOptions(n=args.n, validate=None if args.validate == "none" else args.validate,
                          link_penetration=not args.no_linkpen, table=args.table,
                          seed=args.seed, workers=args.workers or default_workers(),
                          time_budget_s=args.budget, gallery=args.gallery,
                          squeeze_convention=args.squeeze_convention,
                          finger_iteration=bool(args.finger_iteration))
