"""Subcommand ``demo``: the main job on its embedded default (what ``make demo`` runs), and the
actions on demos (``dexaug demo ACTION``).

The main job: one chain from a teleop recording to a dataset (a synthetic operator's session
recorded through the bridge, its demo extracted and augmented:
:mod:`dexaug.pipeline.demo_chain`), or the augmentation of a given session, or of a scripted
procedural demonstration when the YCB objects are missing. Actions register with
:func:`action` (argument setup + handler, as subcommands do with ``registry.command``), so
adding one is one decorated function.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

from rich.console import Console

from dexaug.commands.argtypes import count
from dexaug.commands.guards import object_name, require_writable
from dexaug.commands.options import DEFAULT_GRASPS, hand_arg, logging_args, n_help, workers_arg
from dexaug.commands.registry import Handler, Setup, command

#: ``dexaug demo ACTION``: action name → (argument setup, handler), in registration order
ACTIONS: dict[str, tuple[Setup, Handler]] = {}


def action(name: str, setup: Setup) -> Callable[[Handler], Handler]:
    """Register an action of ``dexaug demo``: ``setup`` adds its arguments, the decorated
    function runs it (``dexaug demo`` without an action runs the main job)."""

    def register(fn: Handler) -> Handler:
        ACTIONS[name] = (setup, fn)
        return fn

    return register


def _demo_args(p: argparse.ArgumentParser) -> None:
    from dexaug.pipeline.demo_chain import DEMO_OBJECT, DEMO_SEED, recording_name

    p.add_argument("--session", type=Path, default=None,
                   help="a recorded session to augment instead (every demo in it); default: "
                   f"none, the chain records its own: a synthetic operator's session of "
                   f"{DEMO_OBJECT} (seed {DEMO_SEED}) through the bridge into "
                   f"OUT/{recording_name()}, whose demo is augmented")
    p.add_argument("--out", type=Path, default=Path("datasets"),
                   help="output folder; default %(default)s. A result of an earlier run there is "
                   "kept: this run then writes to the next free DIR-2, DIR-3, … and says so")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the earlier run's result in --out instead")
    p.add_argument("--n", type=count, default=DEFAULT_GRASPS, help=n_help("grasps to generate"))
    actions = p.add_subparsers(dest="action", metavar="ACTION", title="actions (none: the main job)")
    for name, (setup, fn) in ACTIONS.items():
        doc = (fn.__doc__ or "").strip()
        sub = actions.add_parser(name, help=doc.splitlines()[0] if doc else None, description=doc,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
        logging_args(sub)
        setup(sub)
        sub.set_defaults(handler=fn)


@command("demo", _demo_args)
def demo(args: argparse.Namespace, console: Console) -> int:
    """Run the main job on its embedded default (what `make demo` runs): teleop recording → dataset.

    1. session: a synthetic operator's hand-tracking session of the Phillips screwdriver (seed
       0, no headset: `dexaug synth`), written to OUT/synth_<object>.mcap.
    2. recording: that session through the real bridge (zenoh, mink retargeting, MuJoCo, the
       object in demo mode) into OUT/demo_<object>.mcap, as a headset's would be recorded.
    3. demo: the grasp demo extracted from that recording (fingers, and how it was found).
    4. augmentation of that demo: AutoWS → FSG → lift-drop validation of every grasp → HDF5
       dataset and HTML report in OUT/<demo id>/, whose paths are printed.
    Each stage prints one line. With --session, that session's demos are augmented instead
    (stages 3-4). Without the YCB objects, a scripted demonstration on a procedural cylinder
    is recorded and augmented instead.

    A second run never replaces the first's result silently: it writes to the next free
    sibling of --out (datasets-2, …) and prints which, unless --overwrite. Exit status 3: the
    augmentation made fewer than half of --n grasps.

    Actions on demos: `dexaug demo ACTION --help` (import: a static grasp pose file → demo).
    """
    from dexaug.commands.options import SHORT_STATUS, fell_short
    from dexaug.commands.running import progress_bars, stage_ticker
    from dexaug.pipeline.demo_chain import DEMO_OBJECT, record_demo, recording_name
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_demo, augment_session
    from sim.errors import DexaugError
    from sim.hand.config import default_hand_name
    from sim.world.objects import load_object
    from teleop.record.session import open_session

    require_writable(args.out, "--out", folder=True)
    session = args.session
    try:   # the chain's object and a given session's are YCB objects: are they installed here?
        load_object(open_session(session).metadata.get("object", "") if session is not None
                    else DEMO_OBJECT)
        procedural = None
    except DexaugError as exc:
        procedural = exc
    own = PROCEDURAL_SESSION if procedural is not None else recording_name()
    marks = (_session_marks(session) if procedural is None and session is not None
             else lambda root: [root / own])
    out = _result_root(args.out, marks, args.overwrite, console)
    out.mkdir(parents=True, exist_ok=True)
    opts = AugmentOptions(n=args.n, time_budget_s=90.0, gallery=4)

    def say(line: str) -> None:
        console.print(line, highlight=False, soft_wrap=True)

    if procedural is None and session is None:
        made = record_demo(out, default_hand_name(), say=say)
        start = time.perf_counter()
        with progress_bars(console) as bar:
            summaries = [augment_demo(made.demo, out, opts, progress=stage_ticker(bar),
                                      force=True)]
    else:
        if procedural is not None:
            console.print(f"{procedural}\n→ recording a scripted demonstration on a procedural "
                          "cylinder instead", style="yellow", highlight=False)
            session = _procedural_demo_session(out / PROCEDURAL_SESSION)
        say(f"augmenting {session}")
        start = time.perf_counter()
        with progress_bars(console) as bar:
            summaries = augment_session(session, out, opts, progress=stage_ticker(bar),
                                        force=True)
    for s in summaries:
        say(f"4. augmented: {s.demo_id} — {s.passed} grasps kept of {s.generated} generated "
            f"(lift-drop, --n {s.requested}) in {time.perf_counter() - start:.1f} s")
        say(f"dataset: {s.dataset}")
        say(f"report:  {s.report}")
    return SHORT_STATUS if any(fell_short(s.requested, s.generated) for s in summaries) else 0


#: the scripted demonstration's session, in the output folder (no YCB objects installed)
PROCEDURAL_SESSION = "demo_cylinder.mcap"


def _session_marks(session: Path) -> Callable[[Path], list[Path]]:
    """The result folders of ``session``'s demos in an output root."""
    from dexaug.pipeline.options import demo_dir
    from teleop.record import demos as extraction

    demos = extraction.extract_demos(session)
    return lambda root: [demo_dir(root, d) for d in demos]


