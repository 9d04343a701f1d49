"""``dexaug bench paper``: the rows of the paper's Tables 2 and 3, measured here, beside the paper's.

Per object, workspace ("manual": the hand's joint ranges, Table 2; "demo": centred on the
committed demonstration, Table 3: the imported human one ``recordings/demos/human/<object>.json``
where it exists, else the scripted ``recordings/demos/<object>.json``, :func:`demo_file`) and FSG
variant (paper §5.1: FSG samples the whole object cloud, +Aff its graspable part, −FinIter
without finger iteration, +LinkPen with the link penetration check):

* time per result: wall seconds of the whole ``generate`` call (object cloud cached, workspace
  built beforehand) divided by the grasps returned, on this machine's cores;
* GWS ε and volume: means over the grasps whose *simulated* contacts after closing are in force
  closure, and valid-ε %: their share — the paper's GraspIt columns, measured by the MuJoCo
  validator instead (DESIGN §5);
* what the paper could not measure: lift-drop, DexGraspBench (``dgb``, dexaug's pregrasp and
  squeeze) and six-dir pass rates, the hand–object
  penetration at placement (mean of the per-grasp maximum), and diversity: the RMS distance of
  palm positions from their mean and the mean standard deviation of the used joints.

Rows that find nothing show "—", as the paper's NaN rows. The paper's figures, and the hand its
tables are of (``hand``: the Shadow Hand, the paper's §5; the rows are measured on it, not on
whichever hand is the default), come from ``configs/paper/autows_fsg_tables.toml``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sim.config import Section, load_toml
from sim.paths import CONFIG_DIR, REPO_ROOT

if TYPE_CHECKING:
    from augment.fsg.result import FsgGrasp

OBJECTS = ("004_sugar_box", "005_tomato_soup_can", "024_bowl", "043_phillips_screwdriver",
           "062_dice")
VARIANTS: dict[str, dict[str, bool]] = {
    "FSG": {"use_affordance": False},
    "FSG+Aff": {},
    "FSG+Aff-FinIter": {"finger_iteration": False},
    "FSG+Aff+LinkPen": {"link_penetration": True},
}
PAPER_TABLES = CONFIG_DIR / "paper" / "autows_fsg_tables.toml"
DEMOS_DIR = REPO_ROOT / "recordings" / "demos"


@dataclass
class Row:
    """One measured row (NaN where nothing was found)."""

    object: str
    workspace: str
    method: str
    found: int
    requested: int
    stopped: str
    time_per_result_s: float = math.nan
    epsilon: float = math.nan
    volume: float = math.nan
    valid_pct: float = math.nan
    lift_drop_pct: float = math.nan
    dgb_pct: float = math.nan
    six_dir_pct: float = math.nan
    penetration_mm: float = math.nan
    palm_spread_mm: float = math.nan
    joint_spread_deg: float = math.nan


def _paper_config(path: Path) -> Section:
    """The paper config, its keys checked (a typo would silently drop a row or the hand)."""
    root = load_toml(path)
    root.reject_unknown({"hand", "rows"})
    for sec in root.sections("rows"):
        sec.reject_unknown({"table", "object", "values"})
    return root


def paper_hand(path: Path = PAPER_TABLES) -> str:
    """The hand the paper's tables are of (the config's ``hand``), checked against the hand
    folders: a one-line error naming the file and key when there is no such folder."""
    from sim.hand.config import named_hand

    return named_hand(_paper_config(path))


def paper_figures(path: Path = PAPER_TABLES) -> dict[tuple[str, str, str], list[float]]:
    """(workspace, object, method) → [time/result s, ε, volume, valid-ε %] from the paper."""
    out = {}
    for sec in _paper_config(path).sections("rows"):
        values = sec.section("values")
        for method in values.data:
            out[(sec.str("table"), sec.str("object"), method)] = values.floats(method, 4)
    return out


def demo_file(name: str) -> Path | None:
    """The demonstration Table 3 seeds AutoWS with for object ``name``: a real (imported human)
    one where it exists, as the paper's are, else the scripted one; None when there is neither."""
    from dexaug.pipeline.demo_import import IMPORTED_DEMOS_DIR

    found = [p for p in (IMPORTED_DEMOS_DIR / f"{name}.json", DEMOS_DIR / f"{name}.json")
             if p.is_file()]
    return found[0] if found else None


def _diversity(grasps: list[FsgGrasp], joint_mask: np.ndarray) -> tuple[float, float]:
    pos = np.array([g.grasp.palm_pos for g in grasps])
    spread = float(np.sqrt(((pos - pos.mean(axis=0)) ** 2).sum(axis=1).mean()))
    q = np.array([g.grasp.joints for g in grasps])[:, joint_mask]
    used = q.std(axis=0) > 0
    return 1e3 * spread, float(np.degrees(q.std(axis=0)[used].mean())) if used.any() else 0.0


