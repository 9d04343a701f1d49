#!/usr/bin/env python3
"""Does a test fail when a guard is gone? Each security guard and fault handler the guides claim
(docs/security.md: loopback by default, the per-start token, the
Host / Origin / CSRF checks of the dashboard and the headset page, a remote caller never
choosing a file path, the recorder's disk-full / kill / truncation handling, the bridge's
wrist-jump limit and instability restore, busy ports, Ctrl-C ending FSG's workers) is listed
below with the exact source it lives in, a replacement that disables it, and the test meant to
catch that.

For each entry the repository is copied to a temporary folder (without .venv and .git; a
``shared`` link beside it, as the tests find their assets in ../shared), the snippet replaced
there, and that one test run with the project's .venv python in the copy (its own rootdir and
package sources: the editable install's finder comes after the copy on sys.path). The test
must FAIL: then the mutation is "killed". It "survived" when the test passes; "skipped" when it
did not run (assets or Chromium missing); "not found" when the snippet is not in the file
exactly once (the guard moved: update the table). Before that, every listed test is run once
on an unmutated copy, so a kill is not a test that fails anyway. The real tree is only read.

Usage: .venv/bin/python scripts/mutation_check.py [-k SUBSTRING] [--timeout S] [--keep]
Exit status 0 only when every mutation is killed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: not copied: the environment, history, caches and outputs
SKIP = {".venv", ".git", "__pycache__", ".pytest_cache", ".ruff_cache", "artifacts", "datasets",
        "build", "out"}


@dataclass(frozen=True)
class Mutation:
    name: str      # the guard, in docs/quest-capture.md's words
    file: str      # relative to the repository root
    snippet: str   # exact source, found exactly once
    replacement: str
    test: str      # the pytest node id meant to catch it


SEC_T = "tests/test_security_teleop.py::"
SEC_D = "tests/test_security_dashboard.py::"
FAULTS = "tests/test_bridge_faults.py::"
REC = "tests/test_recorder.py::"
CLI = "tests/test_cli_errors.py::"
GUARDS = "tests/test_guards.py::"
#: the one network-access policy every server applies (issue #51)
NET = "teleop/net_access.py"

MUTATIONS = [
    # ------------------------------------------------------------------- loopback by default
    Mutation("loopback default: headset page", "teleop/input/web_ingest.py",
             '    host: str = "127.0.0.1"', '    host: str = "0.0.0.0"',
             SEC_T + "test_servers_listen_on_loopback_by_default"),
    Mutation("loopback default: stream-ingest", "teleop/input/stream_ingest.py",
             'tcp_port: int | None = None, host: str = "127.0.0.1",',
             'tcp_port: int | None = None, host: str = "0.0.0.0",',
             SEC_T + "test_servers_listen_on_loopback_by_default"),
    Mutation("loopback default: dashboard", "dexaug/dashboard/server.py",
             '    host: str = "127.0.0.1"', '    host: str = "0.0.0.0"',
             GUARDS + "test_the_dashboard_listens_on_loopback_by_default"),
    Mutation("loopback default: `ui --host`", "dexaug/commands/ui.py",
             'p.add_argument("--host", default="127.0.0.1",',
             'p.add_argument("--host", default="0.0.0.0",',
             GUARDS + "test_the_servers_command_lines_default_to_loopback[ui]"),
    Mutation("loopback default: `stream-ingest --host`", "dexaug/commands/stream.py",
             'p.add_argument("--host", default="127.0.0.1",',
             'p.add_argument("--host", default="0.0.0.0",',
             GUARDS + "test_the_servers_command_lines_default_to_loopback[stream-ingest]"),
    Mutation("loopback default: `bridge --web-host`", "teleop/input/access.py",
             'LOOPBACK_HOST = "127.0.0.1"', 'LOOPBACK_HOST = "0.0.0.0"',
             SEC_T + "test_the_cli_flags_default_to_loopback_and_a_random_token"),
    Mutation("loopback default: zenoh peers", "teleop/keys.py",
             '*, host: str = "127.0.0.1") -> zenoh.Config:',
             '*, host: str = "0.0.0.0") -> zenoh.Config:',
             GUARDS + "test_a_zenoh_peer_listens_on_loopback_only"),
    # ------------------------------------------------------------------------ per-start token
    Mutation("per-start token: a fresh one each start", NET,
             "    return secrets.token_urlsafe(24)",
             '    return "the-same-token-every-start"',
             SEC_T + "test_servers_listen_on_loopback_by_default"),
    # the one rule (teleop/net_access.py) both servers apply, and each server's use of it
    Mutation("per-start token: required off loopback (page)", NET,
             "    return given is not None or not is_loopback(host)",
             "    return given is not None",
             SEC_T + "test_servers_listen_on_loopback_by_default"),
    Mutation("per-start token: required off loopback (dashboard)", NET,
             "    return given is not None or not is_loopback(host)",
             "    return given is not None",
             SEC_D + "test_beyond_loopback_every_request_needs_the_token"),
    Mutation("per-start token: the page applies the rule", "teleop/input/access.py",
             "required=token_required(host, token),", "required=token is not None,",
             SEC_T + "test_servers_listen_on_loopback_by_default"),
    Mutation("per-start token: made beyond loopback (dashboard)", "dexaug/dashboard/guard.py",
             "self.token: str | None = new_token() if token_required(host) else None",
             "self.token: str | None = None",
             SEC_D + "test_beyond_loopback_every_request_needs_the_token"),
    Mutation("loopback: is_loopback (page)", NET,
             "        return ipaddress.ip_address(host.strip(\"[]\")).is_loopback",
             "        return True",
             SEC_T + "test_servers_listen_on_loopback_by_default"),
    Mutation("loopback: is_loopback (dashboard)", NET,
             "        return ipaddress.ip_address(host.strip(\"[]\")).is_loopback",
             "        return True",
             SEC_D + "test_beyond_loopback_every_request_needs_the_token"),
    Mutation("token compare (constant time)", NET,
             "            and hmac.compare_digest(presented.encode(), token.encode()))",
             "            )",
             SEC_T + "test_no_or_a_wrong_token_is_refused_when_required"),
    Mutation("token compare (dashboard)", NET,
             "            and hmac.compare_digest(presented.encode(), token.encode()))",
             "            )",
             SEC_D + "test_beyond_loopback_every_request_needs_the_token"),
    Mutation("per-start token: checked (dashboard)", "dexaug/dashboard/guard.py",
             "            if not (via_query or self._matches(request.headers.get(TOKEN_HEADER))",
             "            if False and not (via_query or self._matches(request.headers.get(TOKEN_HEADER))",
             SEC_D + "test_beyond_loopback_every_request_needs_the_token"),
    Mutation("per-start token: page and WebSocket", "teleop/input/access.py",
             "        if why is None and policy.required and request.path in TOKEN_PATHS and \\",
             "        if False and why is None and policy.required and request.path in TOKEN_PATHS and \\",
             SEC_T + "test_no_or_a_wrong_token_is_refused_when_required"),
    Mutation("per-start token: page's control messages", "teleop/input/web_ingest.py",
             '        if self.access.required and not self.access.token_ok(msg.get("token")):',
             "        if False:",
             SEC_T + "test_no_or_a_wrong_token_is_refused_when_required"),
    # -------------------------------------------------------------------- Host / Origin / CSRF
    Mutation("dashboard Host check (DNS rebinding)", NET,
             "    if name in names:\n        return True", "    if True:\n        return True",
             SEC_D + "test_a_foreign_host_is_refused_even_for_reading"),
    Mutation("dashboard applies the Host check", "dexaug/dashboard/guard.py",
             "        if host_ok(header, self.names, str(sock[0]) if sock else None):",
             "        if True:",
             SEC_D + "test_a_foreign_host_is_refused_even_for_reading"),
    Mutation("dashboard Origin check", NET,
             "    return origin.strip().lower() == f\"{scheme}://{host_header or ''}\".lower()",
             "    return True",
             SEC_D + "test_cross_site_posts_are_refused_and_start_nothing"),
    Mutation("dashboard applies the Origin check", "dexaug/dashboard/guard.py",
             "        if not origin_ok(origin, request.scheme, request.headers.get(\"Host\")):",
             "        if False:",
             SEC_D + "test_cross_site_posts_are_refused_and_start_nothing"),
    Mutation("dashboard CSRF: JSON bodies only", "dexaug/dashboard/guard.py",
             '        if request.content_type != "application/json":', "        if False:",
             SEC_D + "test_cross_site_posts_are_refused_and_start_nothing"),
    # a cross-site page meets all three POST checks (Origin, JSON only, X-Dexaug): off together
    Mutation("dashboard CSRF checks (a cross-site page in Chromium)", "dexaug/dashboard/guard.py",
             "    def _csrf_error(self, request: web.Request) -> str | None:\n",
             "    def _csrf_error(self, request: web.Request) -> str | None:\n        return None\n",
             SEC_D + "test_chromium_on_a_foreign_page_cannot_start_a_job"),
    Mutation("dashboard CSRF: the X-Dexaug header", "dexaug/dashboard/guard.py",
             "        if request.headers.get(CSRF_HEADER) != CSRF_VALUE and TOKEN_HEADER not in "
             "request.headers:",
             "        if False:",
             SEC_D + "test_cross_site_posts_are_refused_and_start_nothing"),
    Mutation("dashboard job list bounded", "dexaug/dashboard/jobs.py",
             "            if len(waiting) >= self.max_queued:", "            if False:",
             SEC_D + "test_the_job_list_is_bounded"),
    Mutation("page Host check", NET,
             "    if name in names:\n        return True", "    if True:\n        return True",
             SEC_T + "test_a_wrong_host_header_is_refused"),
    Mutation("page applies the Host check", "teleop/input/access.py",
             "        if host_ok(host_header, self.hosts):", "        if True:",
             SEC_T + "test_a_wrong_host_header_is_refused"),
    Mutation("page Origin check", NET,
             "    return origin.strip().lower() == f\"{scheme}://{host_header or ''}\".lower()",
             "    return True",
             SEC_T + "test_a_foreign_origin_websocket_is_refused"),
    Mutation("page applies the Origin check", "teleop/input/access.py",
             "        if origin_ok(origin, scheme, host_header):", "        if True:",
             SEC_T + "test_a_foreign_origin_websocket_is_refused"),
    # ------------------------------------------------------- a remote caller chooses no path
    Mutation("no path: the page forwards only a name", "teleop/input/web_ingest.py",
             "        extra = sorted(clean_text(k, 40) for k in args if k not in allowed)",
             "        extra = []",
             SEC_T + "test_the_page_never_forwards_a_path_or_overwrite"),
    Mutation("no path: zenoh start_recording takes a name", "teleop/bridge/remote_args.py",
             '        refused = sorted(k for k in args if k != "name")', "        refused = []",
             SEC_T + "test_zenoh_start_recording_refuses_path_and_overwrite"),
    Mutation("no path: names stay in recordings_dir", "teleop/bridge/remote_args.py",
             '    base = Path(name.replace("\\\\", "/")).name\n'
             '    stem = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip(".")',
             '    base = name.replace("\\\\", "/")\n    stem = base',
             SEC_T + "test_zenoh_recording_names_stay_inside_the_recordings_folder"),
    Mutation("no path: choose_object takes catalogue ids", "teleop/bridge/remote_args.py",
             "    text = str(name)\n    if not _OBJECT_ID.fullmatch(text):",
             "    text = str(name)\n    return text\n    if not _OBJECT_ID.fullmatch(text):",
             SEC_T + "test_zenoh_choose_object_takes_catalogue_ids_only"),
    Mutation("no path: dashboard arm endpoint", "dexaug/dashboard/arm_jobs.py",
             '    return doc["demo"], check_arm_name(doc["arm"]), placements',
             '    return doc["demo"], doc["arm"], placements',
             SEC_D + "test_the_arm_endpoint_takes_no_path_and_needs_the_token"),
    # ------------------------------------------------------------------------------ recorder
    Mutation("recorder disk full: recording stops, loop goes on", "teleop/bridge/faults.py",
             "        except Exception as exc:\n            self._recording_failed(rec, exc)",
             "        except ZeroDivisionError as exc:\n            self._recording_failed(rec, exc)",
             FAULTS + "test_a_full_disk_stops_the_recording_and_the_loop_goes_on"),
    Mutation("recorder write error: cut back to the last chunk", "teleop/record/session_file.py",
             "            os.truncate(self.path, self.good_bytes)", "            pass",
             FAULTS + "test_a_recorder_write_errors_are_one_line_and_leave_a_readable_file"),
    Mutation("recorder kill: a chunk per flush_interval_s", "teleop/record/recorder.py",
             "                or time.monotonic() - self._chunk_open_mono >= self.flush_interval_s\n"
             "                or abs(log_time_ns - self._chunk_first_log_ns) >= "
             "self._flush_interval_ns):",
             "                or False):",
             REC + "test_chunks_are_time_bounded"),
    Mutation("recorder kill: a killed file reads as truncated", "teleop/record/mcap_scan.py",
             "    except FileEndsEarly as stop:\n        scan.truncated = True",
             "    except ZeroDivisionError as stop:\n        scan.truncated = True",
             REC + "test_killed_recorder_leaves_a_readable_file"),
    Mutation("truncation: read up to the damage", "teleop/record/mcap_scan.py",
             '        raise FileEndsEarly(f"the {Opcode(opcode).name} record at the end is '
             'incomplete "\n                            f"({size - offset - 9} of {length} '
             'bytes)", past_end=True)',
             '        raise McapCorrupt(offset, f"the {Opcode(opcode).name} record at the end is '
             'incomplete "\n                          f"({size - offset - 9} of {length} bytes)")',
             REC + "test_truncated_at_any_byte_reads_up_to_the_damage"),
    # ------------------------------------------------------------------------ bridge faults
    Mutation("wrist jump: limited to hand_max_step_m", "teleop/bridge/faults.py",
             "        self._at_target = step_m <= limit_m", "        self._at_target = True",
             FAULTS + "test_b_a_10_m_wrist_jump_is_limited_not_a_reset"),
    Mutation("instability restored (NaN qvel)", "teleop/bridge/faults.py",
             "        self._restore_scene(self._instability(t0_s, steps), t_s)", "        pass",
             FAULTS + "test_c_an_unstable_simulation_is_restored[nan_qvel]"),
    Mutation("instability restored (base far away)", "teleop/bridge/faults.py",
             "        self._restore_scene(self._instability(t0_s, steps), t_s)", "        pass",
             FAULTS + "test_c_an_unstable_simulation_is_restored[far_base]"),
    # ---------------------------------------------------------------------------- busy ports
    Mutation("busy --listen: refused before loading", "dexaug/commands/teleop.py",
             '    require_free_port("--listen", args.listen)   # before seconds of loading the '
             "hand and scene",
             "    pass",
             CLI + "test_busy_listen_port_is_one_line_before_loading"),
    Mutation("busy --web-port: named in one line", "dexaug/commands/teleop.py",
             '            raise NetworkError(f"--web-port {args.web_port}: {exc}") from None',
             "            pass",
             CLI + "test_busy_web_port_error_is_the_only_line"),
    Mutation("busy --web-port: what it opened is closed", "dexaug/commands/teleop.py",
             "    opened.callback(ingest.close)\n    try:\n        ingest.start()",
             "    try:\n        ingest.start()",
             CLI + "test_busy_web_port_ends_the_bridge_at_once"),
    Mutation("busy dashboard port: reported, not waited out", "dexaug/dashboard/server.py",
             "        except OSError as exc:\n            started.set_exception(exc)",
             "        except OSError as exc:\n            pass",
             CLI + "test_busy_dashboard_port_is_one_line"),
    Mutation("Foxglove server: loopback only", "teleop/bridge/foxglove_live.py",
             "    if not is_loopback(host):\n        raise ValueError(",
             "    if False:\n        raise ValueError(",
             "tests/test_foxglove.py::test_a_host_off_loopback_is_refused_in_one_line_before_loading"),
    # ------------------------------------------------------------------ Ctrl-C ends the workers
    Mutation("Ctrl-C ends FSG's workers", "dexaug/cli.py",
             "        stop_workers()        # their running tasks would hold the exit until "
             "their budget ends",
             "        pass",
             CLI + "test_interrupting_fsg_exits_within_seconds[sigint-main-process]"),
    Mutation("SIGTERM ends FSG's workers", "dexaug/cli.py",
             "    except SystemExit:        # SIGTERM (see _exit_on_sigterm)\n        stop_workers()",
             "    except SystemExit:        # SIGTERM (see _exit_on_sigterm)\n        pass",
             CLI + "test_interrupting_fsg_exits_within_seconds[sigterm-main-process]"),
]


def _python() -> str:
    venv = REPO / ".venv" / "bin" / "python"
    return str(venv) if venv.is_file() else sys.executable


def _copy_tree(dest_parent: Path) -> Path:
    """The repository copied to ``dest_parent/<name>`` with ``shared`` linked beside it."""
    dest = dest_parent / REPO.name
    shutil.copytree(REPO, dest, symlinks=True,
                    ignore=lambda d, names: [n for n in names if n in SKIP or n.endswith(".egg-info")])
    shared = REPO.parent / "shared"
    if shared.exists():
        (dest_parent / "shared").symlink_to(shared.resolve())
    return dest


def _run_pytest(root: Path, nodes: list[str], timeout_s: float, xml: Path
                ) -> dict[str, tuple[str, str]]:
    """Run ``nodes`` in ``root``; each node's (outcome, first line of why it failed or was
    skipped): passed, failed, skipped or missing."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"),
           "DEXAUG_NODE_PREFIX": os.environ.get("DEXAUG_NODE_PREFIX",
                                                str(REPO / ".venv" / "node")),
           "PYTHONDONTWRITEBYTECODE": "1"}
    cmd = [_python(), "-m", "pytest", "-q", "-p", "no:cacheprovider", "--rootdir", str(root),
           f"--timeout={timeout_s:g}", f"--junitxml={xml}", *nodes]
    subprocess.run(cmd, cwd=root, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, timeout=timeout_s * max(1, len(nodes)) + 300)
    outcomes: dict[str, tuple[str, str]] = {}
    if xml.is_file():
        for case in ET.parse(xml).iter("testcase"):
            module = case.get("classname", "").replace(".", "/") + ".py"
            node = f"{module}::{case.get('name')}"
            kids = {child.tag: child for child in case}
            why = next((kids[k].get("message") or "" for k in ("failure", "error", "skipped")
                        if k in kids), "")
            outcomes[node] = ("failed" if kids.keys() & {"failure", "error"}
                              else "skipped" if "skipped" in kids else "passed",
                              " ".join(why.split())[:150])
    return {n: outcomes.get(n, ("missing", "")) for n in nodes}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-k", dest="only", help="only the mutations whose name contains this")
    ap.add_argument("--timeout", type=float, default=180.0,
                    help="pytest-timeout per test, seconds (a hang counts as a failure)")
    ap.add_argument("--keep", action="store_true", help="keep the temporary copies")
    args = ap.parse_args()
    todo = [m for m in MUTATIONS if not args.only or args.only.lower() in m.name.lower()]
    results: dict[Mutation, str] = {}
    for m in todo:   # the real tree is only read
        if (REPO / m.file).read_text().count(m.snippet) != 1:
            results[m] = "not found"
    tmp = Path(tempfile.mkdtemp(prefix="dexaug-mutants-"))
    t0 = time.monotonic()
    try:
        base_root = _copy_tree(tmp / "baseline")
        nodes = sorted({m.test for m in todo if m not in results})
        print(f"baseline: {len(nodes)} tests on an unmutated copy ...", flush=True)
        baseline = _run_pytest(base_root, nodes, args.timeout, tmp / "baseline.xml")
        for m in todo:
            if m in results:
                continue
            if baseline[m.test][0] != "passed":
                results[m] = f"baseline {baseline[m.test][0]}"
                print(f"  {results[m]:<9} {m.name}: {baseline[m.test][1]}", flush=True)
                continue
            work = tmp / f"m{todo.index(m):02d}"
            root = _copy_tree(work)
            target = root / m.file
            target.write_text(target.read_text().replace(m.snippet, m.replacement))
            outcome, why = _run_pytest(root, [m.test], args.timeout, work / "result.xml")[m.test]
            results[m] = {"failed": "killed", "passed": "SURVIVED"}.get(outcome, outcome)
            print(f"  {results[m]:<9} {m.name}" + (f" — {why}" if why else ""), flush=True)
            if not args.keep:
                shutil.rmtree(work, ignore_errors=True)
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            print(f"copies kept in {tmp}")
    width = max(len(m.name) for m in todo)
    print(f"\n{'guard':<{width}}  {'result':<16}  test")
    print(f"{'-' * width}  {'-' * 16}  {'-' * 4}")
    for m in todo:
        print(f"{m.name:<{width}}  {results[m]:<16}  {m.test}")
    bad = [m for m in todo if results[m] != "killed"]
    print(f"\n{len(todo) - len(bad)} of {len(todo)} mutations killed in "
          f"{time.monotonic() - t0:.0f} s" + (f"; not killed: {len(bad)}" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
