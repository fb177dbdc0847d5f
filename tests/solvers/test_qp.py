"""The least-norm QP (:func:`grasp_env.solvers.qp.least_norm`) against scipy's SLSQP and an
independent KKT check, on random feasible problems, on degenerate ones (dependent and
repeated rows, more active rows than variables) and on infeasible ones (Farkas
certificates, inconsistent equalities)."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from qp_checks import kkt_violation, slsqp

from grasp_env.errors import SolverError
from grasp_env.solvers import qp

NONE = (np.zeros((0, 3)), np.zeros(0))


def feasible_problem(rng: np.random.Generator):
    """0-2 equality and 0-6 inequality rows through a random point ``w0`` (inequalities
    slack by 0, 0.1 or 1 there), rows well conditioned in every small active set."""
    while True:
        m, k = int(rng.integers(0, 3)), int(rng.integers(0, 7))
        A, C = rng.normal(size=(m, 3)), rng.normal(size=(k, 3))
        w0 = rng.normal(size=3) * 2
        rows = np.vstack([A, C])
        if len(rows) and np.linalg.norm(rows, axis=1).min() < 0.2:
            continue
        sets = [
            np.vstack([A, C[list(S)]]) for size in range(4) for S in combinations(range(k), size)
        ]
        if all(len(M) == 0 or _condition(M) < 100.0 for M in sets):
            return A, A @ w0, C, C @ w0 - rng.choice([0.0, 0.1, 1.0], size=k), w0


def _condition(M: np.ndarray) -> float:
    """Condition number of ``M`` restricted to its first ``min(rows, 3)`` singular values."""
    s = np.linalg.svd(M, compute_uv=False)
    return float(s[0] / s[min(len(M), 3) - 1])


def test_random_feasible_problems_meet_kkt_and_match_slsqp() -> None:
    rng = np.random.default_rng(0)
    compared = 0
    for _ in range(200):
        A, b, C, d, w0 = feasible_problem(rng)
        w = qp.least_norm(A, b, C, d)
        assert w.shape == (3,)
        assert kkt_violation(w, A, b, C, d) < 1e-8
        ref = slsqp(A, b, C, d, w0)
        if ref is not None and kkt_violation(ref, A, b, C, d, 1e-7) < 1e-7:
            np.testing.assert_allclose(w, ref, atol=1e-7)
            compared += 1
    assert compared > 150


@pytest.mark.parametrize(
    ("A", "b", "C", "d", "expected"),
    [
        # a repeated inequality, active
        (*NONE, np.array([[1.0, 1, 0], [1.0, 1, 0]]), np.array([2.0, 2.0]), [1, 1, 0]),
        # a repeated inequality, scaled, with a redundant parallel one
        (
            *NONE,
            np.array([[0, 0, 1.0], [0, 0, 2.0], [0, 0, 1.0]]),
            np.array([1.0, 2.0, -5.0]),
            [0, 0, 1],
        ),
        # four rows active at the optimum (more than the three variables)
        (
            *NONE,
            np.array([[1.0, 0, 0], [1, 1, 0], [1, -1, 0], [1, 0, 1]]),
            np.ones(4),
            [1, 0, 0],
        ),
        # dependent consistent equalities
        (np.array([[1.0, 1, 0], [2, 2, 0]]), np.array([1.0, 2.0]), *NONE, [0.5, 0.5, 0]),
        # an inequality repeating an equality
        (
            np.array([[0, 1.0, 0]]),
            np.array([1.0]),
            np.array([[0, 1.0, 0], [1, 0, 0]]),
            np.array([1.0, -1.0]),
            [0, 1, 0],
        ),
        # an inequality opposite to an equality (both active, multiplier of either sign)
        (
            np.array([[1.0, 0, 1]]),
            np.array([2.0]),
            np.array([[-1.0, 0, -1]]),
            np.array([-2.0]),
            [1, 0, 1],
        ),
        # three equalities of rank 2 and an active inequality
        (
            np.array([[1.0, 0, 0], [0, 1, 0], [1, 1, 0]]),
            np.array([1.0, 1.0, 2.0]),
            np.array([[0, 0, 1.0]]),
            np.array([3.0]),
            [1, 1, 3],
        ),
    ],
    ids=[
        "repeated",
        "scaled_and_redundant",
        "four_active",
        "dependent_equalities",
        "inequality_repeats_equality",
        "inequality_opposes_equality",
        "rank_deficient_equalities",
    ],
)
def test_degenerate_problems(A, b, C, d, expected) -> None:
    w = qp.least_norm(A, b, C, d)
    np.testing.assert_allclose(w, expected, atol=1e-12)
    assert kkt_violation(w, A, b, C, d) < 1e-12


def test_random_degenerate_problems_meet_kkt() -> None:
    """Random problems with repeated, scaled and opposite rows, and rows through the origin
    of the optimum's neighbourhood (many active at once)."""
    rng = np.random.default_rng(1)
    for _ in range(200):
        base = rng.normal(size=(3, 3))
        C = np.vstack([base, base[rng.integers(3, size=3)] * rng.choice([1.0, 2.0], size=(3, 1))])
        w0 = rng.normal(size=3)
        d = C @ w0 - rng.choice([0.0, 0.5], size=6)
        A = base[:1] if rng.random() < 0.5 else np.zeros((0, 3))
        b = A @ w0
        w = qp.least_norm(A, b, C, d)
        assert kkt_violation(w, A, b, C, d, 1e-8) < 1e-8


