"""Checks the commands make before any work, and the hints their errors carry.

Why here, not in the libraries: each one is about the command line a person typed (an output
that cannot be written, a mistyped object name, a path that is not a dataset) and is answered
before seconds of loading, searching or validating are spent; the libraries keep their own
errors for callers that do not come through the CLI.

- :func:`require_writable`: an output file or folder that cannot be created or written is a
  :class:`~sim.errors.UsageError` (exit status 2, like every input the user must change),
  raised by every command that writes results before its expensive step.
- :func:`object_name`: the argparse type of ``--object``: a name that is no primitive and no
  YCB object, but close to some, is refused while parsing with "did you mean" (``difflib``).
- :func:`dataset_file`: the argparse type of a dataset argument: a directory, a missing file or
  one that is not HDF5 is one line naming the path and what was expected.
- :func:`error_hint`: a damaged session's error ends with the command that salvages it.
"""

from __future__ import annotations

import argparse
import difflib
import os
import re
import tempfile
from collections.abc import Iterable
from pathlib import Path

from sim.errors import UsageError

__all__ = ["dataset_file", "did_you_mean", "error_hint", "object_name", "require_new_or_dataset",
           "require_writable"]


# ------------------------------------------------------------------------------ outputs

def require_writable(path: Path | str, option: str = "--out", *, folder: bool = False) -> None:
    """Refuse (:class:`UsageError`, one line naming ``option`` and ``path``) an output this
    process cannot write: ``path`` is a file to write (``folder``: a folder to write into),
    created with its missing parent folders as the commands do. The nearest existing folder on
    the way is tried by creating (and removing) a temporary file in it, which is what the
    write will do: permissions, a read-only file system and a file where a folder belongs all
    show there, for root too. Nothing is left behind."""
    path = Path(path)
    if folder and path.exists() and not path.is_dir():
        raise UsageError(f"{option} {path}: cannot write there: it is a file, expected a folder")
    if not folder and path.is_dir():
        raise UsageError(f"{option} {path}: cannot write there: it is a folder, expected a "
                         "file name")
    if not folder and path.exists() and not os.access(path, os.W_OK):
        raise UsageError(f"{option} {path}: cannot write there: the file is read-only")
    start = path if folder else path.parent
    existing = start
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UsageError(f"{option} {path}: cannot write there: {existing} is a file, not a "
                         "folder")
    try:
        with tempfile.NamedTemporaryFile(dir=existing, prefix=".dexaug-write-check."):
            pass
    except OSError as exc:
        why = exc.strerror or str(exc)
        raise UsageError(f"{option} {path}: cannot write there: {existing} refuses new files "
                         f"({why})") from None


# ------------------------------------------------------------------------------ objects

def did_you_mean(name: str, choices: Iterable[str]) -> str:
    """``"; did you mean 'X'?"`` (or ``'X' or 'Y'``) for the choices close to ``name``
    (``difflib.get_close_matches``), or ``""``."""
    close = difflib.get_close_matches(name, sorted(set(choices)), n=3, cutoff=0.6)
    if not close:
        return ""
    return "; did you mean " + " or ".join(repr(c) for c in close) + "?"


def _ycb_folder_names() -> list[str]:
    from sim.paths import ycb_root

    root = ycb_root(required=False)
    if root is None:
        return []
    return sorted(p.name for p in root.iterdir() if p.is_dir() and p.name[:3].isdigit())


def object_name(text: str) -> str:
    """An object as ``load_object`` takes it (primitive, YCB folder name, unique id or name,
    or a path), returned unchanged; only a name that matches nothing but is close to known
    ones is refused here, with "did you mean". Anything else (a path, an ambiguous id, no YCB
    objects at all) is left for ``load_object`` to accept or explain."""
    from sim.world.primitives import PRIMITIVES

    if text in PRIMITIVES or "/" in text or text.endswith(".xml") or Path(text).exists():
        return text
    folders = _ycb_folder_names()
    if any(f == text or f.startswith(f"{text}_") or f[4:] == text for f in folders):
        return text
    hint = did_you_mean(text, [*PRIMITIVES, *folders, *(f[4:] for f in folders)])
    if hint:
        raise argparse.ArgumentTypeError(f"unknown object {text!r}{hint}")
    return text


# ------------------------------------------------------------------------------ datasets

#: what a dataset argument is expected to be, in every message about one
_DATASET = "expected a grasp dataset .h5 file (written by dexaug augment or generate)"


def dataset_file(text: str) -> Path:
    """A grasp dataset to read: an existing HDF5 file. A directory, a missing path or another
    kind of file is refused while parsing, with the path and what was expected (no h5py
    message: its "Unable to synchronously open file" says nothing to a user)."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{path}: is a directory, {_DATASET}")
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{path}: no such file, {_DATASET}")
    import h5py

    try:
        hdf5 = h5py.is_hdf5(path)
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{path}: cannot be read ({exc.strerror or exc}), "
                                         f"{_DATASET}") from None
    if not hdf5:
        raise argparse.ArgumentTypeError(f"{path}: not an HDF5 file, {_DATASET}")
    return path


def require_new_or_dataset(path: Path, option: str = "--out") -> None:
    """An output dataset that is added to when it exists: a new path, or a grasp dataset
    (:func:`dataset_file`); UsageError naming ``option`` otherwise."""
    if path.exists():
        try:
            dataset_file(str(path))
        except argparse.ArgumentTypeError as exc:
            raise UsageError(f"{option} {exc}") from None


# ------------------------------------------------------------------------------ hints

#: a session the reader found damaged (teleop.record.session): ``<path>: corrupt MCAP session``
_CORRUPT_SESSION = re.compile(r"(?P<path>\S.*?): corrupt MCAP session at offset")


def error_hint(message: str) -> str:
    """``message`` with what to do next when there is a command for it: a damaged session
    gets ``dexaug repair <file>``, which writes a readable copy of every intact record."""
    m = _CORRUPT_SESSION.search(message)
    if m and "dexaug repair" not in message:
        return (f"{message}; `dexaug repair {m['path']}` writes a readable copy of every "
                "intact record")
    return message
