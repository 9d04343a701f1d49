"""What an untrusted caller of the bridge's control may ask for (:mod:`teleop.bridge.control`).

Why a module of its own: these checks are the bridge's security boundary — a query on the
zenoh queryable or a request forwarded from the headset page names a recording (``name``,
reduced to a plain file name inside the recordings folder, never over an existing file), an
object of the installed catalogue, a resting pose or a calibration time, and nothing else —
so they are read and tested apart from the command handlers. Each raises ValueError with a
one-line message naming what is refused.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from sim.world.objects import one_line, ycb_folders
from sim.world.primitives import PRIMITIVES
from teleop.bridge.object_mode import rest_request

__all__ = ["MAX_CALIBRATION_S", "calibration_seconds", "installed_object", "recording_file",
           "remote_args"]

_OBJECT_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,99}")
_NAME_MAX_CHARS = 100
_MAX_SUFFIX = 1000


def installed_object(name: object) -> str:
    """``name`` if it is an object id of the installed catalogue: a primitive, a YCB folder
    (``004_sugar_box``) or its unique id/name (``004``, ``sugar_box``); ValueError otherwise,
    before any file is opened."""
    text = str(name)
    if not _OBJECT_ID.fullmatch(text):
        raise ValueError(f"choose_object: object {one_line(text)[:80]!r} is not an object id "
                         "(letters, digits, '_', '-'); a remote caller picks from the installed "
                         "catalogue, never a file")
    if text in PRIMITIVES:
        return text
    folders = [f.name for f in ycb_folders()]
    matches = [f for f in folders if f == text or f.startswith(f"{text}_") or f[4:] == text]
    if text in folders or len(matches) == 1:
        return text
    raise ValueError(f"choose_object: {text!r} is not an installed object (primitives: "
                     f"{', '.join(PRIMITIVES)}; {len(folders)} YCB objects"
                     f"{' (ambiguous: ' + ', '.join(matches) + ')' if matches else ''})")


def remote_args(command: str, args: dict[str, Any]) -> dict[str, Any]:
    """The arguments of an untrusted (zenoh) call of ``command``, checked (module docstring);
    ValueError names what is refused."""
    if command == "start_recording":
        refused = sorted(k for k in args if k != "name")
        if refused:
            raise ValueError(f"start_recording: {refused} not accepted from a remote caller; "
                             "pass a 'name' (the file goes into the recordings folder, never "
                             "over an existing one)")
        if "name" in args and not isinstance(args["name"], str):
            raise ValueError("start_recording: 'name' must be a string")
    elif command == "choose_object":
        args = {**args, "object": installed_object(args.get("object"))}
        rest_request(command, args)
    elif command == "set_object_rest":
        rest_request(command, args, only_rest=True)
    elif command == "recalibrate_scale":
        calibration_seconds(args)
    return args


#: the longest scale calibration a control may ask for (seconds of tracking)
MAX_CALIBRATION_S = 10.0


def calibration_seconds(args: dict[str, Any]) -> float | None:
    """``duration_s`` of a ``recalibrate_scale`` call (None: the config's ``calibration_s``),
    checked: a finite number in (0, :data:`MAX_CALIBRATION_S`]; no other argument."""
    refused = sorted(k for k in args if k != "duration_s")
    if refused:
        raise ValueError(f"recalibrate_scale: {refused} not accepted; only 'duration_s'")
    d = args.get("duration_s")
    if d is None:
        return None
    if isinstance(d, bool) or not isinstance(d, (int, float)) or not 0 < d <= MAX_CALIBRATION_S:
        raise ValueError(f"recalibrate_scale: duration_s must be a number of seconds in (0, "
                         f"{MAX_CALIBRATION_S:g}], got {d!r}")
    return float(d)


def recording_file(folder: Path, name: str) -> Path:
    """A new ``.mcap`` file in ``folder`` named after ``name`` reduced to a plain file name
    (directories dropped, characters other than letters, digits, ``.``, ``_``, ``-`` replaced,
    no leading dot, at most 100 characters); ``_2``, ``_3``… is added while the name is taken."""
    base = Path(name.replace("\\", "/")).name
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", base).lstrip(".")
    stem = stem[:-len(".mcap")] if stem.lower().endswith(".mcap") else stem
    stem = stem[:_NAME_MAX_CHARS].rstrip(".")
    if not stem:
        raise ValueError(f"start_recording: name {one_line(name)[:80]!r} has no usable file name "
                         "characters (letters, digits, '.', '_', '-')")
    for k in range(1, _MAX_SUFFIX + 1):
        path = folder / (f"{stem}.mcap" if k == 1 else f"{stem}_{k}.mcap")
        if not path.exists() and not path.is_symlink():
            return path
    raise ValueError(f"start_recording: {folder}: {stem}.mcap and {_MAX_SUFFIX - 1} suffixed "
                     "names are taken")
