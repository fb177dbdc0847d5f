"""The compiled simplex method against HiGHS (the reference) on random small LPs of the grip
objective's form: ``min c^T x s.t. A_eq x = b_eq, A_ub x <= b_ub, x >= 0``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from grasp_env.solvers import simplex


def random_lp(rng: np.random.Generator):
    """3 equality rows and 0-4 inequality rows over 1-10 variables of order-one data;
    a third of the problems made feasible by construction around a positive point, some
    with a zero or negative right-hand side, duplicated rows or columns."""
    n = int(rng.integers(1, 11))
    m_ub = int(rng.integers(0, 5))
    A_eq = rng.normal(size=(3, n))
    A_ub = rng.normal(size=(m_ub, n))
    c = rng.uniform(0.0, 2.0, n) if rng.random() < 0.8 else rng.normal(size=n)
    if rng.random() < 0.5:
        x0 = rng.uniform(0.0, 1.0, n) * (rng.random(n) < 0.7)
        b_eq = A_eq @ x0
        b_ub = A_ub @ x0 + rng.uniform(0.0, 0.5, m_ub) * (rng.random(m_ub) < 0.7)
    else:
        b_eq, b_ub = rng.normal(size=3), rng.normal(size=m_ub)
    if n > 1 and rng.random() < 0.2:
        A_eq[:, -1], A_ub[:, -1], c[-1] = A_eq[:, 0], A_ub[:, 0], c[0]
    if rng.random() < 0.1:
        A_eq[2], b_eq[2] = A_eq[0], b_eq[0]
    return c, A_eq, b_eq, A_ub, b_ub


def test_matches_highs_on_random_problems() -> None:
    rng = np.random.default_rng(11)
    counts = {"optimal": 0, "infeasible": 0, "unbounded": 0}
    for _ in range(600):
        c, A_eq, b_eq, A_ub, b_ub = random_lp(rng)
        status, x, value = simplex.solve(c, A_eq, b_eq, A_ub, b_ub, 1e-10)
        ref = linprog(
            c, A_ub=A_ub if len(A_ub) else None, b_ub=b_ub if len(A_ub) else None,
            A_eq=A_eq, b_eq=b_eq, bounds=(0, None), method="highs",
        )  # fmt: skip
        name = simplex.STATUS_NAMES[status]
        assert name == {0: "optimal", 2: "infeasible", 3: "unbounded"}[ref.status]
        counts[name] += 1
        if name == "optimal":
            assert value == pytest.approx(ref.fun, rel=1e-8, abs=1e-8)
            assert np.all(x >= 0.0)
            np.testing.assert_allclose(A_eq @ x, b_eq, atol=1e-8)
            assert np.all(A_ub @ x <= b_ub + 1e-8)
    assert min(counts.values()) >= 20, counts


def test_degenerate_vertex_does_not_cycle() -> None:
    """Beale's classic cycling example (textbook simplex with the largest-coefficient rule
    cycles on it); Bland's rule reaches the optimum -0.05."""
    c = np.array([-0.75, 150.0, -0.02, 6.0])
    A_ub = np.array([[0.25, -60.0, -0.04, 9.0], [0.5, -90.0, -0.02, 3.0], [0.0, 0.0, 1.0, 0.0]])
    b_ub = np.array([0.0, 0.0, 1.0])
    status, x, value = simplex.solve(c, np.zeros((0, 4)), np.zeros(0), A_ub, b_ub, 1e-12)
    assert status == simplex.OPTIMAL
    assert value == pytest.approx(-0.05, rel=1e-12)
    np.testing.assert_allclose(x, [0.04, 0.0, 1.0, 0.0], atol=1e-12)
