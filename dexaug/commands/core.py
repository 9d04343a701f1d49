"""Subcommands of ``dexaug``. Each one parses its arguments, calls the library, and reports."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.progress import Progress
from rich.table import Table

from dexaug.commands.registry import command


def _assets_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--broken", action="store_true", help="list only objects that fail to load")


@command("assets", _assets_args)
def assets(args: argparse.Namespace, console: Console) -> int:
    """List the hands and objects dexaug can find, and what is broken and why.

    Hands come from configs/hands/*/hand.toml resolved through mujoco_menagerie (MENAGERIE_ROOT);
    objects are the procedural primitives plus every YCB object under DEXAUG_YCB_ROOT.
    """
    from sim.errors import DexaugError
    from sim.hand.config import HANDS_DIR
    from sim.hand.model import Hand
    from sim.paths import MENAGERIE_ENV, YCB_ENV, ensure_menagerie_root, ycb_root
    from sim.world.objects import list_objects

    console.print(f"{MENAGERIE_ENV} = {ensure_menagerie_root()}")
    console.print(f"{YCB_ENV} = {ycb_root(required=False)}")
    hands = Table(title="hands")
    for col in ("hand", "joints", "actuators", "fingers", "status"):
        hands.add_column(col)
    for path in sorted(HANDS_DIR.glob("*/hand.toml")):
        try:
            hand = Hand.load(path)
            hands.add_row(path.parent.name, str(hand.nq), str(hand.model.nu),
                          ", ".join(hand.finger_names), "[green]ok")
        except DexaugError as exc:
            hands.add_row(path.parent.name, "", "", "", f"[red]{exc}")
    console.print(hands)
    objects = Table(title="objects")
    for col in ("object", "source", "mass (kg)", "status"):
        objects.add_column(col)
    statuses = list_objects()
    for s in statuses:
        if args.broken and s.ok:
            continue
        state = "[green]ok" if s.ok else f"[red]broken: {s.problem}"
        if s.ok and s.warnings:
            state = f"[yellow]ok ({'; '.join(s.warnings)})"
        objects.add_row(s.name, s.source, f"{s.mass_kg:.3f}" if s.mass_kg else "", state)
    console.print(objects)
    broken = sum(not s.ok for s in statuses)
    console.print(f"{len(statuses) - broken} objects load, {broken} broken")
    return 0


def _validate_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--hand", default="shadow_right", help="hand config name (configs/hands)")
    p.add_argument("--object", help="only grasps of this object")
    p.add_argument("--grasps", type=Path, help="reference-grasp TOML (default: "
                   "configs/hands/<hand>/grasps.toml)")
    p.add_argument("--protocol", choices=("lift-drop", "six-dir", "both"), default="both")
    p.add_argument("--render", type=Path, metavar="DIR",
                   help="write a PNG of each grasp after closing (contacts marked) into DIR")
    p.add_argument("--json", type=Path, help="write the full results as JSON")


def _result_table(rows: list[tuple[str, str, object]]) -> Table:
    table = Table(title="grasp validation")
    for col in ("grasp", "object", "protocol", "result", "reason", "contacts", "pen. (mm)",
                "disp. (mm)", "rot. (°)", "GWS ε", "GWS vol.", "time (s)"):
        table.add_column(col, justify="right" if col[0] in "cpdrGt" else "left")
    for name, obj, (res, seconds) in rows:
        table.add_row(name, obj, res.protocol, "[green]pass" if res.passed else "[red]fail",
                      res.failure or "", str(res.n_contacts), f"{res.penetration_m * 1e3:.1f}",
                      f"{res.displacement_m * 1e3:.1f}", f"{np.degrees(res.rotation_rad):.1f}",
                      f"{res.epsilon:.4f}", f"{res.volume:.2e}", f"{seconds:.2f}")
    return table


