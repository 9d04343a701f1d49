"""Scripted demonstrations: a grasp worth demonstrating, performed in the bridge's scene and
recorded, kept when it is a demo that augments well (``dexaug demo script``, ``make demo``).

How a demonstration is made, with dexaug's own tools only (no human, no headset):

1. **A grasp worth demonstrating** (:func:`demonstrable_grasps`): FSG on the hand's manual
   workspace (no demo, table mode, link penetration check) proposes grasps of the object
   resting on the table; each is validated by lift-drop, and the passing ones are candidates.
2. **Performed and recorded**: each candidate is performed as a scripted demonstration in the
   bridge's scene (:func:`teleop.synthetic.scripted.record_scripted_demo`: pregrasp → close →
   hold → lift → hold on the table, gravity on) and recorded in the bridge's session format.
3. **Kept when it augments well** (:func:`script_demo`): extraction must find the grasp in the
   recording (:func:`teleop.record.demos.extract_demos`); each demo is tried as a user would
   try it — a small demo-seeded augmentation on a seed of its own (not the benchmarks' 0),
   validated by lift-drop — and the candidate whose trial passes most often (then more fingers
   in contact, then held longer) is kept. The demo's fingers and posture set what its
   augmentation can reach, and an operator would re-record a demo whose augmentations drop the
   object.

Why here (the application layer): it takes FSG and the validator, and the scripted demonstrator
is teleop; neither package imports the other.
"""

from __future__ import annotations

import logging
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from augment.autows.build import build_workspace
from augment.autows.seed import DemoSeed
from augment.object_cloud import object_cloud
from dexaug.pipeline.run import demo_fingers, generate_grasps
from sim.demo import Demo, DemoError, save_demo
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.io import atomic_path
from sim.validate.batch import validate_many
from sim.world.objects import load_object
from teleop.record.demos import extract_demos
from teleop.synthetic.scripted import record_scripted_demo

__all__ = ["TRIAL_SEED", "ScriptedDemo", "demonstrable_grasps", "script_demo", "trial_pass_rate"]

log = logging.getLogger(__name__)

#: FSG seed of the trial augmentations (the benchmarks and ``dexaug augment`` use 0)
TRIAL_SEED = 1000


def demonstrable_grasps(hand: Hand, object_name: str, n: int, *, seed: int = 0,
                        workers: int = 2, time_budget_s: float = 60.0) -> list[Grasp]:
    """Grasps worth demonstrating on ``object_name`` resting on the table: FSG's proposals on
    the hand's manual workspace (table mode, link penetration check; ``n`` asked for) that pass
    the MuJoCo lift-drop test, best FSG ε first. What the scripted demonstrator performs."""
    res = generate_grasps(hand, object_cloud(load_object(object_name)), build_workspace(hand), n=n,
                          table=True, link_penetration=True, seed=seed, workers=workers,
                          time_budget_s=time_budget_s)
    results = validate_many(hand.name, object_name, [g.grasp for g in res.grasps],
                            workers=workers)
    passing = [g.grasp for g, r in zip(res.grasps, results, strict=True) if r.passed]
    log.info("%s: %d FSG proposals, %d pass lift-drop", object_name, len(res.grasps),
             len(passing))
    return passing


def trial_pass_rate(hand: Hand, demo: Demo, n: int, *, workers: int = 2) -> float:
    """Fraction of ``n`` demo-seeded FSG grasps (link penetration check, seed
    :data:`TRIAL_SEED`) that pass lift-drop."""
    cloud = object_cloud(load_object(demo.object))
    res = generate_grasps(hand, cloud, build_workspace(hand, demo=DemoSeed.from_demo(demo)), n=n,
                          finger_names=demo_fingers(demo), finger_iteration=False,
                          link_penetration=True, seed=TRIAL_SEED, workers=workers,
                          time_budget_s=60.0)
    if not res.grasps:
        return 0.0
    results = validate_many(hand.name, demo.object, [g.grasp for g in res.grasps],
                            workers=workers)
    return sum(r.passed for r in results) / len(results)


@dataclass(frozen=True)
class ScriptedDemo:
    """The kept demonstration: its session, its demo file, the demo, and its trial's pass rate."""

    session: Path
    demo_file: Path
    demo: Demo
    trial_pass_rate: float


def script_demo(hand: Hand, object_name: str, out_dir: Path | str, *, candidates: int = 60,
                tries: int = 8, trial: int = 20, workers: int = 2) -> ScriptedDemo:
    """Find, perform, record and choose a scripted demonstration of ``object_name`` (module
    docstring); writes ``<out_dir>/demo_<object>.mcap`` and ``<out_dir>/demos/<object>.json``
    (atomically, only once a demo is found).

    Raises:
        DemoError: no proposal holds, or no performed candidate gave a demo (says which).
    """
    out_dir = Path(out_dir)
    passing = demonstrable_grasps(hand, object_name, candidates, workers=workers)[:tries]
    if not passing:
        raise DemoError(f"{object_name}: none of {candidates} FSG proposals on the table passes "
                        "lift-drop, nothing to demonstrate")
    best: tuple[tuple[float, int, float], Path, Demo] | None = None
    with tempfile.TemporaryDirectory() as tmp:
        for i, grasp in enumerate(passing):
            path = record_scripted_demo(hand, object_name, grasp, Path(tmp) / f"{i}.mcap")
            try:
                demo = max(extract_demos(path), key=lambda d: d.duration_s)
            except DemoError as exc:
                log.info("%s candidate %d: %s", object_name, i, exc)
                continue
            score = (trial_pass_rate(hand, demo, trial, workers=workers), len(demo.fingers),
                     demo.duration_s)
            log.info("%s candidate %d: fingers %s, held %.2f s, trial augmentation passes "
                     "%.0f %%", object_name, i, demo.fingers, demo.duration_s, 100 * score[0])
            if best is None or score > best[0]:
                best = (score, path, demo)
        if best is None:
            raise DemoError(f"{object_name}: {len(passing)} candidates performed, none gave a "
                            "demo (see the log for each one's reason)")
        session = out_dir / f"demo_{object_name}.mcap"
        session.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(session) as dst:
            shutil.copyfile(best[1], dst)
    demo = max(extract_demos(session), key=lambda d: d.duration_s)
    demo_file = out_dir / "demos" / f"{object_name}.json"
    demo_file.parent.mkdir(parents=True, exist_ok=True)
    save_demo(demo_file, demo)
    log.info("%s: demo %s (%s, fingers %s, held %.2f s)", object_name, demo.id, demo.how,
             demo.fingers, demo.duration_s)
    return ScriptedDemo(session, demo_file, demo, best[0][0])
