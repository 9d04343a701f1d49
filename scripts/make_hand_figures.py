"""Draw the paper's figure equivalents into ``docs/images/``: grasps per hand (its Fig. 1) and the
Shadow Hand's grasps of the bleach bottle with 2, 3, 4 and 5 fingers (its Fig. 7).

Every tile is a grasp this project generated without a demo (fingertip FSG on the hand's manual
workspace, or ``--mode power``) and validated with lift-drop; the tile names the hand, the mode,
the object and the verdict. Of each cell's grasps (ranked as the generator ranks them) the first
that passes is drawn, or the first one with its failure when none passes. Run:
``MUJOCO_GL=egl .venv/bin/python scripts/make_hand_figures.py`` (a few minutes on two cores).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from augment.autows.build import build_workspace
from augment.object_cloud import object_cloud
from augment.power import generate_power
from dexaug.pipeline.run import generate_grasps
from sim.hand.config import default_hand_name, hand_names
from sim.hand.model import Hand
from sim.validate.batch import cached_validator, validate_many
from sim.world.drawing import Canvas
from sim.world.objects import load_object
from sim.world.render import save_png

OUT = Path(__file__).resolve().parents[1] / "docs" / "images"
TILE = (360, 270)                       # width, height in pixels
#: per hand: (mode, object) of each column of the per-hand figure
COLUMNS = (("fingertip", "005_tomato_soup_can"), ("power", "005_tomato_soup_can"),
           ("power", "021_bleach_cleanser"))
FINGER_OBJECT = "021_bleach_cleanser"
N = 10


def _tile(hand: Hand, obj: str, grasps: list, label: str) -> np.ndarray:
    """The first passing grasp of ``grasps`` (else the first), rendered and labelled."""
    width, height = TILE
    if not grasps:
        img = np.full((height, width, 3), 235, np.uint8)
        return _label(img, [label, "no grasp generated"])
    results = validate_many(hand.name, obj, grasps, "lift-drop", workers=2)
    k = next((i for i, r in enumerate(results) if r.passed), 0)
    verdict = "holds" if results[k].passed else f"fails: {results[k].failure}"
    passed = sum(r.passed for r in results)
    img = cached_validator(hand.name, obj).render(grasps[k], width, height)
    return _label(np.ascontiguousarray(img), [label, f"lift-drop: {verdict} ({passed}/{len(results)} pass)"])


def _label(img: np.ndarray, lines: list[str]) -> np.ndarray:
    with Canvas(img) as canvas:
        for i, text in enumerate(lines):
            canvas.text((8, 20 + 18 * i), text, (20, 20, 20), size_px=14)
    return img


def _grasps(hand: Hand, mode: str, obj: str, fingers: int | None = None) -> list:
    if mode == "power":
        res = generate_power(hand, obj, n=N, seed=0, workers=2, time_budget_s=300)
        return [g.grasp for g in res.grasps]
    res = generate_grasps(hand, object_cloud(load_object(obj)), build_workspace(hand), n=N,
                          seed=0, workers=2, fingers=fingers, finger_iteration=fingers is None,
                          time_budget_s=300)
    return [g.grasp for g in res.grasps if fingers is None or len(g.fingers) == fingers]


def main() -> None:
    rows = []
    for name in hand_names():
        hand = Hand.load(name)
        rows.append(np.hstack([_tile(hand, obj, _grasps(hand, mode, obj),
                                     f"{name}, {mode}, {obj}") for mode, obj in COLUMNS]))
    save_png(OUT / "grasps_per_hand.png", np.vstack(rows))
    shadow = Hand.load(default_hand_name())
    save_png(OUT / "shadow_fingers_021.png", np.hstack([
        _tile(shadow, FINGER_OBJECT, _grasps(shadow, "fingertip", FINGER_OBJECT, k),
              f"{shadow.name}, {k} fingers, {FINGER_OBJECT}") for k in (2, 3, 4, 5)]))
    print(f"wrote {OUT / 'grasps_per_hand.png'} and {OUT / 'shadow_fingers_021.png'}")


if __name__ == "__main__":
    main()
