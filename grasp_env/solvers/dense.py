"""Small dense linear algebra without BLAS or LAPACK, compiled with numba.

The simulator's matrices are tiny (3 to 6 rows or columns), and its discrete decisions
(contact sets, jams, falls) compare results with tolerances. numpy's ``@``, ``dot``,
``linalg`` and scipy's ``nnls`` go through the machine's BLAS/LAPACK, whose kernels round
differently from one processor (or ``OPENBLAS_CORETYPE``) to another, so a decision near a
threshold could flip with the machine. Every routine here is plain arithmetic in a fixed
order: the same inputs give the same bits on every machine (numba does not contract
multiply-adds into FMAs without ``fastmath``). With ``NUMBA_DISABLE_JIT=1`` the same source
runs as Python, which is how to debug it.

Each routine is checked against its numpy/scipy counterpart in the tests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE

EPS = float(np.finfo(float).eps)

#: One-sided Jacobi sweeps before giving up (each sweep squares the off-diagonal size).
_SWEEPS = 60


@njit(cache=CACHE)
def dot(a: np.ndarray, b: np.ndarray) -> float:
    """``a . b`` for 1-D arrays, summed in index order."""
    out = 0.0
    for i in range(a.shape[0]):
        out += a[i] * b[i]
    return out


@njit(cache=CACHE, inline="always")
def _matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A x`` for a 2-D ``A`` (a view or a transpose), inlined into its two callers."""
    m, n = A.shape
    out = np.zeros(m)
    for i in range(m):
        acc = 0.0
        for j in range(n):
            acc += A[i, j] * x[j]
        out[i] = acc
    return out


@njit(cache=CACHE)
def matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A x`` for a 2-D ``A``."""
    return _matvec(A, x)


@njit(cache=CACHE)
def rmatvec(A: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``A^T y`` for a 2-D ``A``: each entry summed in the row order of ``A``, on its
    transposed view (no copy)."""
    return _matvec(A.T, y)


@njit(cache=CACHE)
def matmul(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A B`` for 2-D arrays."""
    m, k = A.shape
    n = B.shape[1]
    out = np.zeros((m, n))
    for i in range(m):
        for j in range(n):
            acc = 0.0
            for p in range(k):
                acc += A[i, p] * B[p, j]
            out[i, j] = acc
    return out


@njit(cache=CACHE)
def _lu(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """LU factors of a square ``A`` with partial pivoting: ``(LU, perm, sign)``; an exactly
    zero pivot leaves its column unreduced (the determinant is then 0)."""
    LU = A.copy()
    perm = np.empty(A.shape[0], dtype=np.int64)
    sign = lu_in_place(LU, perm)
    return LU, perm, sign


@njit(cache=CACHE, inline="always")
def lu_in_place(LU: np.ndarray, perm: np.ndarray) -> float:
    """:func:`_lu` in the caller's arrays: ``LU`` (holding ``A``) becomes its factors and
    ``perm`` its row permutation; returns the permutation's sign (for a caller that factors
    at every iteration without allocating)."""
    n = LU.shape[0]
    for k in range(n):
        perm[k] = k
    sign = 1.0
    for k in range(n):
        p = k
        best = abs(LU[k, k])
        for i in range(k + 1, n):
            if abs(LU[i, k]) > best:
                best, p = abs(LU[i, k]), i
        if p != k:
            for j in range(n):
                LU[k, j], LU[p, j] = LU[p, j], LU[k, j]
            perm[k], perm[p] = perm[p], perm[k]
            sign = -sign
        if LU[k, k] == 0.0:
            continue
        for i in range(k + 1, n):
            f = LU[i, k] / LU[k, k]
            LU[i, k] = f
            for j in range(k + 1, n):
                LU[i, j] -= f * LU[k, j]
    return sign


@njit(cache=CACHE, inline="always")
def lu_det(LU: np.ndarray, sign: float) -> float:
    """The determinant from :func:`lu_in_place`'s factors and sign."""
    out = sign
    for k in range(LU.shape[0]):
        out *= LU[k, k]
    return out


@njit(cache=CACHE, inline="always")
def lu_solve(LU: np.ndarray, perm: np.ndarray, b: np.ndarray, x: np.ndarray) -> bool:
    """``x`` with ``A x = b`` from :func:`lu_in_place`'s factors of ``A``, and whether it
    exists (:func:`solve`)."""
    n = LU.shape[0]
    for i in range(n):
        x[i] = b[perm[i]]
    for i in range(n):
        for j in range(i):
            x[i] -= LU[i, j] * x[j]
    for i in range(n - 1, -1, -1):
        if LU[i, i] == 0.0:
            return False
        for j in range(i + 1, n):
            x[i] -= LU[i, j] * x[j]
        x[i] /= LU[i, i]
    for i in range(n):
        if not math.isfinite(x[i]):
            return False
    return True