def _result_root(out: Path, marks: Callable[[Path], list[Path]], overwrite: bool,
                 console: Console) -> Path:
    """Where this run writes: ``out``, unless an earlier run's result is there (one of
    ``marks(out)``: the chain's recording, a given session's result folders, the procedural
    session) and ``overwrite`` is off: then the first of ``out-2``, ``out-3``, … that holds
    none, said in one line."""

    def taken(root: Path) -> Path | None:
        return next((m for m in marks(root) if m.exists()), None)

    earlier = taken(out)
    if earlier is None or overwrite:
        if earlier is not None:
            console.print(f"--overwrite: replacing the earlier result {earlier}",
                          highlight=False, soft_wrap=True)
        return out
    k = 2
    while taken(new := out.with_name(f"{out.name}-{k}")) is not None:
        k += 1
    require_writable(new, "--out", folder=True)
    console.print(f"{earlier} holds an earlier run's result, kept: this run writes to {new}/ "
                  "(--overwrite replaces the earlier one)", style="yellow", highlight=False,
                  soft_wrap=True)
    return new


def _procedural_demo_session(out: Path) -> Path:
    """A scripted demonstration on the procedural cylinder: the first FSG grasp (manual
    workspace, table mode) that passes lift-drop, performed and recorded."""
    from dexaug.pipeline.scripted_demos import demonstrable_grasps
    from sim.errors import DexaugError
    from sim.hand.config import default_hand_name
    from sim.hand.model import Hand
    from teleop.synthetic.scripted import record_scripted_demo

    hand = Hand.load(default_hand_name())
    passing = demonstrable_grasps(hand, "cylinder", 30)
    if not passing:
        raise DexaugError("no FSG grasp of the procedural cylinder passed lift-drop")
    return record_scripted_demo(hand, "cylinder", passing[0], out, overwrite=True)