def run_reference_validation(hand_name: str, console: Console, *, object_name: str | None = None,
                             grasps_path: Path | None = None, protocols: tuple[str, ...] = (
                                 "lift-drop", "six-dir"), render_dir: Path | None = None,
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
    """Validate grasps in MuJoCo with the lift-drop and/or six-dir protocol (DESIGN §5).

    Without --grasps, validates the hand's hand-built reference grasps
    (configs/hands/<hand>/grasps.toml). Prints per grasp: pass/fail and why, contact count,
    penetration, object displacement and rotation, and the GWS ε/volume of the simulated contacts.
    """
    protocols = ("lift-drop", "six-dir") if args.protocol == "both" else (args.protocol,)
    if args.render:
        from sim.world.render import select_gl_backend

        select_gl_backend()
    return run_reference_validation(args.hand, console, object_name=args.object,
                                    grasps_path=args.grasps, protocols=protocols,
                                    render_dir=args.render, json_path=args.json)


def _demo_args(p: argparse.ArgumentParser) -> None:
    from sim.paths import REPO_ROOT

    p.add_argument("--session", type=Path,
                   default=REPO_ROOT / "recordings" / "demo_005_tomato_soup_can.mcap",
                   help="the demonstration session to augment (default: the committed Shadow "
                   "Hand grasp of the tomato soup can)")
    p.add_argument("--out", type=Path, default=Path("datasets/demo"), help="output folder")
    p.add_argument("--n", type=int, default=100, help="grasps to generate")


@command("demo", _demo_args)
def demo(args: argparse.Namespace, console: Console) -> int:
    """Run the main job on its embedded default (what `make demo` runs).

    1. The teleop path: the synthetic operator's session (recordings/synth_*.mcap, raw hand
       tracking) replays through the real bridge (zenoh, mink retargeting, MuJoCo) into a new
       recording, as a headset's would.
    2. The augmentation: the demonstration session (--session) → grasp demo → AutoWS → FSG →
       lift-drop validation of every grasp → HDF5 dataset and HTML report, whose paths are
       printed. Without the YCB objects, a scripted demonstration on a procedural cylinder is
       recorded first and augmented instead.
    """
    import tempfile

    from dexaug.commands.augment import progress_bars, stage_ticker
    from dexaug.pipeline.options import AugmentOptions
    from dexaug.pipeline.run import augment_session
    from sim.errors import DexaugError
    from sim.paths import REPO_ROOT
    from sim.world.objects import load_object
    from teleop.record.rerecord import rerecord
    from teleop.record.session import open_session

    args.out.mkdir(parents=True, exist_ok=True)
    session = args.session
    raw = sorted((REPO_ROOT / "recordings").glob("synth_*.mcap"))
    try:   # the committed sessions hold YCB objects: are they installed here?
        for path in (session, *raw[:1]):
            load_object(open_session(path).metadata.get("object", ""))
    except DexaugError as exc:
        console.print(f"[yellow]{exc}\n→ recording a scripted demonstration on a procedural "
                      f"cylinder instead", highlight=False)
        session = _procedural_demo_session(args.out / "demo_cylinder.mcap")
        raw = []
    if raw:
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            rec = open_session(rerecord(raw[0], Path(tmp) / "replayed.mcap"))
            console.print(f"1. replayed {raw[0].name} through the bridge: {rec.counts['/hands']} "
                          f"frames → {rec.counts['/state']} states, "
                          f"{rec.counts['/contacts']} contact records in "
                          f"{time.perf_counter() - start:.1f} s")
    console.print(f"2. augmenting {session}")
    opts = AugmentOptions(n=args.n, time_budget_s=90.0, gallery=4)
    start = time.perf_counter()
    with progress_bars(console) as bar:
        summaries = augment_session(session, args.out, opts, progress=stage_ticker(bar),
                                    force=True)
    for s in summaries:
        console.print(f"demo {s.demo_id}: {s.generated} grasps generated, {s.passed} passed "
                      f"lift-drop in {time.perf_counter() - start:.1f} s")
        console.print(f"dataset: {s.dataset}")
        console.print(f"report:  {s.report}")
    return 0


def _procedural_demo_session(out: Path) -> Path:
    """A scripted demonstration on the procedural cylinder: the first FSG grasp (manual
    workspace, table mode) that passes lift-drop, performed and recorded."""
    from dexaug.pipeline.scripted_demos import demonstrable_grasps
    from sim.errors import DexaugError
    from sim.hand.model import Hand
    from teleop.synthetic.scripted import record_scripted_demo

    hand = Hand.load("shadow_right")
    passing = demonstrable_grasps(hand, "cylinder", 30)
    if not passing:
        raise DexaugError("no FSG grasp of the procedural cylinder passed lift-drop")
    return record_scripted_demo(hand, "cylinder", passing[0], out, overwrite=True)


def _workspace_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--hand", default="shadow_right", help="hand config name (configs/hands)")
    p.add_argument("--demo", metavar="GRASP",
                   help="centre the clouds on a demonstration: the name of a reference grasp in "
                   "configs/hands/<hand>/grasps.toml (its joints, and its fingertip contacts on its "
                   "object found in MuJoCo)")
    p.add_argument("--out", type=Path, help="also save the clouds to this .npz file")
    p.add_argument("--render", type=Path, metavar="PNG", help="render the clouds over the hand")
    p.add_argument("--no-cache", action="store_true", help="ignore and do not write the disk cache")


@command("workspace", _workspace_args)
def workspace(args: argparse.Namespace, console: Console) -> int:
    """Build AutoWS fingertip workspace clouds (paper §3) for a hand.

    Without --demo, joint grids come from the manual ranges of the hand config (the paper's
    Table 1 for the Shadow Hand); with --demo, from the demonstration's angles ± 2 steps of 5°,
    with contact faces centred on its fingertip contacts. Clouds are cached on disk
    (DEXAUG_CACHE_DIR), keyed by the hand model, config, demo and parameters.
    """
    if args.render:
        from sim.world.render import select_gl_backend

        select_gl_backend()
    from augment.autows.workspace import DemoSeed, build_workspace, render_workspace_png, summarise
    from sim.hand.model import Hand

    hand = Hand.load(args.hand)
    demo = None
    if args.demo:
        from sim.errors import ConfigError
        from sim.hand.reference_grasps import load_reference_grasps
        from sim.validate.validator import Validator
        from sim.world.objects import load_object

        refs = {r.name: r for r in load_reference_grasps(hand)}
        if args.demo not in refs:
            raise ConfigError(f"--demo: no reference grasp {args.demo!r} for hand {hand.name!r}; "
                              f"known: {sorted(refs)}")
        ref = refs[args.demo]
        contacts = Validator(hand, load_object(ref.object)).fingertip_contacts(ref.grasp)
        demo = DemoSeed(joints=ref.grasp.joints, contacts=contacts, id=f"grasp:{ref.name}")
    start = time.perf_counter()
    cloud = build_workspace(hand, demo=demo, cache=not args.no_cache)
    seconds = time.perf_counter() - start
    table = Table(title=f"AutoWS workspace of {hand.name}" + (f" (demo {args.demo})" if demo else ""))
    for col in ("finger", "points", "contact faces"):
        table.add_column(col)
    for finger, n_points, n_faces in summarise(cloud):
        table.add_row(finger, str(n_points), str(n_faces))
    console.print(table)
    source = "cache" if cloud.from_cache else "built"
    console.print(f"{source} in {seconds * 1e3:.1f} ms, {cloud.nbytes / 1e6:.2f} MB")
    if args.out:
        cloud.save(args.out)
        console.print(f"wrote {args.out}")
    if args.render:
        render_workspace_png(hand, cloud, args.render)
        console.print(f"wrote {args.render}")
    return 0


def _retarget_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="an MCAP session recorded by dexaug, or an IWER "
                   "capture module (.js) recorded in a WebXR page")
    p.add_argument("--hand", default="shadow_right", help="hand config name (configs/hands)")
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
    from teleop.retarget.retargeter import Retargeter, retarget_frames, summarise_errors

    if args.file.suffix == ".js":
        from teleop.input.webxr import iwer_hand_frames, load_iwer_capture

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
            np.savez(f, **trace.as_dict())
        console.print(f"wrote {args.out}")
    return 0


