"""Subcommand ``export``: a grasp dataset in a layout other tools read, or recorded teleop
sessions as a LeRobot dataset.

The work is :mod:`augment.export`; this module picks the tables, the hand, the masses and the
object frames (or reads the sessions, :mod:`teleop.record.session_steps`), and prints what was
written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.text import Text

from augment.export import FORMATS
from dexaug.commands.argtypes import int_at_least
from dexaug.commands.guards import dataset_file, did_you_mean, require_writable
from dexaug.commands.registry import command
from sim.errors import DexaugError, UsageError

__all__ = ["export"]

#: where the FSG authors' demonstrations are, in their object frames and in ours
FSG_KEYFRAMES = ("handdata", "fsg_keyframes")


def _source(text: str) -> Path:
    """A grasp dataset (:func:`dataset_file`) or a recorded session (an existing ``.mcap``
    file; its content is checked when it is read)."""
    path = Path(text)
    if path.suffix != ".mcap":
        return dataset_file(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{path}: no such session file (a recorded .mcap)")
    return path


def camera_size(text: str) -> tuple[int, int]:
    """``HxW`` (pixels, e.g. ``64x64``) as (height, width)."""
    h, sep, w = text.lower().partition("x")
    if not sep or not h.isdigit() or not w.isdigit() or int(h) < 1 or int(w) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected HEIGHTxWIDTH in pixels, e.g. 64x64")
    return int(h), int(w)


def _export_args(p: argparse.ArgumentParser) -> None:
    from augment.export.lerobot_sessions import SESSION_FPS
    from sim.validate.config import SQUEEZE_CONVENTIONS

    p.add_argument("dataset", type=_source, nargs="+", metavar="DATASET|SESSION.mcap",
                   help="a grasps.h5 written by augment/generate; or, for --format lerobot "
                        "only, one or more sessions recorded through the bridge (.mcap, as "
                        "in recordings/), each an episode of the person's demonstration")
    p.add_argument("--format", choices=(*FORMATS, "lerobot"), required=True,
                   help="dexgraspbench: one JSON line per grasp in the DexGraspBench reference "
                        "layout (palm body pose in the world, joints by name, pregrasp/squeeze); "
                        "npz: every column of every table, for numpy.load; fsg: the FSG authors' "
                        "HDF5 (rh_palm pose in the object frame, their 22 joints, gws (N,1), "
                        "float32); bodex: a folder of DexGraspBench per-grasp .npy files "
                        "(pregrasp/grasp/squeeze qpos of its floating Shadow Hand, object pose), "
                        "with the usual permissions (0777 less the umask); lerobot: every "
                        "grasp rolled out by lift-drop, the successful rollouts as episodes of "
                        "a LeRobot dataset (format v3.0, a folder; failed ones listed in its "
                        "failed_rollouts.json; needs the extra dexaug[lerobot]); of sessions, "
                        "one episode each, resampled to --fps")
    p.add_argument("--out", type=Path, required=True,
                   help="file to write (replaced atomically); for bodex and lerobot a folder "
                        "(replaced whole, only if it is empty or an earlier export of that "
                        "format)")
    p.add_argument("--camera", type=camera_size, default=None, metavar="HxW",
                   help="lerobot, grasp datasets: also render every frame of each rollout "
                        "(the overview camera, HEIGHTxWIDTH pixels, e.g. 64x64) into the "
                        "feature observation.images.overview (PNG in the parquet); offscreen "
                        "rendering costs milliseconds to tenths of a second a frame")
    p.add_argument("--fps", type=int_at_least(1), default=None,
                   help="lerobot, sessions: frames a second of each episode (LeRobot's fps is "
                        "a whole number; the bridge steps at 83.33 Hz): frame k holds the "
                        "latest recorded step at or before k/FPS s, no interpolation; at most "
                        f"the session's step rate; default {SESSION_FPS}")
    p.add_argument("--object", help="only this object's table (default: every object)")
    p.add_argument("--rejected", action="store_true",
                   help="also the grasps that failed validation (their verdict says so); "
                        "default: only the main table")
    p.add_argument("--object-pose", type=float, nargs=7, default=None,
                   metavar=("X", "Y", "Z", "QW", "QX", "QY", "QZ"),
                   help="dexgraspbench, bodex: the object frame in the world (metres, wxyz); "
                        "default: dexgraspbench the reference file's (0 0 0.3 1 0 0 0), bodex "
                        "DexGraspBench's examples' (the identity)")
    p.add_argument("--object-frame", choices=("dexaug", "fsg-mesh"), default="dexaug",
                   help="fsg: the object frame of the poses: dexaug's (the mesh origin of our "
                        "objects) or fsg-mesh, the FSG authors' re-centred meshes (known for "
                        "the objects of their demonstrations, ../shared/assets/handdata/"
                        "fsg_keyframes: derived from their srh.txt and our frames of the same "
                        "scenes); default %(default)s")
    p.add_argument("--object-transform", type=float, nargs=7, default=None,
                   metavar=("X", "Y", "Z", "QW", "QX", "QY", "QZ"),
                   help="fsg, one object: our object's frame in the target object frame "
                        "(metres, wxyz; as `demo import` takes it)")
    p.add_argument("--squeeze-convention", choices=SQUEEZE_CONVENTIONS, default=None,
                   help="bodex: how the pregrasp and squeeze of grasps the dataset has none "
                        "for are made (as the validator makes them); default: "
                        "configs/validate.toml [dgb] squeeze_convention")
    p.add_argument("--object-root", default="assets/object",
                   help="bodex: each file's obj_path is OBJECT_ROOT/<object>, where "
                        "DexGraspBench finds the processed object; default %(default)s")


def _tables(path: Path, name: str | None, rejected: bool) -> dict:
    from augment.dataset import load, with_rejected

    tables = dict(load(path))
    if name is not None:
        if name not in tables:
            raise DexaugError(f"{path}: no object {name!r} (has {sorted(tables)})"
                              f"{did_you_mean(name, tables)}")
        tables = {name: tables[name]}
    return {k: with_rejected(t) for k, t in tables.items()} if rejected else tables


def _hand(path: Path, tables: dict):
    from sim.hand.model import Hand

    hands = {str(t.attrs.get("hand", "")) for t in tables.values()}
    if len(hands) != 1 or not next(iter(hands)):
        raise DexaugError(f"{path}: the tables name no single hand (attrs: {hands})")
    return Hand.load(hands.pop())


def _mass_kg(name: str) -> float | None:
    from sim.world.objects import load_object

    try:
        return load_object(name).mass_kg
    except DexaugError:   # not installed here: the row says null
        return None


def fsg_mesh_transforms(names: list[str]) -> dict[str, list[float]]:
    """Our object frame in the FSG authors' re-centred mesh frame, for each object of ``names``:
    their ``srh.txt`` places their object and our ``keyframes_shared_frames.json`` places ours
    in the same scene, so T = T_world←theirs⁻¹ · T_world←ours."""
    from dexaug.pipeline.keyframe_files import read_keyframes
    from sim.paths import SHARED_ASSETS
    from sim.transforms import pose_inv, pose_mul

    folder = SHARED_ASSETS.joinpath(*FSG_KEYFRAMES)
    ours = {k.object: k for k in read_keyframes(folder / "keyframes_shared_frames.json")}
    theirs = {k.object: k for k in read_keyframes(folder / "srh.txt")}
    out = {}
    for name in names:
        if name not in ours or name not in theirs:
            raise UsageError(f"--object-frame fsg-mesh: no transform known for {name} ({folder} "
                             f"has {', '.join(sorted(set(ours) & set(theirs)))}); give "
                             "--object-transform with --object")
        a, b = theirs[name], ours[name]
        p, q = pose_mul(*pose_inv(a.object_pos_m, a.object_quat_wxyz), b.object_pos_m,
                        b.object_quat_wxyz)
        out[name] = [*map(float, p), *map(float, q)]
    return out


def _refuse_options(args: argparse.Namespace, sessions: bool) -> None:
    """Options that mean nothing for the chosen format (or for sessions, which have no
    tables, render nothing and alone take a frame rate) are refused rather than ignored."""
    allowed = {"dexgraspbench": {"object_pose", "object", "rejected"},
               "npz": {"object", "rejected"},
               "fsg": {"object_frame", "object_transform", "object", "rejected"},
               "bodex": {"object_pose", "squeeze_convention", "object_root", "object",
                         "rejected"},
               "lerobot": {"camera", "object", "rejected"}}[args.format]
    if sessions:
        allowed = {"fps"}
    given = {"fps": args.fps is not None, "camera": args.camera is not None,
             "object": args.object is not None, "rejected": args.rejected,
             "object_pose": args.object_pose is not None,
             "object_frame": args.object_frame != "dexaug",
             "object_transform": args.object_transform is not None,
             "squeeze_convention": args.squeeze_convention is not None,
             "object_root": args.object_root != "assets/object"}
    bad = [k for k, v in given.items() if v and k not in allowed]
    if bad:
        what = "sessions" if sessions else f"--format {args.format}"
        raise UsageError(f"--{bad[0].replace('_', '-')} does not apply to {what}")


@command("export", _export_args)
def export(args: argparse.Namespace, console: Console) -> int:
    """Export a grasp dataset: DexGraspBench's reference JSONL, a flat .npz, the FSG authors'
    HDF5, DexGraspBench/BODex per-grasp files, or its grasps rolled out as a LeRobot dataset;
    or recorded teleop sessions as a LeRobot dataset.

    The dexgraspbench layout is the one of ../shared/reference/dexgraspbench/grasps.jsonl: the
    hand's palm body pose and the object pose in the world, q_grasp / q_pregrasp / q_squeeze by
    joint name, plus dexaug's verdict; reading the shared reference file and writing it back
    gives its poses and angles to 1e-9 (tests/test_export.py). fsg and bodex convert our
    frame_palm and 24 joints to their rh_palm-based poses and 22 joints (augment.export.fsg,
    augment.export.bodex; tests/test_export_fsg.py, tests/test_export_bodex.py). lerobot
    rolls every grasp out by lift-drop and writes the successful episodes in LeRobot's
    format v3.0 (augment.export.lerobot, docs/learning.md; tests/test_export_lerobot.py),
    with ``--camera HxW`` an image of every frame too; recorded sessions (``.mcap``) go to
    lerobot only, one episode each, resampled to ``--fps`` by sample and hold
    (augment.export.lerobot_sessions; tests/test_export_lerobot_sessions.py).
    """
    from augment import export as ex

    sessions = _sessions(args)
    _refuse_options(args, bool(sessions))
    require_writable(args.out, "--out", folder=args.format in ("bodex", "lerobot"))
    if sessions:
        return _export_sessions(args.out, sessions, args.fps, console)
    args.dataset = args.dataset[0]
    tables = _tables(args.dataset, args.object, args.rejected)
    source = str(args.dataset)
    note = ""
    if args.format == "lerobot":
        return _export_lerobot(args, console, tables)
    if args.format == "npz":
        n = ex.write_npz(args.out, tables)
    elif args.format == "dexgraspbench":
        masses = {k: m for k in tables if (m := _mass_kg(k)) is not None}
        n = ex.write_dexgraspbench(args.out, tables, _hand(args.dataset, tables),
                                   object_pose_world=args.object_pose or ex.REFERENCE_OBJECT_POSE,
                                   masses_kg=masses, source=source)
    elif args.format == "fsg":
        if args.object_transform is not None and (len(tables) != 1 or
                                                  args.object_frame != "dexaug"):
            raise UsageError("--object-transform: one object only (--object), and not with "
                             "--object-frame fsg-mesh")
        transforms = ({next(iter(tables)): args.object_transform}
                      if args.object_transform is not None
                      else fsg_mesh_transforms(list(tables))
                      if args.object_frame == "fsg-mesh" else None)
        fsg = ex.write_fsg(args.out, tables, _hand(args.dataset, tables),
                           object_transforms=transforms, source=source)
        n = fsg.grasps
        note = _dropped_note(fsg.dropped_moved)
    else:
        done = ex.write_bodex(args.out, tables, _hand(args.dataset, tables),
                              object_pose_world=args.object_pose or ex.IDENTITY_POSE,
                              object_root=args.object_root,
                              squeeze_convention=args.squeeze_convention, source=source)
        n = done.grasps
        note = "; stages: " + ", ".join(f"{k} {v}" for k, v in sorted(done.stages.items()))
        note += _dropped_note(done.dropped_moved)
    console.print(Text(f"wrote {n} grasps of {len(tables)} object(s) to {args.out} "
                       f"({args.format}){note}"))
    return 0


def _sessions(args: argparse.Namespace) -> list[Path]:
    """The sessions given (``.mcap``), or [] for one grasp dataset; a mix, several datasets,
    or sessions to a format other than lerobot are refused."""
    sessions = [p for p in args.dataset if p.suffix == ".mcap"]
    if sessions and len(sessions) != len(args.dataset):
        raise UsageError("give either sessions (.mcap) or one grasp dataset, not both")
    if sessions and args.format != "lerobot":
        raise UsageError(f"sessions (.mcap) export only as --format lerobot, not {args.format}")
    if not sessions and len(args.dataset) != 1:
        raise UsageError(f"one grasp dataset at a time (got {len(args.dataset)})")
    return sessions


def _export_sessions(out: Path, sessions: list[Path], fps: int | None,
                     console: Console) -> int:
    """Each session an episode of a LeRobot dataset at ``fps`` (None: the default,
    augment.export.lerobot_sessions); print the count and the speed."""
    import time

    from augment.export.lerobot import pyarrow_modules, write_lerobot
    from augment.export.lerobot_sessions import SESSION_FPS, session_episode
    from teleop.record.session_steps import read_session_steps

    pyarrow_modules()
    fps = SESSION_FPS if fps is None else fps
    start = time.perf_counter()
    episodes = (session_episode(read_session_steps(p), fps) for p in sessions)
    done = write_lerobot(out, episodes, source=", ".join(map(str, sessions)))
    wall_s = time.perf_counter() - start
    console.print(Text(f"wrote {done.episodes} session episode(s) ({done.frames} frames at "
                       f"{fps} fps) to {out} (lerobot v3.0) in {wall_s:.2f} s: "
                       f"{done.episodes / wall_s:.1f} episodes/s, {done.frames / wall_s:.0f} "
                       "frames/s"))
    return 0


def _dropped_note(moved: int) -> str:
    return ("" if not moved else f"; {moved} grasps had the wrist off 0: its angles are dropped "
            "(their hand has no wrist; rh_palm and the fingers are exact)")


def _export_lerobot(args: argparse.Namespace, console: Console, tables: dict) -> int:
    """Roll every grasp out (a rich progress bar over the rollouts) and write the successful
    ones as a LeRobot dataset (augment.export.lerobot); print the count and episodes/s."""
    import time

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

    from augment.export.lerobot import FAILED_FILE, pyarrow_modules, write_lerobot
    from augment.export.lerobot_rollouts import count_grasps, rollouts

    pyarrow_modules()   # the missing extra is said before any rollout, not after
    hand = _hand(args.dataset, tables)
    if args.camera is not None:
        from sim.world.render import select_gl_backend

        select_gl_backend()
    start = time.perf_counter()
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeRemainingColumn(), console=console,
                  transient=True) as bar:
        task = bar.add_task("rolling out grasps", total=count_grasps(tables))
        done = write_lerobot(args.out, rollouts(tables, hand, camera=args.camera),
                             source=str(args.dataset),
                             progress=lambda n: bar.update(task, completed=n))
    wall_s = time.perf_counter() - start
    rate = (done.episodes + done.failed) / wall_s if wall_s > 0 else float("inf")
    console.print(Text(f"wrote {done.episodes} episodes ({done.frames} frames) of "
                       f"{len(tables)} object(s) to {args.out} (lerobot v3.0); "
                       f"{done.failed} failed rollouts listed in {args.out / FAILED_FILE}; "
                       f"{done.episodes + done.failed} rollouts in {wall_s:.1f} s: "
                       f"{rate:.2f} episodes/s"))
    return 0
