"""SHA-256 hashes of the asset files a result was made from (the hand's model, the object), for
provenance.

Why: package versions and the code version do not cover the assets, which live outside the
repository (Menagerie, YCB) and can change under a dataset — a re-exported mesh or an edited
MJCF changes contacts and verdicts with no version changing. A file is named by its path
relative to the asset root it was found under, with the root's label in front
(``ycb:005_tomato_soup_can/tomato_soup_can.xml``), so a dataset made on another machine, with
its roots elsewhere, is still checked file by file against the roots here.

Cheap by design: the files of a hand or an object are listed once per process (and asset
roots), and each file is hashed once while its size and modification time stay the same (a
stat per file afterwards). Textures are left out: they change pictures, not grasps.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from sim.errors import DexaugError
from sim.paths import MENAGERIE_ENV, REPO_ROOT, SHARED_ASSETS, YCB_ENV, ensure_menagerie_root, ycb_root
from sim.versions import code_version, package_versions

__all__ = ["APPENDED", "PROVENANCE", "AssetChange", "as_recorded", "asset_hashes", "asset_roots",
           "changed_assets", "decoded", "file_sha256", "merged_attrs", "plain",
           "recorded_changes", "stamped"]

log = logging.getLogger(__name__)

#: the attributes of a result that say what made it; :func:`stamped` adds those it lacks
PROVENANCE = ("versions", "code_version", "asset_sha256")
#: attribute listing rows added later under other attributes (:func:`merged_attrs`)
APPENDED = "appended"
#: a provenance attribute of a result made before the attribute existed: not known, and never
#: to be filled in by whoever rewrites the result
UNRECORDED = "unrecorded"

#: resolved path → (size, mtime_ns, sha256): a file is hashed again only when it changed
_HASHES: dict[str, tuple[int, int, str]] = {}


@dataclass(frozen=True)
class AssetChange:
    """One asset file of a dataset table that differs from the file here now. ``recorded``
    None: the table holds no asset hashes (written before they existed); ``current`` None: the
    file (or its asset root) is missing here."""

    table: str
    file: str
    recorded: str | None
    current: str | None

    @property
    def reason(self) -> str:
        if self.recorded is None:
            return "not recorded"
        return "missing" if self.current is None else "changed"

    def __str__(self) -> str:
        return f"{self.table}: {self.file or 'asset hashes'} {self.reason}"


def asset_roots() -> dict[str, Path]:
    """Label → asset root, as this process resolves them (the environment variables of
    :mod:`sim.paths`); roots that do not exist here are left out."""
    try:
        menagerie = ensure_menagerie_root()
    except DexaugError:
        menagerie = None
    roots = {"menagerie": menagerie, "ycb": ycb_root(required=False), "shared": SHARED_ASSETS,
             "repo": REPO_ROOT}
    return {k: v.resolve() for k, v in roots.items() if v is not None and v.is_dir()}


def _key(path: Path, roots: Mapping[str, Path]) -> str:
    """``label:relative/path`` under the deepest root holding ``path``; else the absolute path."""
    holding = [(len(r.parts), label, r) for label, r in roots.items() if path.is_relative_to(r)]
    if not holding:
        return str(path)
    _, label, root = max(holding)
    return f"{label}:{path.relative_to(root).as_posix()}"


def _resolve(key: str, roots: Mapping[str, Path]) -> Path | None:
    """The file a :func:`_key` names here; None when its root is not here."""
    label, sep, rel = key.partition(":")
    if sep and label in roots:
        return roots[label] / rel
    return Path(key) if Path(key).is_absolute() else None


def file_sha256(path: Path) -> str:
    """SHA-256 of ``path`` (hex), hashed once while its size and mtime stay the same."""
    st = path.stat()
    cached = _HASHES.get(str(path))
    if cached is not None and cached[:2] == (st.st_size, st.st_mtime_ns):
        return cached[2]
    with path.open("rb") as f:
        digest = hashlib.file_digest(f, "sha256").hexdigest()
    _HASHES[str(path)] = (st.st_size, st.st_mtime_ns, digest)
    return digest


def _includes(xml: Path) -> list[Path]:
    """The files ``<include>``d by an MJCF file, recursively (relative to its folder)."""
    out = []
    for node in ET.parse(xml).iter("include"):
        inc = (xml.parent / node.get("file", "")).resolve()
        if inc.is_file():
            out += [inc, *_includes(inc)]
    return out


def mjcf_files(xml: Path) -> list[Path]:
    """An MJCF file, the files it includes, and its mesh, height-field and skin files (not
    textures). Parsed by MuJoCo without loading any asset (~1 ms)."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(xml))
    meshdir = xml.parent / spec.meshdir
    named = [a.file for a in (*spec.meshes, *spec.hfields, *spec.skins) if a.file]
    return [xml.resolve(), *_includes(xml), *((meshdir / f).resolve() for f in named)]