@njit(cache=CACHE)
def det(A: np.ndarray) -> float:
    """Determinant of a square ``A`` (LU with partial pivoting)."""
    LU, _, sign = _lu(A)
    return lu_det(LU, sign)


@njit(cache=CACHE)
def solve(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, bool]:
    """``x`` with ``A x = b`` for a square ``A`` (LU with partial pivoting), and whether it
    exists: False on an exactly zero pivot or a non-finite result (as LAPACK's
    ``gesv`` reports a singular matrix)."""
    LU, perm, _ = _lu(A)
    x = np.empty(A.shape[0])
    ok = lu_solve(LU, perm, b, x)
    return x, ok


@njit(cache=CACHE)
def det_and_solve(U: np.ndarray, A: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray, bool]:
    """``(det(U), x, ok)`` with ``(x, ok) = solve(A, b)``, for square ``U`` and ``A`` of one
    size (a volume test on ``U``, then the solve), in one pair of LU buffers: the bits of
    :func:`det` and :func:`solve`, with three allocations instead of five."""
    n = A.shape[0]
    LU = U.copy()
    perm = np.empty(n, dtype=np.int64)
    volume = lu_det(LU, lu_in_place(LU, perm))
    LU[:] = A
    lu_in_place(LU, perm)
    x = np.empty(n)
    ok = lu_solve(LU, perm, b, x)
    return volume, x, ok


@njit(cache=CACHE)
def _jacobi(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-sided Jacobi rotations of ``A``'s columns until they are orthogonal: ``(U, V,
    sv)`` with ``A V = U``, ``V`` orthogonal and ``sv`` the norms of ``U``'s columns (the
    singular values, unsorted; ``U``'s columns not yet normalized)."""
    m, n = A.shape
    U = A.copy()
    V = np.eye(n)
    # columns below this squared norm are zero to rounding: rotating them never converges
    tiny = 0.0
    for i in range(m):
        for j in range(n):
            tiny += A[i, j] * A[i, j]
    tiny *= (EPS * EPS) * max(m, n)
    for _ in range(_SWEEPS):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for i in range(m):
                    alpha += U[i, p] * U[i, p]
                    beta += U[i, q] * U[i, q]
                    gamma += U[i, p] * U[i, q]
                if (
                    gamma == 0.0
                    or min(alpha, beta) <= tiny
                    or abs(gamma) <= EPS * math.sqrt(alpha * beta)
                ):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for i in range(m):
                    up, uq = U[i, p], U[i, q]
                    U[i, p] = c * up - s * uq
                    U[i, q] = s * up + c * uq
                for i in range(n):
                    vp, vq = V[i, p], V[i, q]
                    V[i, p] = c * vp - s * vq
                    V[i, q] = s * vp + c * vq
        if not rotated:
            break
    sv = np.empty(n)
    for j in range(n):
        acc = 0.0
        for i in range(m):
            acc += U[i, j] * U[i, j]
        sv[j] = math.sqrt(acc)
    return U, V, sv


@njit(cache=CACHE)
def _descending(sv: np.ndarray) -> np.ndarray:
    """The order of ``sv`` from largest to smallest, equal values in index order and NaN
    last: ``np.argsort(-sv, kind="stable")``, by insertion (a handful of entries)."""
    n = sv.shape[0]
    order = np.empty(n, dtype=np.int64)
    for k in range(n):
        j = k
        key = -sv[k]
        while j > 0:
            prev = -sv[order[j - 1]]
            # key sorts before prev: smaller, or a number before NaN
            if key < prev or (prev != prev and key == key):
                order[j] = order[j - 1]
                j -= 1
            else:
                break
        order[j] = k
    return order


