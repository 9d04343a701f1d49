"""One JSON record per benchmark run (:func:`write_record`), under ``benchmarks/measured/``.

Why: a figure in the README or a closing note is only worth what can be traced back to the
run that made it — which code (commit, and whether the checkout had uncommitted changes),
which machine (CPU model, cores, memory, GPU), which package versions (MuJoCo's contact solver
changes verdicts between releases), which assets (SHA-256 of the hand and object files,
:func:`sim.provenance.asset_hashes`), the exact command line, and the rows themselves. Every
benchmark writes its result through this one helper so that records have one shape:

    {"benchmark", "created_utc", "command", "code", "machine", "packages", "config",
     "assets", "rows", "summary"}

Records are written atomically (:func:`sim.io.write_bytes_atomic`): a run killed while writing
leaves the previous records intact and no half file. Each run gets its own file,
``benchmarks/measured/<benchmark>/<UTC time>-<commit[:10]>.json``, so records accumulate and
nothing is overwritten; ``--record-dir`` style overrides pass ``out_dir``, and the environment
variable ``DEXAUG_RECORD_DIR`` (:data:`RECORD_DIR_ENV`) moves every record of a process tree to
``$DEXAUG_RECORD_DIR/<benchmark>/``: ``benchmarks/headline.py run --quick`` sends its CI-size runs
there so that they never become the newest record of a headline figure.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import shlex
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sim.io import write_bytes_atomic
from sim.provenance import asset_hashes
from sim.versions import PACKAGES, code_version, package_versions

__all__ = ["MEASURED_DIR", "RECORD_DIR_ENV", "machine", "write_record"]

#: where records live: one folder per benchmark
MEASURED_DIR = Path(__file__).resolve().parent / "measured"
#: environment variable: a folder that replaces :data:`MEASURED_DIR` (scratch runs)
RECORD_DIR_ENV = "DEXAUG_RECORD_DIR"
#: packages beyond :data:`sim.versions.PACKAGES` that shape benchmark results
_EXTRA_PACKAGES = ("foxglove-sdk", "trimesh", "highspy", "mujoco-warp", "ray", "warp-lang")


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gib() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return round(int(line.split()[1]) / 2**20, 1)
    except (OSError, ValueError, IndexError):
        pass
    return None


def _gpus() -> list[str]:
    """GPU names from ``nvidia-smi`` when it is there (none on the CPU machines)."""
    import shutil
    import subprocess

    exe = shutil.which("nvidia-smi")
    if exe is None:
        return []
    try:
        out = subprocess.run([exe, "--query-gpu=name", "--format=csv,noheader"],
                             capture_output=True, text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return []
    return [g.strip() for g in out.stdout.splitlines() if g.strip()]


def machine() -> dict[str, Any]:
    """The machine a run is on: host name, OS, Python, CPU model, cores usable by this
    process, memory (GiB) and GPUs."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {"host": platform.node(), "os": platform.platform(), "python": platform.python_version(),
            "cpu": _cpu_model(), "cores": cores, "memory_gib": _memory_gib(), "gpus": _gpus()}


def _plain(v: Any) -> Any:
    """JSON-ready copy of ``v`` (NumPy scalars and arrays, paths, tuples, sets)."""
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, np.ndarray):
        return _plain(v.tolist())
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, (list, tuple, set, frozenset)):
        return [_plain(x) for x in (sorted(v) if isinstance(v, (set, frozenset)) else v)]
    if isinstance(v, float) and not np.isfinite(v):
        return None
    return v


def write_record(benchmark: str, rows: Sequence[Mapping[str, Any]], *,
                 summary: Mapping[str, Any] | None = None,
                 config: Mapping[str, Any] | None = None,
                 hand: str | None = None, objects: Iterable[str] = (),
                 argv: Sequence[str] | None = None, out_dir: Path | str | None = None) -> Path:
    """Write one run of ``benchmark`` (a folder name: letters, digits, ``_``, ``-``) with its
    ``rows`` and ``summary`` (the figures a reader quotes), the ``config`` it ran under, and the
    SHA-256 of ``hand``'s files and each of ``objects``'; returns the record's path.

    ``argv`` defaults to this process's command line; the folder is ``out_dir``, else
    ``$DEXAUG_RECORD_DIR/<benchmark>``, else ``benchmarks/measured/<benchmark>``. NaN and
    infinities are written as null (JSON has none)."""
    if not benchmark or not all(c.isalnum() or c in "_-" for c in benchmark):
        raise ValueError(f"benchmark name {benchmark!r}: expected letters, digits, '_' or '-'")
    code = code_version()
    assets = asset_hashes(hand, None)
    for obj in objects:
        assets.update(asset_hashes(None, obj))
    now = _dt.datetime.now(_dt.UTC)
    record = {
        "benchmark": benchmark,
        "created_utc": now.isoformat(timespec="seconds"),
        "command": shlex.join([Path(sys.executable).name, *(sys.argv if argv is None else argv)]),
        "code": code,
        "machine": machine(),
        "packages": package_versions((*PACKAGES, *_EXTRA_PACKAGES)),
        "config": _plain(dict(config or {})),
        "assets": assets,
        "rows": _plain([dict(r) for r in rows]),
        "summary": _plain(dict(summary or {})),
    }
    root = Path(os.environ[RECORD_DIR_ENV]) if os.environ.get(RECORD_DIR_ENV) else MEASURED_DIR
    folder = Path(out_dir) if out_dir is not None else root / benchmark
    stem = now.strftime("%Y%m%dT%H%M%SZ") + "-" + str(code.get("commit", code.get("version")))[:10]
    path = folder / f"{stem}.json"
    k = 1
    while path.exists():
        path, k = folder / f"{stem}-{k}.json", k + 1
    folder.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, (json.dumps(record, indent=1, allow_nan=False) + "\n").encode())
    return path