@lru_cache(maxsize=256)
def _hand_files(hand: str, _menagerie_env: str | None) -> tuple[Path, ...]:
    """The model files of hand ``hand`` (its MJCF and meshes), once per name and Menagerie root;
    none when the hand cannot be resolved (a result's provenance never stops it being written)."""
    from sim.hand.config import load_hand_config
    from sim.hand.model import hand_model_path

    try:
        return tuple(mjcf_files(hand_model_path(load_hand_config(hand))))
    except (DexaugError, ValueError, OSError, ET.ParseError) as exc:
        log.debug("no asset hashes for hand %r: %s", hand, exc)
        return ()


@lru_cache(maxsize=256)
def _object_files(obj: str, _ycb_env: str | None) -> tuple[Path, ...]:
    """The files of object ``obj`` (its XML and meshes; none for a primitive, which is code),
    once per name and YCB root; none when the object cannot be resolved."""
    from sim.world.objects import load_object

    try:
        path = load_object(obj).path
        return tuple(mjcf_files(path)) if path is not None else ()
    except (DexaugError, ValueError, OSError, ET.ParseError) as exc:
        log.debug("no asset hashes for object %r: %s", obj, exc)
        return ()


def asset_hashes(hand: str | None, obj: str | None) -> dict[str, str]:
    """``label:relative path`` → SHA-256 of every file of ``hand``'s model and of object ``obj``
    that exists here (sorted); what cannot be resolved (an unknown name) is left out."""
    files: list[Path] = []
    if hand:
        files += _hand_files(hand, os.environ.get(MENAGERIE_ENV))
    if obj:
        files += _object_files(obj, os.environ.get(YCB_ENV))
    roots = asset_roots()
    return dict(sorted((_key(p, roots), file_sha256(p)) for p in set(files) if p.is_file()))


def changed_assets(recorded: Mapping[str, str] | None, table: str = "") -> list[AssetChange]:
    """The files of ``recorded`` (an :func:`asset_hashes` result) whose file here now has
    another hash or is missing; one "not recorded" change when ``recorded`` is None."""
    if recorded is None:
        return [AssetChange(table, "", None, None)]
    roots = asset_roots()
    out = []
    for key, digest in recorded.items():
        path = _resolve(key, roots)
        current = file_sha256(path) if path is not None and path.is_file() else None
        if current != digest:
            out.append(AssetChange(table, key, digest, current))
    return out


# ---------------------------------------------------------------- provenance attributes


def plain(v: Any) -> Any:
    """An attribute value as Python: NumPy scalars (as HDF5 returns them) as plain numbers."""
    return v.item() if isinstance(v, np.generic) else v


def decoded(v: Any) -> Any:
    """An attribute value with its JSON text decoded: to compare values, not spellings."""
    if isinstance(v, str) and v.startswith(("{", "[")):
        try:
            return json.loads(v)
        except ValueError:
            return v
    return plain(v)


def stamped(attrs: Mapping[str, Any], obj: str) -> dict[str, Any]:
    """``attrs`` of a result about object ``obj`` with the :data:`PROVENANCE` it lacks, as this
    process makes it: its packages, its code, and the files of the result's hand (attribute
    ``hand``) and object as they are now. What ``attrs`` has is kept: a result made elsewhere
    keeps what it was made with."""
    hand = str(attrs.get("hand") or "") or None
    makers: dict[str, Callable[[], Any]] = {"versions": package_versions, "code_version": code_version,
              "asset_sha256": lambda: asset_hashes(hand, obj)}
    return {**attrs, **{k: makers[k]() for k in PROVENANCE if k not in attrs}}


def as_recorded(attrs: Mapping[str, Any]) -> dict[str, Any]:
    """``attrs`` read back from a file, the :data:`PROVENANCE` it lacks marked unrecorded, so
    that rewriting the file never stamps the rewriter's provenance on rows it did not make."""
    return {**{k: UNRECORDED for k in PROVENANCE}, **attrs}


def merged_attrs(old: Mapping[str, Any], new: Mapping[str, Any], rows: int) -> dict[str, Any]:
    """The attributes of rows made under ``old`` followed by ``rows`` rows made under ``new``:
    ``old``'s, plus an :data:`APPENDED` entry ``{"grasps": rows, "attrs": ...}`` with those of
    ``new`` that differ (nothing is lost of how any row was made)."""
    diff = {k: decoded(v) for k, v in new.items()
            if k != APPENDED and decoded(old.get(k)) != decoded(v)}
    if not diff:
        return dict(old)
    return {**old, APPENDED: [*decoded(old.get(APPENDED, "[]")), {"grasps": rows, "attrs": diff}]}


def recorded_changes(attrs: Mapping[str, Any], table: str = "") -> list[AssetChange]:
    """:func:`changed_assets` for every asset record in ``attrs`` (its own and its appended
    runs'), each changed file once."""
    runs = [attrs.get("asset_sha256"),
            *(r["attrs"]["asset_sha256"] for r in decoded(attrs.get(APPENDED, "[]"))
              if "asset_sha256" in r["attrs"])]
    out: dict[tuple[str, str | None], AssetChange] = {}
    for recorded in map(decoded, runs):
        for change in changed_assets(recorded if isinstance(recorded, dict) else None, table):
            out.setdefault((change.file, change.recorded), change)
    return list(out.values())
