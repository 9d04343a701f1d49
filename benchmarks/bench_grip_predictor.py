"""How well do the physical scores predict the simulated verdict? AUC, precision / recall.

FSG can rank its grasps (``hold_oversample`` > 1) by two scores computed before anything is
simulated: the actuator effort (``sim.validate.effort``: the least worst actuator force, as a
fraction of its limit, that holds the validation's loads at the placed grasp) and the grip ratio
(``sim.metrics.holding``: the least total normal force within the simulation's friction cones,
over the load). This reads datasets that were validated (``grasps.h5`` of ``dexaug augment`` /
``dexaug generate``; passing and rejected tables), recomputes both for every grasp (the effort
from the grasp placed in the validator's scene, the grip ratio from its stored FSG contacts)
with the loads of the dataset's protocol, and compares with the stored verdicts:

* **AUC**: the probability that a passing grasp scores lower than a failing one (0.5: no
  information), for the effort, the grip ratio and the GWS ε the paper ranks by (negated);
* **effort > 1**: the share of grasps the actuators cannot hold the load with, and how many
  of those passed;
* **precision / recall** of the rule "holds when the squeeze the validator sizes (before its
  headroom boost) is at least the least grip": total squeeze
  ``grip_safety · F · (1 + d/ρ) / μ`` (F the protocol's largest load: the weight, or a push;
  ``configs/validate.toml``;
  d, ρ from the per-finger contacts, as ``sim.validate.targets`` computes it) ≥ λ*;
* the share of grasps whose contacts cannot hold the load at all (ratio = inf), and the
  finger-count distribution of the passing grasps;
* with ``--bins``, the pass rate of all the datasets' grasps by actuator effort and a
  logistic fit p(pass) = σ(a + b·effort) by maximum likelihood, with the effort at which it
  crosses a few pass chances: the calibration behind ``[fsg] max_actuator_effort``
  (configs/augment.toml). Calibrate on objects outside the set you will judge the limit on.

    .venv/bin/python benchmarks/bench_grip_predictor.py DATASET.h5 [DATASET.h5 ...] [--bins]

Prints one Markdown table, a row per dataset and object and one over all of them, and writes
those rows (with the bins and the fit) as a record (:func:`benchmarks.record.write_record`,
``benchmarks/measured/grip_predictor/``).
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scipy.optimize import minimize

from augment import dataset
from benchmarks.record import write_record
from sim.grasp import Grasp
from sim.hand.model import Hand
from sim.metrics.holding import HoldLoads, finger_contacts
from sim.validate.config import ValidateConfig
from sim.validate.loads import hold_loads
from sim.validate.targets import largest_force_n, squeeze_total_n
from sim.validate.validator import Validator
from sim.world.objects import load_object


def auc(score: np.ndarray, passed: np.ndarray) -> float:
    """P(score of a passing grasp < score of a failing one), ties half (Mann–Whitney)."""
    score = np.where(np.isfinite(score), score, np.finfo(float).max)
    pos, neg = score[passed], score[~passed]
    if not len(pos) or not len(neg):
        return float("nan")
    less = (pos[:, None] < neg[None, :]).sum() + 0.5 * (pos[:, None] == neg[None, :]).sum()
    return float(less / (len(pos) * len(neg)))


def squeeze_ratio(points: np.ndarray, hold: HoldLoads, cfg: ValidateConfig) -> float:
    """The validator's total squeeze for the protocol's loads ``hold`` (its friction; the
    largest load force), over that force, for contacts at ``points`` (one per finger)."""
    total = squeeze_total_n(points, hold, cfg.common.grip_safety)
    return max(total, cfg.common.min_grip_force_n * len(points)) / largest_force_n(hold)


def rows_of(path: Path, cfg: ValidateConfig) -> list[dict[str, object]]:
    out = []
    for name, table in dataset.load(path).items():
        protocol = str(table.attrs.get("protocol") or "lift-drop")
        obj = load_object(name)
        hold = hold_loads(obj, protocol, cfg)
        validator = Validator(Hand.load(str(table.attrs["hand"])), obj, cfg)
        ratios, budgets, passed, fingers, eps, efforts = [], [], [], [], [], []
        for t in (table, table.rejected):
            if t is None:
                continue
            for i in range(len(t)):
                p, n, f = t.contacts(i)
                ratios.append(hold.grip_ratio(p, n, f))
                pose = t.columns["palm_pose"][i]
                efforts.append(validator.actuator_effort(
                    Grasp(pose[:3], pose[3:], t.columns["hand_pose"][i]), hold, protocol))
                centres, _ = finger_contacts(p, n, f)
                budgets.append(squeeze_ratio(centres, hold, cfg))
                passed.append(bool(t.columns["passed"][i]))
                fingers.append(int(t.columns["fingers_used"][i].sum()))
                eps.append(float(t.columns["gws"][i]))
        out.append({"source": path.parent.name, "object": name, "protocol": protocol,
                    "ratio": np.array(ratios), "budget": np.array(budgets),
                    "passed": np.array(passed, bool), "fingers": np.array(fingers),
                    "epsilon": np.array(eps), "effort": np.array(efforts)})
    return out


def stats(label: str, r: dict[str, np.ndarray]) -> dict[str, Any]:
    """One row of the table as data (shares as fractions)."""
    y, ratio = r["passed"], r["ratio"]
    pred = np.isfinite(ratio) & (ratio <= r["budget"])
    tp, fp, fn = int((pred & y).sum()), int((pred & ~y).sum()), int((~pred & y).sum())
    over = ~(r["effort"] <= 1.0)
    return {"label": label, "grasps": len(y), "pass": float(y.mean()),
            "auc_effort": auc(r["effort"], y), "auc_grip_ratio": auc(ratio, y),
            "auc_epsilon": auc(-r["epsilon"], y), "effort_over_1": float(over.mean()),
            "effort_over_1_passed": int((over & y).sum()), "squeeze_ge_grip": float(pred.mean()),
            "precision": tp / max(tp + fp, 1), "recall": tp / max(tp + fn, 1),
            "grip_inf": float(np.mean(~np.isfinite(ratio))),
            "passing_by_fingers": dict(sorted(Counter(int(k) for k in r["fingers"][y]).items()))}


def line(row: dict[str, Any]) -> str:
    """The Markdown row of :func:`stats`'s dict."""
    fingers = " ".join(f"{k}:{v}" for k, v in row["passing_by_fingers"].items())
    return (f"| {row['label']} | {row['grasps']} | {row['pass']:.1%} | {row['auc_effort']:.2f} | "
            f"{row['auc_grip_ratio']:.2f} | {row['auc_epsilon']:.2f} | {row['effort_over_1']:.1%} "
            f"({row['effort_over_1_passed']} passed) | {row['squeeze_ge_grip']:.1%} | "
            f"{row['precision']:.1%} | {row['recall']:.1%} | {row['grip_inf']:.1%} | {fingers} |")


