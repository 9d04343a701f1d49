"""Argument builders shared by several subcommands, so a flag means the same everywhere.

``--hand`` (default: ``configs/hands/default.toml``), the logging options of every command, the
grasp-generation options of ``generate``, ``augment``, ``batch`` and ``ui``, and the
``AugmentOptions`` those options stand for; with them, the one default number of grasps
(:data:`DEFAULT_GRASPS`) and what counts as a run that fell short (:data:`SHORT_SHARE`, exit
status :data:`SHORT_STATUS`), warned about before the search when ``--n`` cannot be reached
within ``--budget`` (:func:`warn_if_unreachable`).
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from dexaug.commands.argtypes import count, positive
from dexaug.pipeline.exit_status import SHORT_SHARE, SHORT_STATUS
from sim.errors import UsageError

if TYPE_CHECKING:
    from rich.console import Console

    from dexaug.pipeline.options import AugmentOptions

__all__ = ["DEFAULT_GRASPS", "FSG_MAX_GRASPS_PER_S", "SHORT_SHARE", "SHORT_STATUS",
           "augment_options", "backend_of", "budget_arg", "fell_short", "generation_args",
           "hand_arg", "logging_args", "warn_if_unreachable", "workers_arg"]

#: grasps asked for per demo / object when ``--n`` is not given, by every command that makes
#: grasps (generate, augment, batch, ui, demo, bridge --augment-n): the same number everywhere,
#: so a result made from the dashboard and one made on the command line are the same run
DEFAULT_GRASPS = 200


#: FSG's ceiling, grasps per second per worker process, for the warning before a search whose
#: ``--n`` no budget can meet: about 3x the fastest rate measured (5,000 grasps of 005 in 82 s on
#: 2 workers, 30 per second each: README, cost curves), so that only a request that is out of
#: reach on any machine is warned about
FSG_MAX_GRASPS_PER_S = 100.0

_LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")


def logging_args(p: argparse.ArgumentParser, *, top: bool = False) -> None:
    """``-v/--verbose``, ``-q/--quiet``, ``--log-level LEVEL`` (see :func:`dexaug.cli.log_level`).
    ``top``: the options of ``dexaug`` itself, with their defaults; on a subcommand they
    default to nothing (``argparse.SUPPRESS``), so that the same option given before the
    subcommand is not reset by the subcommand's default."""
    default = (lambda value: value) if top else (lambda value: argparse.SUPPRESS)
    p.add_argument("-v", "--verbose", action="store_true", default=default(False),
                   help="debug logging (and the traceback of an unforeseen error)")
    p.add_argument("-q", "--quiet", action="store_true", default=default(False),
                   help="dexaug's own log only from WARNING up")
    p.add_argument("--log-level", type=str.upper, choices=_LOG_LEVELS, default=default(None),
                   metavar="LEVEL", help="level of dexaug's own log: DEBUG, INFO, WARNING or "
                   "ERROR (wins over -v and -q); default INFO")


def hand_arg(p: argparse.ArgumentParser, help: str = "hand config name (configs/hands/<hand>/)") -> None:
    """``--hand NAME``, defaulting to the default hand (shown in the help)."""
    from sim.hand.config import default_hand_name

    p.add_argument("--hand", default=default_hand_name(), help=f"{help}; default %(default)s")


