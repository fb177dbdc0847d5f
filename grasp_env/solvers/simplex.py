"""A compiled dense simplex method for the analysis's small LPs (the grip objective y*).

``min c^T x  s.t.  A_eq x = b_eq,  A_ub x <= b_ub,  x >= 0`` with a handful of rows and
columns (y* has 3 equality rows, up to 4 torque rows and one column per contact). HiGHS
(:func:`grasp_env.solvers.lp.solve`) solves the same problems in a millisecond, most of it the call;
this tableau simplex takes microseconds and needs no BLAS, so its answer is the same on every
machine. HiGHS stays the reference the tests compare it with.

Method: two phases on one tableau (artificial variables on every row, rows with a negative
right-hand side negated first); Bland's rule (the lowest-index improving column, the
lowest-index basic variable among tied ratios), which cannot cycle. The data should be of
order one (the caller scales it), since ``tol`` is absolute: reduced costs below ``-tol``
improve, pivots need a coefficient above ``tol``, and phase one's residual must be within
``tol`` times the right-hand side's size for the problem to be feasible.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE

OPTIMAL, INFEASIBLE, UNBOUNDED, ITERATION_LIMIT = 0, 1, 2, 3
STATUS_NAMES = ("optimal", "infeasible", "unbounded", "iteration_limit")


@njit(cache=CACHE)
def _pivot(T: np.ndarray, row: int, col: int) -> None:
    """Make column ``col`` basic in ``row``; a basic value below zero by rounding is zero."""
    T[row] /= T[row, col]
    for i in range(T.shape[0]):
        if i != row and T[i, col] != 0.0:
            T[i] -= T[i, col] * T[row]
    for i in range(T.shape[0] - 1):
        if T[i, -1] < 0.0:
            T[i, -1] = 0.0


@njit(cache=CACHE)
def _iterate(T: np.ndarray, basis: np.ndarray, allowed: int, tol: float, limit: int) -> int:
    """Bland's-rule pivots on tableau ``T`` (objective in the last row, right-hand side in
    the last column) over the first ``allowed`` columns, until optimal or unbounded."""
    m = T.shape[0] - 1
    for _ in range(limit):
        col = -1
        for j in range(allowed):
            if T[m, j] < -tol:
                col = j
                break
        if col < 0:
            return OPTIMAL
        row, best = -1, np.inf
        for i in range(m):
            if T[i, col] > tol:
                ratio = T[i, -1] / T[i, col]
                if ratio < best or (ratio == best and basis[i] < basis[row]):
                    row, best = i, ratio
        if row < 0:
            return UNBOUNDED
        _pivot(T, row, col)
        basis[row] = col
    return ITERATION_LIMIT


@njit(cache=CACHE)
def solve(
    c: np.ndarray, A_eq: np.ndarray, b_eq: np.ndarray, A_ub: np.ndarray, b_ub: np.ndarray,
    tol: float,
) -> tuple[int, np.ndarray, float]:  # fmt: skip
    """``(status, x, value)`` of ``min c^T x s.t. A_eq x = b_eq, A_ub x <= b_ub, x >= 0``
    (status codes :data:`OPTIMAL` ...; ``x`` and ``value`` meaningful when optimal)."""
    n = c.shape[0]
    m_eq, m_ub = A_eq.shape[0], A_ub.shape[0]
    m = m_eq + m_ub
    n_real = n + m_ub  # variables and slacks; artificials follow
    T = np.zeros((m + 1, n_real + m + 1))
    size = 0.0
    for i in range(m):
        if i < m_eq:
            T[i, :n] = A_eq[i]
            T[i, -1] = b_eq[i]
        else:
            T[i, :n] = A_ub[i - m_eq]
            T[i, n + i - m_eq] = 1.0
            T[i, -1] = b_ub[i - m_eq]
        if T[i, -1] < 0.0:
            T[i, :n_real] = -T[i, :n_real]
            T[i, -1] = -T[i, -1]
        T[i, n_real + i] = 1.0
        size = max(size, T[i, -1])
    basis = np.arange(n_real, n_real + m)
    limit = 50 * (n_real + m + 1)
    # phase one: minimise the sum of the artificials
    for i in range(m):
        T[m] -= T[i]
    for i in range(m):
        T[m, n_real + i] = 0.0
    status = _iterate(T, basis, n_real, tol, limit)
    if status == ITERATION_LIMIT:
        return status, np.zeros(n), np.nan
    if -T[m, -1] > tol * max(size, 1.0):
        return INFEASIBLE, np.zeros(n), np.inf
    # artificials left in the basis at zero: swap each for the real column with the row's
    # largest entry (a tiny pivot would scale the rounding of every other row up); a row
    # with none above tol is redundant
    for i in range(m):
        if basis[i] >= n_real:
            best, col = tol, -1
            for j in range(n_real):
                if abs(T[i, j]) > best:
                    best, col = abs(T[i, j]), j
            if col >= 0:
                _pivot(T, i, col)
                basis[i] = col
    # phase two: the real objective, reduced over the current basis
    T[m] = 0.0
    T[m, :n] = c
    for i in range(m):
        if basis[i] < n:
            T[m] -= c[basis[i]] * T[i]
    status = _iterate(T, basis, n_real, tol, limit)
    x = np.zeros(n)
    for i in range(m):
        if basis[i] < n:
            x[basis[i]] = T[i, -1]
    if status != OPTIMAL:
        return status, x, -np.inf if status == UNBOUNDED else np.nan
    value = 0.0
    for j in range(n):
        value += c[j] * x[j]
    return OPTIMAL, x, value
