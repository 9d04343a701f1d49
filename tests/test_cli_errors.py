"""Every `dexaug` error is one line on stderr, naming the option or file and what was expected,
never a traceback; out-of-range options are refused while the command line is parsed, before
anything is loaded; a busy port ends the command at once with everything it opened closed.

Each test runs the real command in its own process (``python -m dexaug``), as a user would.
"""

from __future__ import annotations

import importlib.util
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import HANG_S, SOON_S, needs_menagerie, needs_ycb, sigint_as_a_terminal_gives_it, wait_for

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]

#: exit status and stderr line of a command run with ``no_zenoh`` that opened a zenoh session
ZENOH_OPENED = 97
#: ``python -c`` program running ``dexaug`` with ``zenoh.open`` replaced by an exit: a command
#: refused "before any zenoh session" is checked on that event instead of on its wall time
_NO_ZENOH = f"""
import os, runpy, sys, zenoh

def _opened(*args, **kwargs):
    sys.stderr.write("test guard: dexaug opened a zenoh session\\n")
    sys.stderr.flush()
    os._exit({ZENOH_OPENED})

zenoh.open = _opened
sys.argv[0] = "dexaug"
runpy.run_module("dexaug", run_name="__main__")
"""


def _dexaug(*args: str, timeout_s: float = HANG_S, no_zenoh: bool = False
            ) -> tuple[subprocess.CompletedProcess[str], float]:
    """Run ``python -m dexaug ARGS``; returns the finished process and its wall time, seconds.
    ``timeout_s`` only catches a hang (the tests assert on events, not on wall time);
    ``no_zenoh``: the command exits with :data:`ZENOH_OPENED` if it opens a zenoh session."""
    start = time.monotonic()
    head = ["-c", _NO_ZENOH] if no_zenoh else ["-m", "dexaug"]
    proc = subprocess.run([sys.executable, *head, *args], capture_output=True, text=True,
                          timeout=timeout_s, cwd=REPO, stdin=subprocess.DEVNULL,
                          env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")})
    assert proc.returncode != ZENOH_OPENED, proc.stderr
    return proc, time.monotonic() - start


def _one_line_error(proc: subprocess.CompletedProcess[str], *words: str) -> str:
    """The single stderr line of a failed command, checked to hold every one of ``words``."""
    assert proc.returncode != 0, proc.stdout
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.fixture
def busy_port() -> Iterator[int]:
    """A TCP port on 127.0.0.1 held by a listening socket for the test's duration."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


@pytest.mark.parametrize(("args", "option", "expected"), [
    (["generate", "--object", "cylinder", "--n", "0"], "--n", "whole number >= 1"),
    (["generate", "--object", "cylinder", "--n", "-5"], "--n", "whole number >= 1"),
    (["generate", "--object", "cylinder", "--fingers", "1"], "--fingers", "whole number >= 2"),
    (["augment", "s.mcap", "--budget", "0"], "--budget", "finite number > 0"),
    (["augment", "s.mcap", "--budget", "nan"], "--budget", "finite number > 0"),
    (["augment", "s.mcap", "--budget", "inf"], "--budget", "finite number > 0"),
    (["augment", "s.mcap", "--workers", "0"], "--workers", "whole number >= 1"),
    (["augment", "s.mcap", "--gallery", "-1"], "--gallery", "whole number >= 0"),
    (["bench", "paper", "--n", "0"], "--n", "whole number >= 1"),
    (["demo", "script", "--object", "cylinder", "--out", "d", "--tries", "0"], "--tries",
     "whole number >= 1"),
    (["replay", "s.mcap", "--rate", "0"], "--rate", "speed factor > 0 or 'max'"),
    (["replay", "s.mcap", "--rate", "fast"], "--rate", "speed factor > 0 or 'max'"),
    (["replay", "s.mcap", "--connect", "0"], "--connect", "port number 1-65535"),
    (["replay", "s.mcap", "--rig", "a/b*"], "--rig", "letters, digits, '_' and '-'"),
    (["ui", "--port", "70000"], "--port", "port number 0-65535"),
    (["ui", "--workers", "0"], "--workers", "whole number >= 1"),
    (["bridge", "--listen", "70000"], "--listen", "port number 1-65535"),
    (["bridge", "--web-port", "-1"], "--web-port", "port number 0-65535"),
    (["bridge", "--connect", "7447", "65536"], "--connect", "port number 1-65535"),
    (["bridge", "--rig", "a/b*"], "--rig", "letters, digits, '_' and '-'"),
    (["bridge", "--rig", "lab 1"], "--rig", "letters, digits, '_' and '-'"),
    (["bridge", "--augment-n", "0"], "--augment-n", "whole number >= 1"),
    (["bridge", "--duration", "-1"], "--duration", "finite number > 0"),
    (["import-trajectory", "t.npy", "--side", "right", "--out", "o.mcap", "--fps", "0"], "--fps",
     "finite number > 0"),
])
def test_out_of_range_options_are_refused_while_parsing(args: list[str], option: str,
                                                         expected: str) -> None:
    proc, _ = _dexaug(*args)
    line = _one_line_error(proc, f"argument {option}", expected, f"dexaug {args[0]}")
    assert proc.returncode == 2, line
    # refused before anything loads: loading a hand, object or workspace logs INFO lines, which
    # the one-line check above would catch (a hang: _dexaug's timeout)


def test_a_missing_argument_is_one_line() -> None:
    proc, _ = _dexaug("generate", "--n", "5")
    _one_line_error(proc, "--object", "required")


def test_augment_without_input_is_one_line() -> None:
    proc, _ = _dexaug("augment")
    assert proc.returncode == 2
    _one_line_error(proc, "give sessions to augment or --watch DIR")


def test_warp_with_a_protocol_it_cannot_step_is_refused() -> None:
    proc, _ = _dexaug("generate", "--object", "062_dice", "--backend", "warp", "--validate", "dgb")
    assert proc.returncode == 2
    _one_line_error(proc, "--backend warp runs lift-drop and six-dir", "dgb")


@pytest.mark.skipif(importlib.util.find_spec("mujoco_warp") is not None,
                    reason="MuJoCo Warp is installed here: the backend may run")
def test_a_missing_warp_backend_is_one_line_before_any_work(tmp_path: Path) -> None:
    out = tmp_path / "grasps.h5"
    proc, _ = _dexaug("generate", "--object", "062_dice", "--n", "200", "--backend", "warp",
                      "--out", str(out))
    _one_line_error(proc, "--backend warp needs MuJoCo Warp", "pip install mujoco-warp")
    assert "FSG" not in proc.stdout and not out.exists()   # refused before the search


def test_error_text_is_printed_as_is_not_as_markup(tmp_path: Path) -> None:
    """Bracketed text ("[x]", "[bold]") in a path is printed, not read as rich markup."""
    folder = tmp_path / "take [x] [bold]"
    folder.mkdir()
    missing = folder / "[red]session.mcap"
    proc, _ = _dexaug("replay", str(missing))
    line = _one_line_error(proc, str(missing))
    assert line.startswith("error: ")


def test_an_existing_file_that_is_not_a_session_names_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "[thumb] notes.mcap"
    bad.write_text("not an MCAP file\n")
    proc, _ = _dexaug("replay", str(bad))
    _one_line_error(proc, str(bad))


def test_replay_of_a_session_without_hand_frames_fails(tmp_path: Path) -> None:
    from teleop.record.recorder import SessionRecorder

    path = tmp_path / "no_hands.mcap"
    with SessionRecorder(path, metadata={"hand": "shadow_right", "object": "cylinder"}) as rec:
        rec.write_event("object_reset")
    # refused before any zenoh session (so before any wait for a bridge): no_zenoh
    proc, _ = _dexaug("replay", str(path), "--connect", "1", no_zenoh=True)
    _one_line_error(proc, str(path), "no hand frames (/hands)")


def test_busy_listen_port_is_one_line_before_loading(busy_port: int) -> None:
    # checked before the hand loads and before zenoh opens its listener (no_zenoh)
    proc, _ = _dexaug("bridge", "--listen", str(busy_port), "--no-view", "--duration", "3",
                      no_zenoh=True)
    _one_line_error(proc, f"--listen {busy_port}", "already in use")  # no loading log before it
    assert "bridge on rig" not in proc.stdout


def _bridge_on_busy_web_port(port: int) -> tuple[subprocess.CompletedProcess[str], float]:
    return _dexaug("bridge", "--web", "--http", "--web-port", str(port), "--listen",
                   str(_free_port()), "--no-view", "--duration", "3")


def test_busy_web_port_ends_the_bridge_at_once(busy_port: int) -> None:
    """`dexaug bridge --web` on a taken port: an error naming --web-port and an exit, not a
    hang (the ingest's zenoh peer, opened before the page server failed, is closed)."""
    proc, _ = _bridge_on_busy_web_port(busy_port)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    first = proc.stderr.splitlines()[0]
    assert first.startswith(f"error: --web-port {busy_port}: ") and "already in use" in first
    # "at once": it ended before the bridge was built (printed first), not after its 3 s run
    # (which would exit 0); a hang is _dexaug's timeout
    assert "bridge on rig" not in proc.stdout, proc.stdout


def test_busy_web_port_error_is_the_only_line(busy_port: int) -> None:
    proc, _ = _bridge_on_busy_web_port(busy_port)
    _one_line_error(proc, f"--web-port {busy_port}", "already in use")
    assert "bridge on rig" not in proc.stdout, proc.stdout


@needs_menagerie
def test_busy_dashboard_port_is_one_line(busy_port: int, tmp_path: Path) -> None:
    # a dashboard that went on serving would never exit: _dexaug's timeout
    proc, _ = _dexaug("ui", "--port", str(busy_port), "--sessions", str(tmp_path),
                      "--out", str(tmp_path / "out"))
    _one_line_error(proc, str(busy_port), "already in use")


def test_a_real_zenoh_refusal_reads_as_one_clean_line() -> None:
    """The fallback message for a --listen port taken after the check: zenoh's own error,
    without the Rust source locations it carries."""
    import zenoh

    from dexaug.commands.network import zenoh_message
    from teleop.keys import open_session

    port = _free_port()
    first = open_session(port)
    try:
        with pytest.raises(zenoh.ZError) as refused:
            open_session(port).close()
    finally:
        first.close()
    text = zenoh_message(refused.value)
    assert f"127.0.0.1:{port}" in text and "already in use" in text, text
    assert ".rs:" not in text and "\n" not in text


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _group_processes(pgid: int) -> list[str]:
    """The command lines of the live (not zombie) processes of process group ``pgid``."""
    return [args for _, args in _group_pids(pgid)]


def _group_pids(pgid: int) -> list[tuple[int, str]]:
    """(pid, command line) of the live (not zombie) processes of process group ``pgid``.

    ``-ww``: whole command lines. Without it ps cuts each line to ``$COLUMNS`` (80 on CI), and
    a checkout path longer than ours pushed "forkserver" past the cut: CI saw no worker."""
    ps = subprocess.run(["ps", "-ww", "-o", "pid=,stat=,args=", "-g", str(pgid)],
                        capture_output=True, text=True)
    rows = [line.split(None, 2) for line in ps.stdout.splitlines()]
    return [(int(row[0]), row[2]) for row in rows if len(row) == 3 and not row[1].startswith("Z")]


def _sampling_workers(pgid: int) -> list[int]:
    """The FSG workers of group ``pgid`` that are sampling: the fork server's children that
    have mapped FSG's progress board (a ``/dev/shm/psm_*`` block, attached by each worker as
    its FSG task begins: augment.fsg.progress.worker_slot); the fork server itself maps none."""
    found = []
    for pid, args in _group_pids(pgid):
        if "forkserver" not in args:
            continue
        try:
            maps = Path(f"/proc/{pid}/maps").read_text()
        except OSError:   # gone meanwhile
            continue
        if "/dev/shm/psm_" in maps:
            found.append(pid)
    return found


@needs_menagerie
@needs_ycb
@pytest.mark.parametrize(("signum", "to_group", "status", "again"), [
    (signal.SIGINT, False, 130, False), (signal.SIGINT, True, 130, False),
    (signal.SIGTERM, False, 143, False), (signal.SIGINT, True, 130, True)],
    ids=["sigint-main-process", "sigint-process-group", "sigterm-main-process",
         "sigint-again-while-stopping"])
def test_interrupting_fsg_exits_within_seconds(tmp_path: Path, signum: int, to_group: bool,
                                               status: int, again: bool) -> None:
    """SIGINT or SIGTERM while FSG's workers sample (a budget of minutes): the command ends
    within seconds (status 130 or 143), whether the signal reaches the main process only
    (`kill`, a service manager, a parent process) or the whole process group (Ctrl-C in a
    terminal), prints no traceback and leaves no worker behind. ``again``: Ctrl-C pressed over
    and over (an impatient user; ``timeout -s INT`` delivering it twice) until the command has
    ended — one landing while the workers are being stopped used to print a traceback."""
    session = REPO / "recordings" / "demo_062_dice.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "dexaug", "augment", str(session), "--n", "100000", "--budget",
         "300", "--gallery", "0", "--workers", "2", "--validate", "none", "--out",
         str(tmp_path / "out")],
        cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        start_new_session=True, env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")},
        preexec_fn=sigint_as_a_terminal_gives_it)
    try:
        # the event itself: both workers are in their FSG task (loading the session, building
        # the workspace and starting the fork server come first: seconds, more under load)
        wait_for(lambda: len(_sampling_workers(proc.pid)) == 2, 5 * SOON_S,
                 lambda: f"2 sampling FSG workers; the group: {_group_processes(proc.pid)}",
                 every_s=0.1, unless=lambda: None if proc.poll() is None
                 else f"the command exited with status {proc.returncode}")
        sent = time.monotonic()
        if to_group:
            os.killpg(proc.pid, signum)
        else:
            proc.send_signal(signum)
        while again and proc.poll() is None and time.monotonic() - sent < SOON_S:
            os.killpg(proc.pid, signum)
            time.sleep(0.01)
        # within seconds on a quiet machine; the bound is SOON_S, a fifth of the 300 s budget
        # its workers would otherwise sample for, so it still tells the two apart under load
        assert proc.wait(SOON_S) == status, time.monotonic() - sent
        assert "Traceback" not in proc.stderr.read()
        # the fork server ends on its own pipe's EOF, a worker within a second of its owner
        wait_for(lambda: _group_processes(proc.pid) == [], SOON_S,
                 lambda: f"the group's end; left: {_group_processes(proc.pid)}", every_s=0.1)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_every_option_help_shows_its_default() -> None:
    """`dexaug <command> --help` names the default of every option that has one (#16: help
    texts hid defaults): the value as given, or the help's own words for it."""
    import argparse

    from dexaug.cli import COMMANDS, build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name in COMMANDS:
        p = sub.choices[name]
        text = " ".join(p.format_help().split())
        for action in p._actions:
            d = action.default
            if (not action.option_strings or d is None or d is False or d is argparse.SUPPRESS
                    or (isinstance(d, list) and not d)):
                continue
            if str(d) not in text and "default" not in (action.help or ""):
                missing.append(f"{name} {action.option_strings[0]}")
    assert not missing, missing