@njit(cache=CACHE)
def svd(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thin singular value decomposition ``A = U diag(s) V^T`` by one-sided Jacobi.

    Returns ``U`` (m, n), ``s`` (n,) in descending order and ``V`` (n, n) (columns are the
    right singular vectors; note: V, not V^T). Columns of ``U`` for zero singular values
    are zero. One-sided Jacobi computes small singular values to high relative accuracy and
    needs no BLAS; for the few columns here it is also fast.
    """
    m, n = A.shape
    U, V, sv = _jacobi(A)
    order = _descending(sv)
    s_out = np.empty(n)
    U_out = np.zeros((m, n))
    V_out = np.empty((n, n))
    for k in range(n):
        j = order[k]
        s_out[k] = sv[j]
        for i in range(n):
            V_out[i, k] = V[i, j]
        if s_out[k] > 0.0:
            for i in range(m):
                U_out[i, k] = U[i, j] / s_out[k]
    return U_out, s_out, V_out


@njit(cache=CACHE)
def lstsq_into(A: np.ndarray, b: np.ndarray, rcond: float, floor: float, x: np.ndarray) -> int:
    """:func:`lstsq` into ``x`` (n,); returns the rank used. The singular vectors are read
    from the rotations (:func:`_jacobi`) in :func:`svd`'s order, with its arithmetic, without
    assembling the decomposition."""
    m, n = A.shape
    U, V, sv = _jacobi(A)
    order = _descending(sv)
    if rcond < 0.0:
        rcond = EPS * max(m, n)
    cut = max(rcond * (sv[order[0]] if n > 0 else 0.0), floor)
    x[:] = 0.0
    rank = 0
    for k in range(n):
        j = order[k]
        sk = sv[j]
        if sk <= cut or sk == 0.0:
            continue
        rank += 1
        coef = 0.0
        for i in range(m):
            coef += (U[i, j] / sk) * b[i]
        coef /= sk
        for i in range(n):
            x[i] += coef * V[i, j]
    return rank


@njit(cache=CACHE)
def lstsq(A: np.ndarray, b: np.ndarray, rcond: float, floor: float = 0.0) -> tuple[np.ndarray, int]:
    """Least-norm least-squares solution of ``A x ~ b`` and the rank used.

    Singular values at most ``rcond`` times the largest count as zero (numpy's ``lstsq``
    convention; ``rcond < 0`` means ``EPS * max(m, n)``), and so do those at most ``floor``.
    """
    x = np.empty(A.shape[1])
    rank = lstsq_into(A, b, rcond, floor, x)
    return x, rank


@njit(cache=CACHE)
def rank(A: np.ndarray, tol: float) -> int:
    """Number of singular values of ``A`` above ``tol`` (an absolute threshold)."""
    sv = _jacobi(A)[2]
    out = 0
    for k in range(sv.shape[0]):
        if sv[k] > tol:
            out += 1
    return out


@njit(cache=CACHE)
def nnls(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """``argmin |A x - b|`` over ``x >= 0`` (Lawson and Hanson's active-set method) and the
    residual norm.

    The passive-set subproblems are solved by :func:`lstsq` on ``A``'s columns themselves
    (not the normal equations). Dual values count as positive above a tolerance relative to
    ``|A| |b|``, so the result does not depend on the problem's units.
    """
    m, n = A.shape
    x = np.zeros(n)
    if n == 0:
        return x, math.sqrt(dot(b, b))
    size = 0.0
    for i in range(m):
        for j in range(n):
            size += A[i, j] * A[i, j]
    tol = 10.0 * max(m, n) * EPS * math.sqrt(size) * math.sqrt(dot(b, b))
    passive = np.zeros(n, dtype=np.bool_)
    for _ in range(3 * n + 3):
        w = rmatvec(A, b - matvec(A, x))
        j, best = -1, tol
        for k in range(n):
            if not passive[k] and w[k] > best:
                j, best = k, w[k]
        if j < 0:
            break
        passive[j] = True
        for _inner in range(3 * n + 3):
            idx = np.nonzero(passive)[0]
            if idx.shape[0] == 0:
                break
            z = lstsq(A[:, idx].copy(), b, -1.0)[0]
            if z.min() > 0.0:
                x[:] = 0.0
                x[idx] = z
                break
            # Move from x towards z until the first passive variable reaches zero, and
            # return that one (and any other at zero) to the active set.
            alpha, first = 1.0, idx[0]
            for t in range(idx.shape[0]):
                if z[t] <= 0.0:
                    step = x[idx[t]] / (x[idx[t]] - z[t])
                    if step < alpha:
                        alpha, first = step, idx[t]
            for t in range(idx.shape[0]):
                x[idx[t]] += alpha * (z[t] - x[idx[t]])
            x[first] = 0.0
            for t in range(idx.shape[0]):
                if x[idx[t]] <= 0.0:
                    x[idx[t]] = 0.0
                    passive[idx[t]] = False
    r = matvec(A, x) - b
    return x, math.sqrt(dot(r, r))
