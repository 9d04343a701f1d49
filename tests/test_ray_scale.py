"""Scale-out on Ray: a real local cluster on loopback (two worker CPUs) runs demos and objects as
tasks and writes the same datasets as the local process pool for a fixed seed; a worker killed
with SIGKILL in the middle of a task is recovered (the task reruns, no row lost or doubled);
every server of the cluster listens on loopback only; an unreachable cluster address is one
line. Skipped where Ray is not installed (``pip install 'dexaug[ray]'``; ``make test`` installs it).
"""

from __future__ import annotations

import builtins
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import HANG_S, needs_ycb

ray = pytest.importorskip("ray")

from augment import dataset  # noqa: E402
from dexaug.cli import main  # noqa: E402
from dexaug.pipeline.options import AugmentOptions  # noqa: E402
from dexaug.scale.ray_cluster import ray_cluster  # noqa: E402
from dexaug.scale.ray_jobs import run_on_ray  # noqa: E402
from dexaug.scale.units import Unit, gather_units, run_local  # noqa: E402
from sim.hand.config import default_hand_name  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DEMO = REPO / "recordings" / "demos" / "005_tomato_soup_can.json"
OPTS = AugmentOptions(n=10, seed=3, workers=1, gallery=0, validate="lift-drop")

pytestmark = [pytest.mark.slow, needs_ycb, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def cluster() -> Iterator[object]:
    """One local cluster for the module, started as ``--ray`` starts it (two worker CPUs);
    afterwards the process's ``print`` is its own again (Ray's driver replaces it)."""
    before = builtins.print
    with ray_cluster(num_cpus=2) as r:
        yield r
    assert builtins.print is before, builtins.print


def _units() -> list[Unit]:
    units, errors = gather_units([DEMO], OPTS, objects=["062_dice"], hand=default_hand_name())
    assert not errors
    return [units[0], replace(units[1], opts=replace(units[1].opts, n=6))]


def _tables(folder: Path) -> dict[str, dataset.ObjectTable]:
    """Every unit's table in ``folder``, passing grasps then rejected ones."""
    out = {}
    for sub in sorted(folder.iterdir()):
        (table,) = dataset.load(sub / "grasps.h5").values()
        out[sub.name] = dataset.with_rejected(table)
    return out


@pytest.fixture(scope="module")
def local_tables(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dataset.ObjectTable]:
    """The reference: the same units on the local path, this process."""
    out = tmp_path_factory.mktemp("local")
    for unit in _units():
        run_local(unit, out)
    return _tables(out)


def _assert_same(a: dict[str, dataset.ObjectTable], b: dict[str, dataset.ObjectTable]) -> None:
    assert a.keys() == b.keys()
    for name in a:
        ta, tb = a[name], b[name]
        assert ta.columns.keys() == tb.columns.keys(), name
        for col, x in ta.columns.items():
            y = tb.columns[col]
            if x.dtype.kind == "f":
                assert np.array_equal(x, y, equal_nan=True), (name, col)
            else:
                assert np.array_equal(x, y), (name, col)


def test_ray_writes_the_local_datasets(cluster: object, tmp_path: Path,
                                       local_tables: dict[str, dataset.ObjectTable]) -> None:
    outcomes = run_on_ray(_units(), tmp_path, chunk=3)
    assert all(o.error is None for o in outcomes), [o.error for o in outcomes]
    got = _tables(tmp_path)
    assert {len(t) for t in got.values()} == {10, 6}
    assert sum(o.summary.passed for o in outcomes) > 0
    _assert_same(local_tables, got)
    # the check can fail: another seed gives other grasps
    other = tmp_path.parent / (tmp_path.name + "_seed")
    run_on_ray([replace(_units()[1], opts=replace(_units()[1].opts, seed=4))], other, chunk=3)
    (name,) = (n for n in got if n.endswith("@manual"))
    assert not np.array_equal(_tables(other)[name]["hand_pose"], got[name]["hand_pose"])


def _ray_tasks() -> dict[int, str]:
    """Processes running one of our tasks now: pid → Ray's process title (``ray::fsg_task``)."""
    found = {}
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            title = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[0].decode()
        except (OSError, UnicodeDecodeError):
            continue
        if title in ("ray::fsg_task", "ray::validate_chunk"):
            found[int(pid)] = title
    return found


def test_a_killed_worker_is_recovered(cluster: object, tmp_path: Path,
                                      local_tables: dict[str, dataset.ObjectTable]) -> None:
    """SIGKILL the first worker seen running FSG and the first seen validating: Ray reruns
    both tasks and the datasets are complete, without duplicates, and equal the local ones."""
    killed: dict[str, int] = {}
    stop = threading.Event()

    def killer() -> None:
        while not stop.is_set() and len(killed) < 2:
            for pid, title in _ray_tasks().items():
                if title not in killed:
                    os.kill(pid, signal.SIGKILL)
                    killed[title] = pid
            time.sleep(0.01)

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    try:
        outcomes = run_on_ray(_units(), tmp_path, chunk=5)
    finally:
        stop.set()
        thread.join()
    assert set(killed) == {"ray::fsg_task", "ray::validate_chunk"}, killed
    for pid in killed.values():   # really gone, not only signalled
        assert not Path(f"/proc/{pid}/cmdline").exists() or not Path(f"/proc/{pid}/cmdline").read_bytes()
    assert all(o.error is None for o in outcomes), [o.error for o in outcomes]
    got = _tables(tmp_path)
    for name, table in got.items():
        rows = {np.hstack([table["palm_pose"][i], table["hand_pose"][i]]).tobytes()
                for i in range(len(table))}
        assert len(rows) == len(table), f"{name}: duplicated rows"
    _assert_same(local_tables, got)


def test_augment_cli_runs_on_ray(cluster: object, tmp_path: Path) -> None:
    """``dexaug augment DEMO --ray``: the command's own path, its folder and summary."""
    code = main(["augment", str(DEMO), "--ray", "--n", "4", "--gallery", "0", "--seed", "3",
                 "--out", str(tmp_path)])
    assert code == 0
    (folder,) = tmp_path.iterdir()
    assert (folder / "summary.json").is_file()
    assert len(dataset.with_rejected(next(iter(dataset.load(folder / "grasps.h5").values())))) == 4


def _listening_inodes() -> dict[str, str]:
    """Socket inode → local address (hex, as the kernel writes it) of every listening TCP socket."""
    rows = {}
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            parts = line.split()
            if parts[3] == "0A":   # LISTEN
                rows[parts[9]] = parts[1]
    return rows


def _descendants(root: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                ppid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            children.setdefault(ppid, []).append(int(pid))
    out, stack = [], [root]
    while stack:
        pid = stack.pop()
        out.append(pid)
        stack.extend(children.get(pid, []))
    return out


LOOPBACK = ("0100007F:", "0000000000000000FFFF00000100007F:", "00000000000000000000000001000000:")


def test_the_local_cluster_listens_on_loopback_only(cluster: object) -> None:
    listening = _listening_inodes()
    seen = []
    for pid in _descendants(os.getpid()):
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                link = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if link.startswith("socket:[") and (addr := listening.get(link[8:-1])):
                seen.append((pid, addr))
    assert len(seen) >= 3, seen   # GCS, raylet, workers at least
    assert all(addr.startswith(LOOPBACK) for _, addr in seen), seen


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_address_is_one_line(tmp_path: Path) -> None:
    address = f"127.0.0.1:{_free_port()}"
    proc = subprocess.run([sys.executable, "-m", "dexaug", "batch", str(DEMO), "--ray", address,
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=HANG_S,
                          cwd=REPO, stdin=subprocess.DEVNULL)
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert address in lines[0] and "Ray" in lines[0], lines[0]
    # refused by dexaug's own connection probe, before ray.init's minute of retries: the
    # probe's words (ray.init's failure reads "cannot start or reach the Ray cluster …")
    assert f"cannot reach the Ray cluster at {address}: Connection refused" in lines[0], lines[0]
    assert not any(tmp_path.iterdir())   # nothing written
