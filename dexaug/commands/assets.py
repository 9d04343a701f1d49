"""Subcommand ``assets``: which hands and objects dexaug can find, and what is broken and why.

The listing never stops at the first problem: a hand whose model files are not installed is a
"missing assets" row naming what is missing and where it was looked for (a checkout without
``../shared`` beside it lists every hand and the primitives), a broken object is a red
"broken" row and is named again in the count line, and missing texture files (most of the YCB
set ships without them: the objects load with plain colours) are one note, not a remark on
each row.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.table import Table
from rich.text import Text

from dexaug.commands.registry import command

#: how the YCB loader words a dropped texture (sim.world.ycb_xml): such warnings are counted
#: into one note instead of being shown on each row
TEXTURE_WARNING = "texture file(s) missing"


def _assets_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--broken", action="store_true", help="list only objects that fail to load")


def _menagerie_root(console: Console) -> Path | None:
    """``MENAGERIE_ROOT`` as resolved (None: not set and no ../shared/assets/menagerie); a root
    that is not a folder is printed as the problem and counts as missing."""
    from sim.errors import AssetError
    from sim.paths import MENAGERIE_ENV, SHARED_ASSETS, ensure_menagerie_root

    try:
        root = ensure_menagerie_root()
    except AssetError as exc:
        console.print(Text(f"{MENAGERIE_ENV}: {exc}", style="red"))
        return None
    where = root if root is not None else (f"None (not set, and {SHARED_ASSETS / 'menagerie'} "
                                           "does not exist)")
    console.print(Text(f"{MENAGERIE_ENV} = {where}"))
    return root


def missing_hand_assets(name: str, menagerie: Path | None) -> str | None:
    """What a hand's model needs that is not installed, in words, before anything is compiled:
    a Menagerie model without a Menagerie root, a model file that is not there, or a mesh
    folder (the model's ``<compiler meshdir>``, relative to its file) that does not exist.
    None when all of it is there (loading may still fail, for another reason)."""
    import xml.etree.ElementTree as ET

    from sim.hand.config import load_hand_config
    from sim.paths import MENAGERIE_ENV, SHARED_ASSETS

    config = load_hand_config(name)
    if config.model_path is None:
        if menagerie is None:
            return (f"Menagerie model {config.menagerie!r}: {MENAGERIE_ENV} is not set and "
                    f"{SHARED_ASSETS / 'menagerie'} does not exist")
        return None
    path = Path(config.model_path)
    if not path.is_file():
        return f"model file {path} does not exist"
    try:
        compiler = ET.parse(path).getroot().find("compiler")
    except ET.ParseError:
        return None                     # not for this check to judge: loading will say why
    meshdir = compiler.get("meshdir") if compiler is not None else None
    if meshdir:
        folder = (path.parent / meshdir).resolve()
        if not folder.is_dir():
            return (f"mesh folder {folder} does not exist ({path.name}: "
                    f"meshdir={meshdir!r}, relative to {path.parent})")
    return None


def _hands_table(console: Console) -> tuple[int, list[tuple[str, str]], list[str]]:
    """Print the hands table; returns the number of hands, (name, what is missing) of those
    with missing assets, and the names of those otherwise broken."""
    from sim.errors import DexaugError
    from sim.hand.config import hand_names
    from sim.hand.model import Hand

    menagerie = _menagerie_root(console)
    hands = Table(title="hands")
    for col in ("hand", "joints", "actuators", "fingers", "status"):
        hands.add_column(col)
    names = hand_names()
    missing, broken = [], []
    for name in names:
        try:
            if (why := missing_hand_assets(name, menagerie)) is not None:
                missing.append((name, why))
                hands.add_row(name, "", "", "", Text("missing assets (below)", style="bold red"))
                continue
            hand = Hand.load(name)
        except (DexaugError, ValueError) as exc:   # ValueError: MuJoCo could not compile it
            text = str(exc)
            if "Error opening file" in text:
                missing.append((name, text))
                hands.add_row(name, "", "", "", Text("missing assets (below)", style="bold red"))
            else:
                broken.append(name)
                hands.add_row(name, "", "", "", Text(f"broken: {text}", style="bold red"))
            continue
        hands.add_row(name, str(hand.nq), str(hand.model.nu), ", ".join(hand.finger_names),
                      Text("ok", style="green"))
    console.print(hands)
    return len(names), missing, broken


def _objects_table(console: Console, only_broken: bool) -> None:
    from sim.paths import SHARED_ASSETS, YCB_ENV, ycb_root
    from sim.world.catalog import list_objects

    root = ycb_root(required=False)
    where = root if root is not None else (f"None (not set, and {SHARED_ASSETS / 'ycb'} does "
                                           "not exist)")
    console.print(Text(f"{YCB_ENV} = {where}"))
    objects = Table(title="objects")
    for col in ("object", "source", "mass (kg)", "status"):
        objects.add_column(col)
    statuses = list_objects()
    untextured = 0
    for s in statuses:
        notes = [w for w in s.warnings if not w.startswith(TEXTURE_WARNING)]
        untextured += s.ok and len(notes) < len(s.warnings)
        if only_broken and s.ok:
            continue
        if not s.ok:
            state = Text(f"broken: {s.problem}", style="bold red")
        elif notes:
            state = Text(f"ok ({'; '.join(notes)})", style="yellow")
        else:
            state = Text("ok", style="green")
        objects.add_row(s.name, s.source, f"{s.mass_kg:.3f}" if s.mass_kg else "", state)
    console.print(objects)
    ycb = [s for s in statuses if s.source == "ycb"]
    broken = [s.name for s in ycb if not s.ok]
    primitives = [s for s in statuses if s.source == "primitive"]
    line = Text(f"{len(ycb) - len(broken)} of {len(ycb)} YCB objects load, ")
    line.append(f"{len(broken)} broken" + (f": {', '.join(broken)}" if broken else ""),
                style="bold red" if broken else "")
    line.append(f"; {sum(s.ok for s in primitives)} of {len(primitives)} primitives load")
    if root is None:
        line.append(f" (no YCB objects: set {YCB_ENV} to a folder of <id>_<name>/ objects)")
    console.print(line, soft_wrap=True)
    if untextured:
        console.print(Text(f"note: {untextured} YCB objects have missing texture files and load "
                           "with plain colours (geometry, mass and contacts are unaffected)",
                           style="dim"))


@command("assets", _assets_args)
def assets(args: argparse.Namespace, console: Console) -> int:
    """List the hands and objects dexaug can find, and what is broken and why.

    Hands come from configs/hands/*/hand.toml resolved through mujoco_menagerie (MENAGERIE_ROOT)
    or their own model file; a hand whose model or meshes are not installed is a "missing
    assets" row saying what is missing and where it was looked for. Objects are the procedural
    primitives plus every YCB object under DEXAUG_YCB_ROOT; broken ones are red rows, named
    again in the count line ("N of M YCB objects load"), and objects without their texture
    files are counted in one note.
    """
    n_hands, missing, broken = _hands_table(console)
    line = Text(f"{n_hands - len(missing) - len(broken)} of {n_hands} hands load")
    if missing:
        line.append(f"; missing assets: {', '.join(name for name, _ in missing)}",
                    style="bold red")
    if broken:
        line.append(f"; broken: {', '.join(broken)}", style="bold red")
    console.print(line, soft_wrap=True)
    for name, why in missing:     # whole, on one line each: paths are never folded here
        console.print(Text(f"{name}: missing assets: {why}", style="red"), soft_wrap=True)
    _objects_table(console, args.broken)
    return 0