def _import_args(p: argparse.ArgumentParser) -> None:
    from dexaug.pipeline.demo_import import DEFAULT_TOLERANCE_M, IMPORTED_DEMOS_DIR
    from sim.paths import REPO_ROOT

    p.add_argument("file", type=Path, metavar="FILE", help="keyframe file: dexaug keyframe JSON "
                   "(.json) or the FSG authors' srh.txt format (any other suffix)")
    p.add_argument("--out", type=Path, default=IMPORTED_DEMOS_DIR,
                   help="a DEMO.json file (one demo) or a folder (<object>.json per demo); "
                   f"default {IMPORTED_DEMOS_DIR.relative_to(REPO_ROOT)}/, which `dexaug bench "
                   "paper` prefers to the scripted demos")
    p.add_argument("--object", default=None, metavar="NAME",
                   help="import only this object's keyframe; default: every keyframe in FILE")
    p.add_argument("--object-transform", type=float, nargs=7, default=None,
                   metavar=("X", "Y", "Z", "QW", "QX", "QY", "QZ"),
                   help="pose of our object's frame in the file's object frame (metres, "
                   "quaternion w x y z); required for srh.txt, whose objects are the authors' "
                   "re-centred meshes (one object at a time: with --object); default: identity")
    p.add_argument("--hand", default=None, help="hand config (configs/hands/<hand>/); default: "
                   "the one whose palm body and finger joints the file names (srh.txt, which "
                   "names none: the hand whose folder declares [formats.srh_txt])")
    p.add_argument("--tolerance-mm", type=float, default=DEFAULT_TOLERANCE_M * 1e3,
                   help="a fingertip whose signed distance to the object is at most this "
                   "touches it; default %(default)g mm")
    p.add_argument("--note", default="", help="free text kept in the demo's provenance (e.g. "
                   "the source's authors and licence); default none")
    p.add_argument("--force", action="store_true", help="replace existing demo files")


@action("import", _import_args)
def demo_import(args: argparse.Namespace, console: Console) -> int:
    """Turn a static grasp pose (object pose, palm body pose, joints) into a demo.

    The hand and object are placed in MuJoCo as the validator places a grasp; every fingertip's
    signed distance to the object is measured (negative = penetration) and printed, and the
    fingers within --tolerance-mm are the demo's fingers, with their contact points. A pose with
    no fingertip within the tolerance, an object that is not installed or a malformed file is
    refused with one line, and nothing is written. The demo JSON also records its provenance
    (file, entry, transform, tolerance, per-finger distances, --note) and the table top, when
    the file gives one, as a plane in the object frame.
    """
    from dexaug.pipeline.demo_import import describe, import_demos, write_imported

    imported = import_demos(args.file, hand=args.hand, object_name=args.object,
                            object_transform=args.object_transform,
                            tolerance_m=args.tolerance_mm * 1e-3, note=args.note)
    for item in imported:
        console.print(describe(item), highlight=False)
    for path in write_imported(imported, args.out, force=args.force):
        console.print(f"wrote {path}", highlight=False)
    return 0


def _script_args(p: argparse.ArgumentParser) -> None:
    hand_arg(p)
    p.add_argument("--object", required=True, type=object_name,
                   help="object to demonstrate (YCB id or primitive)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="folder for demo_<object>.mcap and demos/<object>.json")
    p.add_argument("--candidates", type=count, default=60,
                   help="FSG grasps proposed on the table; default %(default)s")
    p.add_argument("--tries", type=count, default=8,
                   help="passing proposals performed and recorded; default %(default)s")
    p.add_argument("--trial", type=count, default=20,
                   help="grasps of each candidate's trial augmentation; default %(default)s")
    workers_arg(p)


@action("script", _script_args)
def demo_script(args: argparse.Namespace, console: Console) -> int:
    """Record a scripted demonstration of an object, with no headset and no person.

    FSG proposes grasps of the object resting on the table (manual workspace), lift-drop keeps
    those that hold, up to --tries of them are performed by the scripted demonstrator in the
    bridge's scene and recorded; the recording whose demo augments best in a small trial
    (--trial grasps) is kept as DIR/demo_<object>.mcap with its demo DIR/demos/<object>.json.
    """
    from dexaug.pipeline.scripted_demos import script_demo
    from sim.hand.model import Hand
    from sim.validate.batch import default_workers

    require_writable(args.out, "--out", folder=True)
    made = script_demo(Hand.load(args.hand), args.object, args.out, candidates=args.candidates,
                       tries=args.tries, trial=args.trial,
                       workers=args.workers or default_workers())
    d = made.demo
    console.print(f"demo {d.id}: fingers {', '.join(d.fingers)}, held {d.duration_s:.2f} s, "
                  f"trial augmentation passes {100 * made.trial_pass_rate:.0f} %", highlight=False)
    console.print(f"wrote {made.session}\nwrote {made.demo_file}", highlight=False)
    return 0
