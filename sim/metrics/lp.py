"""One small linear programme solved for many right-hand sides: HiGHS, model built once.

Why: the holding metrics (:mod:`sim.metrics.holding`) solve the same contact LP once per load
(six pushes for the benchmark), for every grasp FSG accepts and for every squeeze the
validator sizes. Through ``scipy.optimize.linprog`` each solve costs ≈ 1.5 ms, almost all of it
input checking and model set-up, and those solves were most of FSG's time for ``dgb``
(``benchmarks/bench_lp.py``). Here the model is passed to HiGHS (the solver ``linprog``'s
``"highs"`` method runs too) once per contact set; each load changes only the equality rows'
bounds, and HiGHS re-solves from the previous basis.

The programme: minimise ``cost · x`` subject to ``a_eq x = b`` (one ``b`` per solve),
``a_ub x ≤ 0`` and ``x ≥ 0``. Its optimum is returned, ``inf`` when infeasible.
"""

from __future__ import annotations

import os
import sys
import threading

import highspy
import numpy as np

__all__ = ["EqualityLP"]

_local = threading.local()


def _solver() -> highspy.Highs:
    """This thread's HiGHS instance, silent. HiGHS prints a banner to the process's standard
    output when its first instance is built, which would end up in the CLI's output (JSON
    included), so that construction runs with file descriptor 1 pointed at /dev/null."""
    h = getattr(_local, "highs", None)
    if h is None:
        sys.stdout.flush()
        saved, null = os.dup(1), os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 1)
            h = highspy.Highs()
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            os.close(null)
        h.setOptionValue("output_flag", False)
        _local.highs = h
    return h


class EqualityLP:
    """``min cost·x  s.t.  a_eq x = b,  a_ub x ≤ 0,  x ≥ 0`` for any ``b`` (module docstring).

    Args:
        cost: (V,) objective coefficients.
        a_eq: (E, V) equality rows.
        a_ub: (U, V) rows bounded above by 0, or None.
    """

    def __init__(self, cost: np.ndarray, a_eq: np.ndarray, a_ub: np.ndarray | None = None) -> None:
        a_eq = np.asarray(a_eq, dtype=float)
        rows = a_eq if a_ub is None else np.vstack([a_eq, np.asarray(a_ub, dtype=float)])
        n_eq, (n_rows, n_vars) = len(a_eq), rows.shape
        inf = highspy.kHighsInf
        lp = highspy.HighsLp()
        lp.num_col_, lp.num_row_ = n_vars, n_rows
        lp.col_cost_ = np.asarray(cost, dtype=float)
        lp.col_lower_, lp.col_upper_ = np.zeros(n_vars), np.full(n_vars, inf)
        lp.row_lower_ = np.r_[np.zeros(n_eq), np.full(n_rows - n_eq, -inf)]
        lp.row_upper_ = np.zeros(n_rows)
        nz_row, nz_col = np.nonzero(rows)
        lp.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
        lp.a_matrix_.start_ = np.r_[0, np.cumsum(np.bincount(nz_row, minlength=n_rows))].astype(np.int32)
        lp.a_matrix_.index_ = nz_col.astype(np.int32)
        lp.a_matrix_.value_ = rows[nz_row, nz_col]
        self._lp, self._eq_rows = lp, np.arange(n_eq, dtype=np.int32)

    def minima(self, rhs: np.ndarray) -> np.ndarray:
        """(k,) optimum per row of ``rhs`` (k, E) — ``inf`` where infeasible — solved in order,
        each from the previous one's basis."""
        rhs = np.asarray(rhs, dtype=float).reshape(-1, len(self._eq_rows))
        h = _solver()
        h.passModel(self._lp)
        out = np.full(len(rhs), np.inf)
        for k, b in enumerate(rhs):
            # the binding has it (highspy 1.16) but its stub file (_core/__init__.pyi) leaves it out
            h.changeRowsBounds(len(b), self._eq_rows, b, b)  # type: ignore[attr-defined]
            h.run()
            if h.getModelStatus() == highspy.HighsModelStatus.kOptimal:
                out[k] = h.getInfo().objective_function_value
        return out
