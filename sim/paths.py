"""Where assets and configs live.

Assets are never copied into the repository: they are found through environment variables,
defaulting to ``../shared/assets`` beside the checkout when that folder exists. The defaults are
applied once, here, so every entry point (CLI, tests, worker processes) resolves the same files.
"""

from __future__ import annotations

import os
from pathlib import Path

from sim.errors import AssetError

REPO_ROOT = Path(__file__).resolve().parent.parent
CONFIG_DIR = REPO_ROOT / "configs"
SHARED_ASSETS = REPO_ROOT.parent / "shared" / "assets"

MENAGERIE_ENV = "MENAGERIE_ROOT"
YCB_ENV = "DEXAUG_YCB_ROOT"
CACHE_ENV = "DEXAUG_CACHE_DIR"


def _default_root(env: str, relative: str) -> Path | None:
    value = os.environ.get(env)
    if value:
        return Path(value).expanduser()
    candidate = SHARED_ASSETS / relative
    return candidate if candidate.is_dir() else None


def ensure_menagerie_root() -> Path | None:
    """Point ``mujoco_menagerie`` at ``../shared/assets/menagerie`` unless the user chose a root.

    Without a root the package downloads models, which fails offline; setting the variable in
    ``os.environ`` also carries it into worker processes.
    """
    root = _default_root(MENAGERIE_ENV, "menagerie")
    if root is not None:
        if not root.is_dir():
            raise AssetError(f"{MENAGERIE_ENV}={root} is not a directory (expected a MuJoCo "
                             "Menagerie checkout with one folder per robot)")
        os.environ[MENAGERIE_ENV] = str(root)
    return root


def ycb_root(required: bool = True) -> Path | None:
    """The YCB object root (``$DEXAUG_YCB_ROOT`` or ``../shared/assets/ycb``)."""
    root = _default_root(YCB_ENV, "ycb")
    if root is None or not root.is_dir():
        if required:
            where = f"{YCB_ENV}={root}" if root else f"{YCB_ENV} is unset and {SHARED_ASSETS / 'ycb'}"
            raise AssetError(f"YCB object root not found: {where} is not a directory; set "
                             f"{YCB_ENV} to a folder holding <id>_<name>/<name>.xml objects")
        return None
    return root


def cache_dir() -> Path:
    """Disk cache for derived data (workspace clouds, object clouds); ``$DEXAUG_CACHE_DIR`` or
    ``~/.cache/dexaug``."""
    path = Path(os.environ.get(CACHE_ENV, Path.home() / ".cache" / "dexaug")).expanduser()
    path.mkdir(parents=True, exist_ok=True)
    return path
