"""Subcommands of the teleoperation half: ``retarget``, ``synth``, ``import-trajectory``,
``bridge`` (``replay``: :mod:`dexaug.commands.replay`).

Each parses its arguments, calls ``teleop``, and reports; the bridge can hand every finished
recording to ``dexaug augment`` in a background process.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console
from rich.progress import Progress
from rich.table import Table
from rich.text import Text

from dexaug.commands.argtypes import count, free_port, int_at_least, port, positive, rig_name
from dexaug.commands.guards import object_name, require_writable
from dexaug.commands.network import require_free_port, zenoh_message
from dexaug.commands.options import DEFAULT_GRASPS, hand_arg
from dexaug.commands.registry import command
from sim.errors import NetworkError, UsageError

#: ``bridge --foxglove``'s defaults (teleop.bridge.foxglove_live's, not imported at start-up:
#: the SDK loads only when the server is asked for): Foxglove's conventional port, which the
#: dashboard (``dexaug ui``, :data:`dexaug.commands.ui.DASHBOARD_PORT`) leaves free
FOXGLOVE_HOST, FOXGLOVE_PORT = "127.0.0.1", 8765

if TYPE_CHECKING:

    from dexaug.pipeline.augment_queue import AugmentQueue


def _retarget_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="an MCAP session recorded by dexaug, or an IWER "
                   "capture module (.js) recorded in a WebXR page")
    hand_arg(p)
    p.add_argument("--out", type=Path, help="save the retargeted trajectory (.npz)")


@command("retarget", _retarget_args)
def retarget(args: argparse.Namespace, console: Console) -> int:
    """Retarget a recorded hand-tracking stream offline and report fingertip errors.

    Runs the same mink retargeter as the bridge over every frame (operator scale calibrated
    from the recording) and prints per-finger fingertip error (median, p95, max) and the
    per-frame solve time.
    """
    from sim.hand.model import Hand
    from sim.io import atomic_path
    from teleop.retarget.retargeter import Retargeter
    from teleop.retarget.trace import retarget_frames, summarise_errors

    if args.out:
        require_writable(args.out, "--out")
    if args.file.suffix == ".js":
        from teleop.input.iwer import iwer_hand_frames, load_iwer_capture

        frames = iwer_hand_frames(load_iwer_capture(args.file))
    else:
        from teleop.record.session import open_session

        frames = [frame for _, frame in open_session(args.file).hands()]
    hand = Hand.load(args.hand)
    retargeter = Retargeter(hand)  # which operator hand it follows: configs/teleop.toml
    retargeter.calibrate_scale(frames)
    with Progress(console=console, transient=True) as progress:
        progress.add_task(f"retargeting {len(frames)} frames", total=None)
        trace = retarget_frames(retargeter, frames)
    summary = summarise_errors(trace)
    table = Table(title=f"retargeting {args.file.name} → {hand.name} (scale "
                  f"{retargeter.scale:.3f})")
    for col in ("finger", "median (mm)", "p95 (mm)", "max (mm)"):
        table.add_column(col, justify="right")
    for finger, stats in summary["fingers"].items():
        table.add_row(finger, *(f"{stats[k] * 1e3:.1f}" for k in ("median_m", "p95_m", "max_m")))
    console.print(table)
    console.print(f"{summary['frames']} frames, {summary['held']} held (no usable hand); solve "
                  f"{summary['step_median_s'] * 1e3:.2f} ms median, "
                  f"{summary['step_p99_s'] * 1e3:.2f} ms p99")
    if args.out:
        with atomic_path(args.out) as tmp, tmp.open("wb") as f:
            np.savez(f, **trace.as_dict())  # type: ignore[arg-type]  # numpy stubs type **kwds as allow_pickle's bool
        console.print(f"wrote {args.out}")
    return 0


def _synth_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--object", default="005_tomato_soup_can", type=object_name,
                   help="object to grasp (YCB id or primitive)")
    hand_arg(p, "robot hand config the episode targets")
    p.add_argument("--grasp", help="reference grasp to imitate (default: the hand's reference "
                   "grasp of the object, else a generic side grasp)")
    p.add_argument("--seed", type=int, default=0, help="noise/dropout seed (deterministic)")
    p.add_argument("--out", type=Path, required=True, help="MCAP session file to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing file")


@command("synth", _synth_args)
def synth(args: argparse.Namespace, console: Console) -> int:
    """Generate a synthetic operator's hand-tracking session (approach → grasp → lift → release).

    A human-proportioned OpenXR hand, with tracking noise, timestamp jitter and dropouts, whose
    retargeted robot hand lands on a reference grasp of the object. Writes /hands and a
    grasp_mark event to an MCAP session that replays like a real recording.
    """
    from teleop.synthetic.synthesize import synthesize
    from teleop.synthetic.writer import write_session

    require_writable(args.out, "--out")
    episode = synthesize(args.object, hand=args.hand, seed=args.seed, grasp_name=args.grasp)
    path = write_session(episode, args.out, overwrite=args.overwrite)
    tracked = int(episode.tracked.sum())
    console.print(f"wrote {path}: {len(episode.frames)} frames over "
                  f"{episode.frames[-1].device_time_s - episode.frames[0].device_time_s:.1f} s "
                  f"({tracked} with a tracked hand), grasp mark at {episode.grasp_time_s:.2f} s, "
                  f"imitating {episode.reference_grasp or 'a generic side grasp'}", soft_wrap=True)
    return 0


def _import_trajectory_args(p: argparse.ArgumentParser) -> None:
    from teleop.input.keypoints import FORMATS, SPACES, Anchor

    default = Anchor()
    p.add_argument("file", type=Path, help="keypoint trajectory, metres: .pkl (a list of (J,3) "
                   "arrays), .npy ((T,J,3)) or .npz (keypoints (T,J,3); optional object_pos_m "
                   "(T,3) and object_quat_wxyz (T,4) in the same space)")
    p.add_argument("--format", choices=FORMATS, default="mediapipe", help="mediapipe: 21 "
                   "MediaPipe/MANO keypoints (wrist, thumb CMC..tip, index..little MCP..tip); "
                   "openxr: 26 OpenXR joints (PALM first) or 25 WebXR joints; default %(default)s")
    p.add_argument("--side", choices=("left", "right"), required=True,
                   help="which hand the trajectory is (never guessed: MediaPipe's handedness "
                   "label is mirrored on selfie images); must match --hand's operator side")
    p.add_argument("--fps", type=positive, default=30.0, help="frames per second of the trajectory "
                   "(timestamps are frame / fps); default %(default)s")
    p.add_argument("--space", choices=SPACES, help="hand: only the hand's shape counts (MediaPipe "
                   "world landmarks, global motion removed), placed at --wrist-pos/--wrist-rpy-deg; "
                   "xr: an OpenXR reference space (+Y up, -Z forward); world: the operator's "
                   "tracking space in MuJoCo axes (+Z up); default hand for mediapipe, xr for openxr")
    hand_arg(p, "robot hand the session is for")
    p.add_argument("--object", type=object_name, help="object on the table (YCB id or "
                   "primitive): required with object poses in the file, and `dexaug rerecord` "
                   "needs one (here or there)")
    p.add_argument("--wrist-pos", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   default=default.wrist_pos_m.tolist(), help="--space hand: the mean wrist "
                   "position in the tracking space, metres (the table top is at z 0.8); default "
                   "%(default)s")
    p.add_argument("--wrist-rpy-deg", type=float, nargs=3, metavar=("R", "P", "Y"),
                   default=[0.0, 0.0, 0.0], help="--space hand: the mean wrist orientation "
                   "(fixed-axis roll, pitch, yaw; 0 0 0 = fingers along +x, back of the hand up); "
                   "default %(default)s")
    p.add_argument("--out", type=Path, required=True, help="raw-input MCAP session to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing file")


@command("import-trajectory", _import_trajectory_args)
def import_trajectory(args: argparse.Namespace, console: Console) -> int:
    """Import an offline hand trajectory (MediaPipe/MANO keypoints or OpenXR joints) as a session.

    Completes each frame into the 26 OpenXR joints (orientations from the bones and the palm
    plane, template radii, metacarpals for 21-keypoint input), checks units (metres), joint
    order and side, and writes a raw-input session (/hands, and the object's poses on /tf)
    that `dexaug rerecord` drives through the bridge and `dexaug replay` publishes. Nothing is
    written when the input is refused.
    """
    from teleop.input.keypoints import Anchor
    from teleop.input.trajectory import import_trajectory as run_import

    require_writable(args.out, "--out")
    space = args.space or ("hand" if args.format == "mediapipe" else "xr")
    result = run_import(args.file, args.out, fmt=args.format, side=args.side, fps=args.fps,
                        hand=args.hand, space=space, object_name=args.object,
                        anchor=Anchor.from_rpy(args.wrist_pos, args.wrist_rpy_deg),
                        overwrite=args.overwrite)
    placed = (f", object {args.object} at {np.round(result.metadata['object_pos_m'], 3).tolist()}"
              if "object_pos_m" in result.metadata else "")
    console.print(f"wrote {result.path}: {result.frames} frames over {result.duration_s:.1f} s "
                  f"({result.tracked} with a tracked {args.side} hand, space {space}){placed}",
                  soft_wrap=True)
    return 0


def _bridge_args(p: argparse.ArgumentParser) -> None:
    hand_arg(p)
    p.add_argument("--object", type=object_name,
                   help="object on the table (default: configs/teleop.toml [bridge])")
    p.add_argument("--rig", type=rig_name, default="local", help="zenoh key prefix dexaug/<rig>/… "
                   "(letters, digits, _ and -)")
    p.add_argument("--listen", type=port, default=7447, help="TCP port to listen on (127.0.0.1)")
    p.add_argument("--connect", type=port, nargs="*", default=[], help="peer ports to connect to")
    p.add_argument("--duration", type=positive, help="stop after this many seconds")
    p.add_argument("--record", type=Path, help="start recording to this MCAP file at once")
    p.add_argument("--no-view", action="store_true", help="do not render the /view stream")
    p.add_argument("--object-mode", choices=("demo", "free"),
                   help="demo: the object settles on the table and is held while you grasp (the "
                   "paper's demonstration mode); free: lift it for real (default: "
                   "configs/teleop.toml [bridge] object_mode, demo)")
    p.add_argument("--object-rest", type=int_at_least(0), metavar="N",
                   help="lay the object in its resting pose N (0: the most frequent one from a "
                   "drop; poses computed in MuJoCo and cached; default: upright)")
    p.add_argument("--object-yaw-deg", type=float, metavar="DEG",
                   help="--object-rest: turn about the table normal (degrees; default: the "
                   "config's object_yaw_deg)")
    p.add_argument("--web", action="store_true",
                   help="also serve the headset page (WebXR) and its WebSocket ingest")
    p.add_argument("--web-port", type=free_port, default=8443,
                   help="port of the headset page (0: any free port); default %(default)s")
    p.add_argument("--cert", type=Path,
                   help="folder for the self-signed certificate (default $DEXAUG_CACHE_DIR/web-cert)")
    p.add_argument("--http", action="store_true",
                   help="plain HTTP (for localhost, e.g. through `adb reverse`: a headset browser "
                   "allows WebXR over plain HTTP on localhost only)")
    from teleop.input.access import add_listen_args

    add_listen_args(p, prefix="web-")
    p.add_argument("--foxglove", action="store_true",
                   help="also serve the live hand, object, contacts, head camera and state to the "
                   "Foxglove app (foxglove-sdk WebSocket server; layout: "
                   "configs/foxglove/dexaug_layout.json)")
    p.add_argument("--foxglove-host", default=FOXGLOVE_HOST,
                   help="address of the Foxglove server: loopback only, as the SDK's server "
                   "cannot require a per-start token (another machine: an SSH tunnel); default "
                   "%(default)s")
    p.add_argument("--foxglove-port", type=free_port, default=FOXGLOVE_PORT,
                   help="port of the Foxglove server (0: any free port); default %(default)s")
    p.add_argument("--auto-augment", action="store_true",
                   help="augment each recording as soon as it is stopped (`dexaug augment` in a "
                   "background process, one at a time in a bounded queue, so the bridge keeps "
                   "running)")
    p.add_argument("--augment-out", type=Path, default=Path("datasets"),
                   help="--auto-augment: output folder (default ./datasets)")
    p.add_argument("--augment-n", type=count, default=DEFAULT_GRASPS,
                   help="--auto-augment: grasps per demo; default %(default)s")


@command("bridge", _bridge_args)
def bridge(args: argparse.Namespace, console: Console) -> int:
    """Run the teleoperation bridge: zenoh /hands in → retarget → MuJoCo → /state, /view out.

    Subscribes dexaug/<rig>/hands (live ingest or `dexaug replay`), drives a floating hand and an
    object on a table, publishes dexaug/<rig>/state and a JPEG head-camera stream on
    dexaug/<rig>/view, and answers dexaug/<rig>/control/** (start_recording, stop_recording,
    choose_object, reset_object, set_object_mode, mark_grasp, status). Ctrl-C stops it.
    """
    import zenoh

    from teleop.bridge.main import bridge_main

    require_free_port("--listen", args.listen)   # before seconds of loading the hand and scene
    if args.record:
        require_writable(args.record, "--record")
    if args.auto_augment:
        require_writable(args.augment_out, "--augment-out", folder=True)
    foxglove = _foxglove_address(args) if args.foxglove else None
    hook = (_auto_augment(args.augment_out, console, ("--n", str(args.augment_n)))
            if args.auto_augment else None)
    with contextlib.ExitStack() as opened:   # whatever starts is closed, on any failure too
        if hook is not None:   # last out: lets the queued augmentations finish (Ctrl-C stops them)
            opened.callback(hook.close)
        extra_ports = (_start_web_ingest(args, console, opened),) if args.web else ()
        console.print(f"bridge on rig {args.rig!r}, listening on tcp/127.0.0.1:{args.listen}")
        try:
            return bridge_main(args.hand, args.object, args.rig, listen_port=args.listen,
                               connect_ports=tuple(args.connect) + extra_ports,
                               duration_s=args.duration, record=args.record,
                               view=False if args.no_view else None,
                               object_mode=args.object_mode, object_rest=args.object_rest,
                               object_yaw_deg=args.object_yaw_deg, on_recording_closed=hook,
                               foxglove=foxglove, on_foxglove=lambda live: console.print(Text(
                                   f"Foxglove: open {live.url} (or {live.app_url()})"),
                                   soft_wrap=True))
        except zenoh.ZError as exc:   # e.g. --listen taken by another process in the meantime
            raise NetworkError(f"zenoh failed (bridge --listen {args.listen}): "
                               f"{zenoh_message(exc)}") from None


def _foxglove_address(args: argparse.Namespace) -> tuple[str, int]:
    """``--foxglove-host``/``--foxglove-port``, checked before the bridge loads: a host off
    loopback is a usage error (teleop.bridge.foxglove_live), a taken port a network error."""
    from teleop.bridge.foxglove_live import check_host

    try:
        host = check_host(args.foxglove_host)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.foxglove_port:
        require_free_port("--foxglove-port", args.foxglove_port, host)
    return host, args.foxglove_port


def _start_web_ingest(args: argparse.Namespace, console: Console,
                      opened: contextlib.ExitStack) -> int:
    """Serve the headset page for ``bridge --web``, closed by ``opened``; returns the port of
    the ingest's own zenoh peer, which the bridge connects to."""
    from teleop.input.background_server import WebIngestError
    from teleop.input.web_ingest import WebIngest, WebIngestConfig
    from teleop.keys import free_tcp_port

    zport = free_tcp_port()
    ingest = WebIngest(args.rig, WebIngestConfig(host=args.web_host, token=args.web_token,
                                                 port=args.web_port, tls=not args.http,
                                                 cert_dir=args.cert), listen_port=zport)
    opened.callback(ingest.close)
    try:
        ingest.start()
    except WebIngestError as exc:
        if isinstance(exc.__cause__, (OSError, OverflowError)):   # the bind itself failed
            raise NetworkError(f"--web-port {args.web_port}: {exc}") from None
        raise
    console.print(Text("headset page: " + "  or  ".join(ingest.page_urls())), soft_wrap=True)
    return zport


def _auto_augment(out: Path, console: Console, augment_args: Sequence[str] = ()) -> AugmentQueue:
    """A recording-closed hook that queues ``dexaug augment PATH --out OUT [augment_args]``:
    each in its own process (log in ``OUT/<session>.augment.log``), one at a time in a bounded
    queue (:mod:`dexaug.pipeline.augment_queue`), so augmentation never stalls the bridge and
    quick start/stops do not pile up processes."""
    from dexaug.pipeline.augment_queue import AugmentQueue

    return AugmentQueue(out, augment_args,
                        notify=lambda message: console.print(Text(message), highlight=False))