def generation_args(p: argparse.ArgumentParser) -> None:
    """Options shared by ``generate`` and ``augment``."""
    p.add_argument("--n", type=count, default=DEFAULT_GRASPS, help=n_help("grasps wanted per "
                   "demo / object"))
    from dexaug.pipeline.protocol_facts import DEFAULT_PROTOCOL
    from sim.validate.config import PROTOCOLS, SQUEEZE_CONVENTIONS

    p.add_argument("--validate", choices=(*PROTOCOLS, "none"), default=DEFAULT_PROTOCOL,
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
    from sim.validate.validator import BACKENDS

    p.add_argument("--backend", choices=BACKENDS, default=BACKENDS[0],
                   help="what steps lift-drop and six-dir: mujoco (MuJoCo's C engine, CPU "
                   "processes) or warp (MuJoCo Warp on a CUDA GPU, pip install mujoco-warp; "
                   "verdicts close to, not identical with, mujoco's); default %(default)s")
    p.add_argument("--seed", type=int, default=0, help="FSG seed (worker k uses seed + k)")
    workers_arg(p)
    budget_arg(p, 120.0)


def n_help(what: str) -> str:
    """The help of a ``--n`` that makes grasps: what it is, and the shortfall rule."""
    return (f"{what} (default %(default)s). A run that makes fewer than half of them (e.g. "
            f"stopped by --budget; none at all included) writes what it made and exits with "
            f"status {SHORT_STATUS}; a --n beyond FSG's ceiling of about "
            f"{FSG_MAX_GRASPS_PER_S:g} grasps per second per worker within --budget is warned "
            "about before the search")


def reachable_grasps(budget_s: float, workers: int) -> int:
    """The most grasps FSG could make in ``budget_s`` with ``workers`` processes
    (:data:`FSG_MAX_GRASPS_PER_S`)."""
    return math.floor(FSG_MAX_GRASPS_PER_S * max(workers, 1) * budget_s)


def warn_if_unreachable(console: Console, n: int, budget_s: float, workers: int) -> bool:
    """Warn, before the search, when ``n`` grasps cannot be made within ``budget_s`` on
    ``workers`` processes even at FSG's ceiling; returns whether it warned."""
    most = reachable_grasps(budget_s, workers)
    if n <= most:
        return False
    console.print(f"warning: --n {n} cannot be reached within --budget {budget_s:g} s: FSG makes "
                  f"at most about {FSG_MAX_GRASPS_PER_S:g} grasps per second per worker, "
                  f"{most} with {workers} worker(s); expect a shortfall (raise --budget or "
                  f"lower --n); a run with fewer than half of --n exits with status "
                  f"{SHORT_STATUS}", style="yellow", soft_wrap=True)
    return True


def fell_short(requested: int, made: int) -> bool:
    """Whether ``made`` of ``requested`` grasps is a shortfall of more than
    :data:`SHORT_SHARE` (exit status :data:`SHORT_STATUS`)."""
    return made < SHORT_SHARE * requested


def workers_arg(p: argparse.ArgumentParser) -> None:
    """``--workers N`` (>= 1), default all cores."""
    p.add_argument("--workers", type=count, default=None, help="processes (default: all cores)")


def budget_arg(p: argparse.ArgumentParser, default_s: float, per: str = "") -> None:
    """``--budget SECONDS``, with a help that says what it bounds: users read "budget" as the
    whole run, which it is not (``--budget 15`` on a 2-core machine: 16.5 s of FSG, then 30 s
    validating the 707 grasps found and 5 s of report, 55 s in all; since the workers share
    the caller's deadline, ``--budget 5`` gives 5.3 s of FSG)."""
    p.add_argument("--budget", type=positive, default=default_s, metavar="SECONDS",
                   help=f"wall-clock limit of the FSG grasp search{per} (default %(default)s s): "
                   "the search stops there with the grasps found so far and reports the "
                   "shortfall. It bounds that stage only (worker start-up included), which may "
                   "overrun it by its last batch, a fraction of a second; loading (hand, object, session, "
                   "workspace) comes before it, and the validation of every grasp found, which "
                   "grows with their number and can take longer than the search, and the report "
                   "come after it")


def augment_options(args: argparse.Namespace) -> AugmentOptions:
    """The ``AugmentOptions`` of parsed :func:`generation_args` (plus ``--gallery``)."""
    from dexaug.pipeline.options import AugmentOptions
    from sim.validate.batch import default_workers

    return AugmentOptions(n=args.n, validate=None if args.validate == "none" else args.validate,
                          link_penetration=not args.no_linkpen, table=args.table,
                          seed=args.seed, workers=args.workers or default_workers(),
                          time_budget_s=args.budget, gallery=args.gallery,
                          squeeze_convention=args.squeeze_convention,
                          finger_iteration=bool(args.finger_iteration), backend=backend_of(args))


def backend_of(args: argparse.Namespace) -> str:
    """``--backend``, refused with a protocol it cannot step (only the protocols that run as one
    program, lift-drop and six-dir, :func:`~dexaug.pipeline.protocol_facts.batch_protocols`,
    are stepped by a batch backend; dgb steps grasp by grasp on the C engine), and checked
    here before any work when it runs in this process (not on a Ray cluster, whose nodes may
    have the GPU this machine lacks): no FSG run ends in a missing package."""
    from dexaug.pipeline.protocol_facts import batch_protocols, spoken

    if args.backend != "mujoco" and args.validate not in batch_protocols():
        raise UsageError(f"--backend {args.backend} runs {spoken(batch_protocols())}; --validate "
                         f"{args.validate} runs on --backend mujoco")
    if args.backend == "warp" and getattr(args, "ray", None) is None:
        from sim.validate.warp_runner import import_warp

        import_warp("cuda")
    return args.backend