def _synth_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--object", default="005_tomato_soup_can", help="object to grasp (YCB id or "
                   "primitive)")
    p.add_argument("--hand", default="shadow_right", help="robot hand config the episode targets")
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
    from teleop.synthetic.synth import synthesize, write_session

    episode = synthesize(args.object, hand=args.hand, seed=args.seed, grasp_name=args.grasp)
    path = write_session(episode, args.out, overwrite=args.overwrite)
    tracked = int(episode.tracked.sum())
    console.print(f"wrote {path}: {len(episode.frames)} frames over "
                  f"{episode.frames[-1].device_time_s - episode.frames[0].device_time_s:.1f} s "
                  f"({tracked} with a tracked hand), grasp mark at {episode.grasp_time_s:.2f} s, "
                  f"imitating {episode.reference_grasp or 'a generic side grasp'}", soft_wrap=True)
    return 0


def _bridge_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--hand", default="shadow_right", help="hand config name (configs/hands)")
    p.add_argument("--object", help="object on the table (default: configs/teleop.toml [bridge])")
    p.add_argument("--rig", default="local", help="zenoh key prefix dexaug/<rig>/…")
    p.add_argument("--listen", type=int, default=7447, help="TCP port to listen on (127.0.0.1)")
    p.add_argument("--connect", type=int, nargs="*", default=[], help="peer ports to connect to")
    p.add_argument("--duration", type=float, help="stop after this many seconds")
    p.add_argument("--record", type=Path, help="start recording to this MCAP file at once")
    p.add_argument("--no-view", action="store_true", help="do not render the /view stream")
    p.add_argument("--web", action="store_true",
                   help="also serve the headset page (WebXR) and its WebSocket ingest")
    p.add_argument("--web-port", type=int, default=8443, help="port of the headset page")
    p.add_argument("--cert", type=Path,
                   help="folder for the self-signed certificate (default $DEXAUG_CACHE_DIR/web-cert)")
    p.add_argument("--http", action="store_true",
                   help="plain HTTP (only for localhost, e.g. through `adb reverse`)")
    p.add_argument("--auto-augment", action="store_true",
                   help="augment each recording as soon as it is stopped (`dexaug augment` in a "
                   "background process, so the bridge keeps running)")
    p.add_argument("--augment-out", type=Path, default=Path("datasets"),
                   help="--auto-augment: output folder (default ./datasets)")


