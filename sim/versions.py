"""The versions of the packages and of the code a result depends on, for provenance.

Why: a dataset or a benchmark row is only comparable with another made by the same simulator
and libraries (MuJoCo's contact solver changes between releases; DexGraspBench's verdicts were
made with MuJoCo 3.3.2) and by the same dexaug code (a fix to the validator changes verdicts
without changing any package version). Package versions are read from the installed
distributions' metadata, so nothing is imported to find them; the code version is the git
commit of the checkout the code runs from, or the installed version where there is none.
"""

from __future__ import annotations

import subprocess
from functools import cache
from importlib import metadata
from pathlib import Path

__all__ = ["PACKAGES", "code_version", "describe_code_version", "package_versions"]

#: distribution names whose versions a result records (missing ones are left out): everything
#: that shapes a grasp or a recording — the simulator and IK (mujoco, mink and its QP solvers),
#: the numerics (numpy, scipy; highspy solves the holding LPs), meshes (trimesh), the data files
#: (h5py, mcap, foxglove-sdk writes the sessions) and the transport (eclipse-zenoh)
PACKAGES = ("dexaug", "mujoco", "mink", "qpsolvers", "daqp", "numpy", "scipy", "highspy",
            "trimesh", "h5py", "mcap", "foxglove-sdk", "eclipse-zenoh")
#: the checkout this module runs from (sim/ is one level below it)
_CODE_ROOT = Path(__file__).resolve().parent.parent
_GIT_TIMEOUT_S = 5.0


def package_versions(packages: tuple[str, ...] = PACKAGES) -> dict[str, str]:
    """Distribution name → installed version, for those of ``packages`` that are installed."""
    out: dict[str, str] = {}
    for name in packages:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def _git(root: Path, *args: str) -> str | None:
    """``git -C root args`` stdout, stripped; None when git is missing, fails or hangs (the
    code version must never stop a result from being written)."""
    try:
        proc = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                              timeout=_GIT_TIMEOUT_S, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return proc.stdout.strip() if proc.returncode == 0 else None


def _git_version(root: Path) -> dict[str, str | bool] | None:
    """Commit and dirtiness of ``root`` when it is the top of a git checkout (not merely inside
    one: an installed copy under some other repository must not claim that repository's
    commit)."""
    top = _git(root, "rev-parse", "--show-toplevel")
    if top is None or Path(top).resolve() != root.resolve():
        return None
    commit = _git(root, "rev-parse", "HEAD")
    status = _git(root, "status", "--porcelain")   # untracked files count: a new module does
    if commit is None or status is None:
        return None
    return {"source": "git", "commit": commit, "dirty": bool(status)}


@cache
def _code_version(root: Path) -> dict[str, str | bool]:
    found = _git_version(root)
    if found is not None:
        return found
    return {"source": "package", "version": package_versions(("dexaug",)).get("dexaug", "unknown")}


def code_version(root: Path = _CODE_ROOT) -> dict[str, str | bool]:
    """What code made a result: ``{"source": "git", "commit", "dirty"}`` for a git checkout
    (dirty: tracked changes or untracked files not ignored), else ``{"source": "package",
    "version"}`` (the installed dexaug, "unknown" when not installed). Computed once per
    process and root (three git calls, ~10 ms); never raises. A copy: callers may change it."""
    return dict(_code_version(root))


def describe_code_version(version: object) -> str:
    """A :func:`code_version` in words ("dexaug at 6a0be9cf07 (dirty)", "dexaug 0.1.0"); for
    anything else (a result made before it was recorded) "unrecorded code"."""
    if not isinstance(version, dict):
        return "unrecorded code"
    if version.get("source") == "git":
        dirty = " (dirty)" if version.get("dirty") else ""
        return f"dexaug at {str(version.get('commit'))[:10]}{dirty}"
    return f"dexaug {version.get('version')}"
