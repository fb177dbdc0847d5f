"""Tiny exact least-norm problems in three variables, by enumerating active sets.

``min 1/2 |w|^2  s.t.  A w = b,  C w >= d`` with ``w`` in R^3 has at most three independent
active rows at the optimum, so trying every small active set and keeping the one that meets
the KKT conditions solves it exactly. The simulator uses it for the least-motion object
velocity on the LP's optimal face and for the steepest admissible descent of a fall.

Active sets are tried by size (0 to 3), each size's in lexicographic order; a set counts
when its rows are consistent (least-norm solution of the equalities and those rows, by
:func:`grasp_env.solvers.dense.lstsq` on the rows themselves, not their Gram matrix, whose
condition number is squared), the solution satisfies every inequality and the set's
multipliers are non-negative, all to within ``tol`` times the problem's scale. The first
size with a set that counts gives the answer: among its sets, the smallest ``|w|^2``, a
later set replacing an earlier one only when smaller by more than 1e-15.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.solvers import dense

#: Relative cut-off of singular values in the active sets' least-squares solves.
RCOND = 1e-13
#: A later active set wins a tie only when its ``|w|^2`` is smaller by more than this.
TIE = 1e-15


@njit(cache=CACHE)
def _scale(b: np.ndarray, d: np.ndarray) -> float:
    """``max(1, max |b|, max |d|)``, the scale of the tolerances."""
    out = 1.0
    if b.shape[0] > 0:
        top = np.abs(b).max()
        if top > out:
            out = top
    if d.shape[0] > 0:
        top = np.abs(d).max()
        if top > out:
            out = top
    return out


@njit(cache=CACHE, inline="always")
def _row_dot(A: np.ndarray, i: int, w: np.ndarray) -> float:
    """``A[i] . w``, summed in column order (:func:`grasp_env.solvers.dense.matvec`'s)."""
    acc = 0.0
    for j in range(A.shape[1]):
        acc += A[i, j] * w[j]
    return acc


@njit(cache=CACHE, inline="always")
def _residual_squares(A: np.ndarray, w: np.ndarray, b: np.ndarray) -> float:
    """``|A w - b|^2`` in :func:`grasp_env.solvers.dense.matvec`'s and ``dot``'s order,
    without their arrays."""
    out = 0.0
    for i in range(A.shape[0]):
        r = _row_dot(A, i, w) - b[i]
        out += r * r
    return out


@njit(cache=CACHE)
def _try(
    A: np.ndarray, b: np.ndarray, C: np.ndarray, d: np.ndarray, S: np.ndarray, thr: float
) -> tuple[np.ndarray, bool]:
    """Least-norm ``w`` with the equalities and the inequality rows ``S`` active, and whether
    it is optimal: the rows consistent, every inequality met and the multipliers of ``S``
    non-negative, to within ``thr``."""
    m, size = A.shape[0], S.shape[0]
    rows = m + size
    AS = np.empty((rows, 3))
    if rows == 0:
        w = np.zeros(3)
    else:
        bS = np.empty(rows)
        AS[:m] = A
        bS[:m] = b
        for i in range(size):
            AS[m + i] = C[S[i]]
            bS[m + i] = d[S[i]]
        w = dense.lstsq(AS, bS, RCOND)[0]
        if math.sqrt(_residual_squares(AS, w, bS)) > thr:
            return w, False
    for i in range(C.shape[0]):
        if _row_dot(C, i, w) - d[i] < -thr:
            return w, False
    if size > 0:
        mu = dense.lstsq(AS.T.copy(), w, RCOND)[0]  # w = AS^T mu
        if mu[m:].min() < -thr:
            return w, False
    return w, True


@njit(cache=CACHE)
def least_norm(
    A: np.ndarray, b: np.ndarray, C: np.ndarray, d: np.ndarray, tol: float
) -> tuple[np.ndarray, bool]:
    """Solve ``min 1/2 |w|^2 s.t. A w = b, C w >= d`` for ``w`` in R^3.

    ``A`` (m, 3), ``b`` (m,), ``C`` (k, 3), ``d`` (k,); ``tol`` is the feasibility and
    multiplier tolerance relative to ``max(1, |b|, |d|)`` (largest entries). Returns ``w``
    and True, or zeros and False when no active set is feasible (the problem is infeasible).
    """
    thr = tol * _scale(b, d)
    k = C.shape[0]
    best_w = np.zeros(3)
    best = np.inf
    found = False
    S = np.empty(3, dtype=np.int64)
    for size in range(min(3, k) + 1):
        for i in range(size):
            S[i] = i
        while True:
            w, ok = _try(A, b, C, d, S[:size], thr)
            if ok:
                nrm = dense.dot(w, w)
                if not found or nrm < best - TIE:
                    best_w, best, found = w, nrm, True
            # next combination in lexicographic order
            i = size - 1
            while i >= 0 and S[i] == k - size + i:
                i -= 1
            if i < 0:
                break
            S[i] += 1
            for j in range(i + 1, size):
                S[j] = S[j - 1] + 1
        if found:
            return best_w, True
    return np.zeros(3), False