@command("bridge", _bridge_args)
def bridge(args: argparse.Namespace, console: Console) -> int:
    """Run the teleoperation bridge: zenoh /hands in → retarget → MuJoCo → /state, /view out.

    Subscribes dexaug/<rig>/hands (live ingest or `dexaug replay`), drives a floating hand and an
    object on a table, publishes dexaug/<rig>/state and a JPEG head-camera stream on
    dexaug/<rig>/view, and answers dexaug/<rig>/control/** (start_recording, stop_recording,
    choose_object, reset_object, mark_grasp, status). Ctrl-C stops it.
    """
    from teleop.bridge.bridge import bridge_main

    console.print(f"bridge on rig {args.rig!r}, listening on tcp/127.0.0.1:{args.listen}")
    ingest, extra_ports = None, ()
    if args.web:
        from teleop.input.web_ingest import WebIngest, WebIngestConfig, local_addresses
        from teleop.keys import free_tcp_port

        zport = free_tcp_port()  # the ingest's own zenoh peer; the bridge connects to it
        ingest = WebIngest(args.rig, WebIngestConfig(port=args.web_port, tls=not args.http,
                                                     cert_dir=args.cert), listen_port=zport)
        url = ingest.start()
        extra_ports = (zport,)
        scheme = url.split(":", 1)[0]
        lan = [a for a in local_addresses() if a != "127.0.0.1"]
        console.print(f"headset page: {url}" + "".join(f"  or  {scheme}://{a}:{ingest.port}/"
                                                        for a in lan), soft_wrap=True)
    hook = _auto_augment(args.augment_out, console) if args.auto_augment else None
    try:
        return bridge_main(args.hand, args.object, args.rig, listen_port=args.listen,
                           connect_ports=tuple(args.connect) + extra_ports,
                           duration_s=args.duration, record=args.record,
                           view=False if args.no_view else None, on_recording_closed=hook)
    finally:
        if ingest is not None:
            ingest.close()


def _auto_augment(out: Path, console: Console) -> Callable[[Path], None]:
    """A recording-closed hook that starts ``dexaug augment PATH --out OUT`` in its own process
    (its log goes to ``OUT/<session>.augment.log``), so augmentation never stalls the bridge."""
    import subprocess
    import sys

    def start(path: Path) -> None:
        out.mkdir(parents=True, exist_ok=True)
        log_path = out / f"{path.stem}.augment.log"
        with open(log_path, "ab") as log_file:
            subprocess.Popen([sys.executable, "-m", "dexaug", "augment", str(path), "--out",
                              str(out)], stdout=log_file, stderr=subprocess.STDOUT,
                             stdin=subprocess.DEVNULL)
        console.print(f"augmenting {path} in the background (log: {log_path})")

    return start


def _replay_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", type=Path, help="MCAP session to replay")
    p.add_argument("--rate", default="1.0", help="playback speed factor, or 'max'")
    p.add_argument("--rig", default="local", help="zenoh key prefix dexaug/<rig>/…")
    p.add_argument("--connect", type=int, nargs="+", default=[7447],
                   help="bridge port(s) to connect to on 127.0.0.1")


@command("replay", _replay_args)
def replay(args: argparse.Namespace, console: Console) -> int:
    """Publish a recorded session's hand tracking back onto zenoh (dexaug/<rig>/hands).

    With original timing (--rate 1.0), scaled, or as fast as possible (--rate max); the bridge
    cannot tell a replay from a live headset.
    """
    from sim.errors import ConfigError
    from teleop.keys import free_tcp_port, open_session
    from teleop.record.replay import replay as replay_session

    rate: float | str = args.rate
    if args.rate != "max":
        try:
            rate = float(args.rate)
        except ValueError:
            raise ConfigError(f"--rate: expected a number or 'max', got {args.rate!r}") from None
    session = open_session(free_tcp_port(), tuple(args.connect))
    try:
        sent = replay_session(args.file, session, args.rig, rate=rate)
    finally:
        session.close()
    console.print(f"replayed {sent} hand-tracking messages from {args.file}")
    return 0
