"""The holding metrics' LPs through HiGHS directly (sim/metrics/lp.py) give the optima that
``scipy.optimize.linprog`` gives for the same programmes, load by load, infeasible loads
included, and HiGHS's banner never reaches standard output."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import linprog

from sim.metrics.holding import _contact_columns, min_actuator_efforts, min_grip_force_n, min_grip_forces_n
from sim.metrics.lp import EqualityLP

#: the benchmark's six pushes of 1 N and a weight, with a torque on the last
LOADS = np.array([[-1, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0], [0, -1, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0],
                  [0, 0, -1, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, -2.0, 0.01, 0, 0]], dtype=float)


def _contacts(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    points = rng.normal(size=(n, 3)) * 0.03
    return points, -points / np.linalg.norm(points, axis=1, keepdims=True)


def _linprog_grip(points: np.ndarray, normals: np.ndarray, load: np.ndarray, mu: float,
                  mu_t: float) -> float:
    a_eq, _, torsion = _contact_columns(points, normals, np.zeros(3), mu, mu_t, 8)
    cost = np.zeros(a_eq.shape[1])
    cost[:len(points) * 8] = 1.0
    res = linprog(cost, A_ub=torsion, b_ub=None if torsion is None else np.zeros(len(points)),
                  A_eq=a_eq, b_eq=-load, bounds=(0, None), method="highs")
    return float(res.fun) if res.status == 0 else float("inf")


@pytest.mark.parametrize("n_contacts", [2, 3, 5])
@pytest.mark.parametrize("mu_t", [0.0, 0.02])
def test_grip_forces_match_linprog_load_by_load(n_contacts: int, mu_t: float) -> None:
    rng = np.random.default_rng(n_contacts)
    infeasible = 0
    for _ in range(5):
        points, normals = _contacts(rng, n_contacts)
        got = min_grip_forces_n(points, normals, np.zeros(3), LOADS, 0.6, mu_t)
        want = np.array([_linprog_grip(points, normals, load, 0.6, mu_t) for load in LOADS])
        assert np.array_equal(np.isinf(got), np.isinf(want))
        np.testing.assert_allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=1e-7,
                                   atol=1e-9)
        assert min_grip_force_n(points, normals, np.zeros(3), LOADS[2], 0.6, mu_t) == \
            pytest.approx(want[2], rel=1e-7)
        infeasible += int(np.isinf(want).sum())
    if n_contacts == 2:   # two random contacts hold few of these loads: both answers were met
        assert infeasible > 0


def test_actuator_efforts_match_linprog() -> None:
    rng = np.random.default_rng(7)
    points, normals = _contacts(rng, 3)
    per = rng.normal(size=(4, 3, 3)) * 0.05             # 4 actuators' N·m per newton at each contact
    limit = np.array([3.0, 3.0, 1.0, np.inf])           # the unlimited one is left out
    got = min_actuator_efforts(points, normals, np.zeros(3), LOADS, 0.6, per, limit, 0.02)
    a_eq, edges, torsion = _contact_columns(points, normals, np.zeros(3), 0.6, 0.02, 8)
    u = np.einsum("uek,ek->ue", per[:3][:, np.repeat(np.arange(3), 8)], edges)
    v = a_eq.shape[1]
    u_cols = np.zeros((3, v + 1))
    u_cols[:, :24], u_cols[:, v] = u, -limit[:3]
    a_ub = np.vstack([u_cols, np.hstack([-u_cols[:, :v], -limit[:3, None]]),
                      np.hstack([torsion, np.zeros((3, 1))])])
    cost = np.zeros(v + 1)
    cost[v] = 1.0
    for k, load in enumerate(LOADS):
        res = linprog(cost, A_ub=a_ub, b_ub=np.zeros(len(a_ub)), A_eq=np.hstack([a_eq, np.zeros((6, 1))]),
                      b_eq=-load, bounds=(0, None), method="highs")
        assert got[k] == (pytest.approx(res.fun, rel=1e-7) if res.status == 0 else float("inf"))


def test_an_infeasible_load_does_not_spoil_the_next() -> None:
    # x ≥ 0 and x₀ + x₁ = b: b < 0 is infeasible, the rest have optimum b (cost 1, 1)
    lp = EqualityLP(np.array([1.0, 1.0]), np.array([[1.0, 1.0]]))
    np.testing.assert_array_equal(lp.minima(np.array([[2.0], [-1.0], [3.0], [-5.0], [0.5]])),
                                  [2.0, np.inf, 3.0, np.inf, 0.5])


def test_highs_prints_nothing_to_stdout() -> None:
    code = ("import numpy as np; from sim.metrics.holding import min_grip_force_n; "
            "min_grip_force_n([[0.03, 0, 0], [-0.03, 0, 0]], [[-1, 0, 0], [1, 0, 0]], np.zeros(3), "
            "[0, 0, -1, 0, 0, 0], 0.6)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout == ""