#: effort bin edges of ``--bins`` (fraction of the force limits; 1: the actuators' limit)
EFFORT_BINS = (0.0, 0.1, 0.2, 0.25, 0.3, 0.4, 0.5, 0.75, 1.0)


def effort_bins(effort: np.ndarray, passed: np.ndarray) -> list[str]:
    """Markdown rows: grasps, passes and pass rate per actuator-effort bin of
    :data:`EFFORT_BINS` (the last bin closed), pooled over every dataset given."""
    rows = []
    last = EFFORT_BINS[-1]
    for lo, hi in pairwise(EFFORT_BINS):
        inside = (effort >= lo) & ((effort < hi) if hi < last else (effort <= hi))
        rate = f"{passed[inside].mean():.1%}" if inside.any() else "–"
        rows.append(f"| [{lo:g}, {hi:g}{']' if hi == last else ')'} | {int(inside.sum())} | "
                    f"{int(passed[inside].sum())} | {rate} |")
    return rows


def logistic_fit(effort: np.ndarray, passed: np.ndarray) -> tuple[float, float]:
    """(a, b) of the maximum-likelihood fit p(pass) = σ(a + b·effort) over the finite efforts."""
    ok = np.isfinite(effort)
    e, y = effort[ok], passed[ok].astype(float)

    def nll(w: np.ndarray) -> float:
        z = w[0] + w[1] * e
        return float(np.sum(np.logaddexp(0.0, z) - y * z))

    a, b = minimize(nll, np.zeros(2)).x
    return float(a), float(b)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("datasets", nargs="+", type=Path)
    ap.add_argument("--bins", action="store_true",
                    help="also the pooled pass rate by actuator effort (default: off)")
    args = ap.parse_args()
    cfg = ValidateConfig.load()
    rows = [r for path in args.datasets for r in rows_of(path, cfg)]
    print("| dataset / object | grasps | pass | AUC effort | AUC grip ratio | AUC ε | effort > 1 | "
          "squeeze ≥ grip | precision | recall | grip inf | fingers of passing grasps |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    table = []
    for r in rows:
        table.append({"source": r["source"], "object": r["object"], "protocol": r["protocol"],
                      **stats(f"{r['source']} / {r['object']} ({r['protocol']})", r)})
        print(line(table[-1]))
    keys = ("ratio", "budget", "passed", "fingers", "epsilon", "effort")
    pooled = {k: np.concatenate([r[k] for r in rows]) for k in keys}
    table.append({"source": "all", **stats(f"all ({len({r['object'] for r in rows})} objects)",
                                           pooled)})
    print(line(table[-1]))
    summary: dict[str, Any] = {"all": table[-1]}
    if args.bins:
        print("\n| actuator effort | grasps | passed | pass rate |\n|---|---|---|---|")
        bins = effort_bins(pooled["effort"], pooled["passed"])
        print("\n".join(bins))
        a, b = logistic_fit(pooled["effort"], pooled["passed"])
        crossings = {p: (np.log(p / (1 - p)) - a) / b for p in (0.5, 0.3, 0.29, 0.2)}
        cross = ", ".join(f"{p:g} at {e:.3f}" for p, e in crossings.items())
        print(f"\nlogistic fit: p(pass) = σ({a:.2f} {b:+.2f}·effort); p crosses {cross}")
        summary.update(effort_bins_markdown=bins, logistic_a=a, logistic_b=b,
                       effort_at_pass_chance={str(p): e for p, e in crossings.items()})
    path = write_record("grip_predictor", table, summary=summary, config=vars(args),
                        objects=sorted({r["object"] for r in rows}))
    print(f"record: {path}")


if __name__ == "__main__":
    main()
