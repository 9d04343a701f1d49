"""What one augmentation run does, and the key that says whether two runs are the same.

Why a module of its own: the CLI, the dashboard and the pipeline all build and compare options,
and the resume logic (:func:`run_key`) must hash exactly what changes results.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from augment.autows.params import AUGMENT_TOML
from sim.demo import Demo, demo_to_json
from sim.hand.config import hand_config_path
from sim.validate.batch import default_workers
from sim.validate.config import VALIDATE_TOML

__all__ = ["RESULT_CONFIGS", "AugmentOptions", "Progress", "demo_dir", "result_configs", "run_key"]

#: progress(stage, done, total): stage is "workspace", "fsg", "validate", "report".
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class AugmentOptions:
    """What one augmentation run does. ``validate``: "lift-drop", "six-dir", "dgb" or None
    (keep every FSG grasp unvalidated); ``squeeze_convention``: how dgb makes each grasp's
    pregrasp and squeeze (None: the config's); ``time_budget_s`` bounds FSG (wall seconds);
    ``gallery`` renders this many grasps for the report (0: no images)."""

    n: int = 200
    validate: str | None = "lift-drop"
    link_penetration: bool = True
    #: table mode: None follows the demo (its table, when it recorded one), True forces it
    #: (the demo's table, else a horizontal one under the object), False turns it off
    table: bool | None = None
    seed: int = 0
    workers: int = field(default_factory=default_workers)
    time_budget_s: float = 120.0
    gallery: int = 6
    squeeze_convention: str | None = None
    #: with a demo, keep its fingers (False) or let FSG drop the least important one on a
    #: poor round (the paper's finger iteration)
    finger_iteration: bool = False
    #: what steps lift-drop and six-dir: "mujoco" (the C engine on the CPU) or "warp" (MuJoCo
    #: Warp on a CUDA device: close to, not bit-identical with, the C engine's verdicts)
    backend: str = "mujoco"


#: the configuration files an augmentation's results depend on (besides the hand's own)
RESULT_CONFIGS = (AUGMENT_TOML, VALIDATE_TOML)


def result_configs(demo: Demo | str) -> dict[str, str]:
    """``"config:<file name>"`` → text of each configuration file the stages read for ``demo``
    (or for a run of hand ``demo`` without one: AutoWS and FSG parameters, the validator's, the
    hand's; "" when absent): read once per run, hashed into :func:`run_key` and stored in the
    dataset as provenance."""
    paths = (*RESULT_CONFIGS, hand_config_path(demo if isinstance(demo, str) else demo.hand))
    return {f"config:{p.name}": p.read_text() if p.is_file() else "" for p in paths}


def result_options(opts: AugmentOptions) -> dict[str, object]:
    """The options that change results, as :func:`run_key` hashes them: all but ``workers``
    and ``gallery``, and ``backend`` only when it is not the default (so results made before
    the option existed are still found finished)."""
    options = asdict(opts)
    options.pop("workers")
    options.pop("gallery")
    if options["backend"] == AugmentOptions.backend:
        options.pop("backend")
    return options


def run_key(demo: Demo, opts: AugmentOptions, configs: dict[str, str] | None = None) -> str:
    """Hash of everything that changes an augmentation's results: the options (not
    ``workers`` or ``gallery``), the demo itself, and the configuration texts
    (:func:`result_configs`, read now unless given). A re-run skips a demo only when this
    matches, so a re-recorded demo or an edited config is redone, not served stale."""
    doc = {"options": result_options(opts), "demo": demo_to_json(demo),
           "configs": configs if configs is not None else result_configs(demo)}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]


#: longest folder name :func:`demo_dir` makes (file systems refuse names over 255 bytes)
_MAX_DIR_NAME = 120


def demo_dir(out_root: Path | str, demo: Demo) -> Path:
    """The folder of ``demo``'s results, always directly inside ``out_root``: its id with
    path-unsafe characters (separators, NUL, anything outside ``[A-Za-z0-9_.@-]``) replaced by
    ``_``, a leading dot prefixed with ``_`` (so ``.`` and ``..`` never name ``out_root`` or its
    parent, and no result folder is hidden), and an over-long id cut and given a hash of the
    whole id. Ordinary ids (``<session>@<time>s``) map to themselves, so earlier results are
    found again."""
    name = re.sub(r"[^A-Za-z0-9_.@-]+", "_", demo.id)
    if not name or name.startswith("."):
        name = "_" + name
    if len(name) > _MAX_DIR_NAME:
        digest = hashlib.sha256(demo.id.encode("utf-8", "surrogatepass")).hexdigest()[:12]
        name = f"{name[:_MAX_DIR_NAME - 13]}-{digest}"
    return Path(out_root) / name