@pytest.mark.parametrize(
    ("A", "b", "C", "d"),
    [
        (*NONE, np.array([[1.0, 0, 0], [-1.0, 0, 0]]), np.array([1.0, 0.0])),
        (np.array([[1.0, 0, 0], [2.0, 0, 0]]), np.array([1.0, 3.0]), *NONE),
        (np.array([[1.0, 0, 0]]), np.array([0.0]), np.array([[1.0, 0, 0]]), np.array([1.0])),
        (np.zeros((1, 3)), np.array([1.0]), *NONE),
    ],
    ids=["opposite_inequalities", "inconsistent_equalities", "equality_vs_inequality", "0=1"],
)
def test_infeasible_raises(A, b, C, d) -> None:
    with pytest.raises(SolverError) as exc:
        qp.least_norm(A, b, C, d)
    assert exc.value.status == "infeasible"


def test_random_infeasible_problems_raise() -> None:
    """``C`` with ``y >= 0``, ``C^T y = 0`` and ``d . y > 0`` (a Farkas certificate): no
    ``w`` has ``C w >= d``."""
    rng = np.random.default_rng(2)
    for _ in range(100):
        k = int(rng.integers(2, 6))
        C = rng.normal(size=(k, 3))
        y = rng.uniform(0.5, 2.0, size=k)
        C[-1] = -(y[:-1] @ C[:-1]) / y[-1]
        d = rng.normal(size=k)
        d[-1] = (0.1 - y[:-1] @ d[:-1]) / y[-1]  # d . y = 0.1
        with pytest.raises(SolverError):
            qp.least_norm(np.zeros((0, 3)), np.zeros(0), C, d)


def test_equalities_only_give_the_pseudo_inverse_solution() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        A = rng.normal(size=(int(rng.integers(1, 3)), 3))
        b = rng.normal(size=len(A))
        np.testing.assert_allclose(qp.least_norm(A, b, *NONE), np.linalg.pinv(A) @ b, atol=1e-12)


def test_inputs_of_any_layout_and_dtype() -> None:
    """Views, integer rows and lists give the same bits as contiguous float arrays."""
    C = np.array([[1, 1, 0, 9], [0, 1, 1, 9], [3, 0, 1, 9]])[:, :3]
    d = np.array([1, 2, 3])
    w = qp.least_norm(np.zeros((0, 3)), [], C, d)
    assert np.array_equal(w, qp.least_norm(*NONE, np.array(C, dtype=float), d.astype(float)))
    assert kkt_violation(w, *NONE, C.astype(float), d.astype(float)) < 1e-12


def test_loose_tolerance_takes_the_smallest_norm_set_then_the_first() -> None:
    """With ``tol = 0.05`` both single rows of ``x >= 1``-like pairs pass the checks (the
    other row violated by under 0.05): the smaller ``|w|^2`` wins, and of two equal ones the
    first in order; the exact optimum (both rows active, a set of size 2) is not reached."""
    C, d = np.array([[1.0, 0, 0], [1.0, 0.1, 0]]), np.ones(2)
    np.testing.assert_allclose(qp.least_norm(*NONE, C, d, 0.05), C[1] / 1.01, atol=1e-15)
    C = np.array([[1.0, 0.1, 0], [1.0, -0.1, 0]])
    np.testing.assert_allclose(qp.least_norm(*NONE, C, d, 0.05), C[0] / 1.01, atol=1e-15)
    np.testing.assert_allclose(qp.least_norm(*NONE, C, d), [1, 0, 0], atol=1e-15)
