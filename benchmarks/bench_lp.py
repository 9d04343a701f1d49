"""How long one holding LP takes: ``scipy.optimize.linprog`` per load against
:class:`sim.metrics.lp.EqualityLP` (HiGHS directly, one model per contact set, re-solved per load).

The least-grip programme of :func:`sim.metrics.holding.min_grip_forces_n` for the benchmark's six
1 N pushes, on random contact sets of 2, 3 and 5 soft contacts (μ 0.6, torsional 0.02 m, as
``[dgb]``), solved both ways; prints milliseconds per load and checks that both give the same
optima (infeasible loads included). The rows go to a record as well
(:func:`benchmarks.record.write_record`, ``benchmarks/measured/lp/``).

    .venv/bin/python benchmarks/bench_lp.py [--sets 200]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linprog

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.record import write_record
from sim.metrics.holding import _contact_columns, min_grip_forces_n

PUSHES = np.vstack([np.hstack([s * np.eye(3)[k], np.zeros(3)]) for k in range(3) for s in (-1.0, 1.0)])


def _scipy(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    a_eq, _, torsion = _contact_columns(points, normals, np.zeros(3), 0.6, 0.02, 8)
    cost = np.zeros(a_eq.shape[1])
    cost[:len(points) * 8] = 1.0
    out = []
    for load in PUSHES:
        res = linprog(cost, A_ub=torsion, b_ub=np.zeros(len(points)), A_eq=a_eq, b_eq=-load,
                      bounds=(0, None), method="highs")
        out.append(res.fun if res.status == 0 else np.inf)
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", type=int, default=200, help="contact sets per size (default 200)")
    args = ap.parse_args()
    print("| contacts | linprog, ms per load | EqualityLP, ms per load | speed-up | same optima |")
    print("|---|---|---|---|---|")
    rows = []
    for n in (2, 3, 5):
        rng = np.random.default_rng(n)
        sets = []
        for _ in range(args.sets):
            p = rng.normal(size=(n, 3)) * 0.03
            sets.append((p, -p / np.linalg.norm(p, axis=1, keepdims=True)))
        t0 = time.perf_counter()
        ref = [_scipy(p, nrm) for p, nrm in sets]
        t_ref = (time.perf_counter() - t0) / (len(sets) * len(PUSHES))
        t0 = time.perf_counter()
        got = [min_grip_forces_n(p, nrm, np.zeros(3), PUSHES, 0.6, 0.02) for p, nrm in sets]
        t_new = (time.perf_counter() - t0) / (len(sets) * len(PUSHES))
        same = all(np.allclose(a, b, rtol=1e-7, atol=1e-9) for a, b in zip(ref, got, strict=True))
        print(f"| {n} | {1e3 * t_ref:.3f} | {1e3 * t_new:.3f} | {t_ref / t_new:.1f}× | {same} |")
        rows.append({"contacts": n, "linprog_ms_per_load": 1e3 * t_ref,
                     "equality_lp_ms_per_load": 1e3 * t_new, "speed_up": t_ref / t_new,
                     "same_optima": same})
    path = write_record("lp", rows, config={**vars(args), "loads": len(PUSHES)})
    print(f"record: {path}")


if __name__ == "__main__":
    main()