def measure(objects: list[str], methods: list[str], workspaces: list[str], *, n: int,
            budget_s: float, workers: int, seed: int = 0, six_dir: bool = True,
            on_row: Callable[[Row], None] | None = None) -> list[Row]:
    """Measure every (object, workspace, method) row on the paper's hand (:func:`paper_hand`);
    see the module docstring."""
    from augment.autows.build import build_workspace
    from augment.autows.seed import DemoSeed
    from augment.object_cloud import object_cloud
    from dexaug.pipeline.run import demo_fingers, generate_grasps
    from sim.demo import load_demo
    from sim.hand.model import Hand
    from sim.validate.batch import validate_many
    from sim.world.objects import load_object

    hand = Hand.load(paper_hand())
    finger_joints = {j for f in hand.config.fingers for j in f.joints}
    joint_mask = np.array([j in finger_joints for j in hand.joint_names])
    manual = build_workspace(hand)
    rows = []
    for name in objects:
        cloud = object_cloud(load_object(name))
        for mode in workspaces:
            demo = None
            if mode == "demo":
                path = demo_file(name)
                if path is None:
                    continue
                demo = load_demo(path)
            ws = build_workspace(hand, demo=DemoSeed.from_demo(demo)) if demo else manual
            for method in methods:
                t0 = time.perf_counter()
                res = generate_grasps(hand, cloud, ws, n=n, seed=seed, time_budget_s=budget_s,
                               workers=workers, finger_names=demo_fingers(demo) if demo else None,
                               hold_protocol=None,  # the paper's method: ranked by ε
                               **VARIANTS[method])
                wall = time.perf_counter() - t0
                k = len(res.grasps)
                row = Row(name, mode, method, k, n, res.stopped)
                if k:
                    grasps = [g.grasp for g in res.grasps]
                    ld = validate_many(hand.name, name, grasps, "lift-drop", workers=workers)
                    valid = [r for r in ld if r.epsilon > 0]
                    row.time_per_result_s = wall / k
                    row.epsilon = float(np.mean([r.epsilon for r in valid])) if valid else math.nan
                    row.volume = float(np.mean([r.volume for r in valid])) if valid else math.nan
                    row.valid_pct = 100.0 * len(valid) / k
                    row.lift_drop_pct = 100.0 * float(np.mean([r.passed for r in ld]))
                    row.penetration_mm = 1e3 * float(np.mean([r.penetration_m for r in ld]))
                    dgb = validate_many(hand.name, name, grasps, "dgb", workers=workers)
                    row.dgb_pct = 100.0 * float(np.mean([r.passed for r in dgb]))
                    if six_dir:
                        sd = validate_many(hand.name, name, grasps, "six-dir", workers=workers)
                        row.six_dir_pct = 100.0 * float(np.mean([r.passed for r in sd]))
                    row.palm_spread_mm, row.joint_spread_deg = _diversity(res.grasps, joint_mask)
                rows.append(row)
                if on_row is not None:
                    on_row(row)
    return rows


def _f(x: float, spec: str) -> str:
    return "—" if not math.isfinite(x) else format(x, spec)


def markdown(rows: list[Row], paper: dict[tuple[str, str, str], list[float]]) -> str:
    """The table: ours / paper for the paper's four columns, then ours only."""
    head = ("| Object | Workspace | Method | Results | Time / result (s) ours / paper "
            "| GWS ε ours / paper | GWS volume ours / paper | Valid ε % ours / paper "
            "| Lift-drop % | DGB % | Six-dir % | Penetration (mm) | Palm spread (mm) "
            "| Joint spread (°) |")
    lines = [head, "|" + "---|" * 14]
    for r in rows:
        p = paper.get((r.workspace, r.object, r.method), [math.nan] * 4)
        note = "" if r.stopped == "done" else " (budget)"
        lines.append(
            f"| {r.object} | {r.workspace} | {r.method} | {r.found}/{r.requested}{note} "
            f"| {_f(r.time_per_result_s, '.3f')} / {_f(p[0], '.3f')} "
            f"| {_f(r.epsilon, '.2e')} / {_f(p[1], '.2e')} "
            f"| {_f(r.volume, '.2e')} / {_f(p[2], '.2e')} "
            f"| {_f(r.valid_pct, '.1f')} / {_f(p[3], '.1f')} "
            f"| {_f(r.lift_drop_pct, '.1f')} | {_f(r.dgb_pct, '.1f')} | {_f(r.six_dir_pct, '.1f')} "
            f"| {_f(r.penetration_mm, '.2f')} | {_f(r.palm_spread_mm, '.0f')} "
            f"| {_f(r.joint_spread_deg, '.1f')} |")
    return "\n".join(lines)
