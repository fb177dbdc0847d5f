"""The velocity LP (eqs. 19-21) and its dual, the force LP (22-24), by exact basis enumeration,
and the form-closure test, compiled with numba::

    min c^T v  s.t.  V v >= xi  (v in R^3 free);     max xi^T lam  s.t.  V^T lam = c, lam >= 0

:func:`solve` makes the rows unit, finds ``r = rank V`` and tries every basis (r rows), every
Farkas support (r + 1 rows) and every extreme ray (r - 1 rows), visiting the row subsets in
lexicographic order; of equally good candidates the first is kept. The method, the
tolerances below and the choice among optimal bases are documented in
:mod:`grasp_env.solvers.fastlp`, which wraps these kernels. Plain arithmetic in a fixed order
(:mod:`grasp_env.solvers.dense`): no BLAS, the same bits on every machine.

The searches for a basis, a Farkas vector and a descent ray are one algorithm sharing the row
subsets, the tolerances and the tie-breaking, which is why they stay in one module, longer
than the others.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.solvers import dense

RANK_TOL = 1e-10
"""Unit-row determinant (volume) an r-subset must exceed for ``rank V >= r``."""

SINGULAR_TOL = 1e-13
"""Unit-row determinant below which a row subset is not tried as a basis."""

FEAS_TOL = 1e-9
"""Relative feasibility, sign and certificate tolerance (see :mod:`grasp_env.solvers.fastlp`)."""

BOUNDARY_TOL = 1e-6
"""A looser dual tolerance for a problem :data:`UNDECIDED` at :data:`FEAS_TOL`: the cost
within about 1e-9 of the boundary of the cone of V's rows (a contact force that has just
reached zero, where the simulator locates events), neither optimal nor unbounded at
FEAS_TOL. At BOUNDARY_TOL it is optimal, with the force refit to zero."""

ROUNDING = 16 * dense.EPS
"""Absolute rounding allowance on ``|det|``-scaled multipliers and slacks, per unit data."""

REFINE_BELOW = 1e-3
"""Unit-row determinant below which the chosen basis's solution is refined (one step)."""

#: Status codes of :func:`solve`.
OPTIMAL, INFEASIBLE, UNBOUNDED, UNDECIDED = 0, 1, 2, 3


# ---------------------------------------------------------------------------------------------
# Row subsets, adjugates and null vectors


@njit(cache=CACHE, inline="always")
def _next_subset(idx: np.ndarray, n: int) -> bool:
    """Advance the increasing k-subset ``idx`` of range(n) to the next one in lexicographic
    order, in place; False (idx unchanged) after the last."""
    k = idx.shape[0]
    t = k - 1
    while t >= 0 and idx[t] == n - k + t:
        t -= 1
    if t < 0:
        return False
    idx[t] += 1
    for s in range(t + 1, k):
        idx[s] = idx[s - 1] + 1
    return True


@njit(cache=CACHE, inline="always")
def _cross(W: np.ndarray, p: int, q: int, out: np.ndarray) -> None:
    """``out = W_p x W_q`` for rows of W (n, 3)."""
    out[0] = W[p, 1] * W[q, 2] - W[p, 2] * W[q, 1]
    out[1] = W[p, 2] * W[q, 0] - W[p, 0] * W[q, 2]
    out[2] = W[p, 0] * W[q, 1] - W[p, 1] * W[q, 0]


@njit(cache=CACHE, inline="always")
def _adjugate(W: np.ndarray, rows: np.ndarray, G: np.ndarray) -> float:
    """Fill ``G`` (r, r) with ``det(W_B) W_B^{-T}`` for the rows ``B = rows`` of W (n, r),
    r in {1, 2, 3}, and return ``det(W_B)``.

    Row k of ``G`` is orthogonal to every row of ``W_B`` but the k-th, with which its dot
    product is the determinant: for rows (a, b, c) these are ``b x c, c x a, a x b``.
    """
    r = rows.shape[0]
    a = rows[0]
    if r == 3:
        b, d = rows[1], rows[2]
        _cross(W, b, d, G[0])
        _cross(W, d, a, G[1])
        _cross(W, a, b, G[2])
        return W[a, 0] * G[0, 0] + W[a, 1] * G[0, 1] + W[a, 2] * G[0, 2]
    if r == 2:
        b = rows[1]
        G[0, 0], G[0, 1] = W[b, 1], -W[b, 0]
        G[1, 0], G[1, 1] = -W[a, 1], W[a, 0]
        return W[a, 0] * W[b, 1] - W[a, 1] * W[b, 0]
    G[0, 0] = 1.0
    return W[a, 0]


@njit(cache=CACHE)
def _has_volume(W: np.ndarray) -> bool:
    """Whether some r rows of W (n, r) span a volume ``|det W_B| > RANK_TOL``."""
    n, r = W.shape
    if n < r:
        return False
    G = np.empty((r, r))
    idx = np.arange(r)
    while True:
        if abs(_adjugate(W, idx, G)) > RANK_TOL:
            return True
        if not _next_subset(idx, n):
            return False


@njit(cache=CACHE, inline="always")
def _null_vector(W: np.ndarray, rows: np.ndarray, out: np.ndarray) -> None:
    """Null vector of the ``r - 1`` rows ``W_R`` (``R = rows``) of W (n, r), by signed minors:
    ``a x b`` for r = 3, ``(a_1, -a_0)`` for r = 2, ``1`` for r = 1."""
    r = out.shape[0]
    if r == 3:
        _cross(W, rows[0], rows[1], out)
    elif r == 2:
        out[0], out[1] = W[rows[0], 1], -W[rows[0], 0]
    else:
        out[0] = 1.0


@njit(cache=CACHE)
def _norm(x: np.ndarray) -> float:
    return math.sqrt(dense.dot(x, x))


@njit(cache=CACHE)
def _abs_max(x: np.ndarray) -> float:
    """``max |x_i|``, 0 for an empty x."""
    out = 0.0
    for i in range(x.shape[0]):
        out = max(out, abs(x[i]))
    return out


# ---------------------------------------------------------------------------------------------
# The three outcomes, for W (n, r) of rank r with (near-)unit rows and xi scaled with them


@njit(cache=CACHE)
def _basis_solution(
    W: np.ndarray, xi: np.ndarray, c_r: np.ndarray, rows: np.ndarray, G: np.ndarray,
    u_s: np.ndarray, lam_s: np.ndarray,
) -> float:  # fmt: skip
    """``|det W_B|`` for the rows ``B = rows``; fills ``G`` with ``|det| W_B^{-T}``, ``u_s``
    with the ``|det|``-scaled basic solution ``u |det| = |det| W_B^{-1} xi_B`` and ``lam_s``
    with the scaled multipliers ``lam_B |det| = |det| W_B^{-T} c_r``."""
    r = rows.shape[0]
    det = _adjugate(W, rows, G)
    sign = 1.0 if det > 0.0 else (-1.0 if det < 0.0 else 0.0)
    for k in range(r):
        for j in range(r):
            G[k, j] *= sign
    for k in range(r):
        acc = 0.0
        for j in range(r):
            acc += G[k, j] * c_r[j]
        lam_s[k] = acc
    for j in range(r):
        acc = 0.0
        for k in range(r):
            acc += G[k, j] * xi[rows[k]]
        u_s[j] = acc
    return abs(det)


@njit(cache=CACHE)
def _optimal_basis(
    W: np.ndarray, xi: np.ndarray, c_r: np.ndarray, dual_tol: float
) -> tuple[bool, np.ndarray, np.ndarray]:
    """The primal-dual feasible basis with the largest ``|det|`` (exact ones first, then the
    first in lexicographic order), as ``(found, u, lam)``; multipliers down to ``-dual_tol``
    times their sum count as non-negative.

    Tests ``|det|``-scaled quantities (``lam_B |det|``, ``u |det|``), whose rounding errors
    are a few ulps of ``|c|`` and ``|xi|_inf``; see :mod:`grasp_env.solvers.fastlp` for the
    tolerances, the refinement and the refit of a slightly negative multiplier.

    One function, longer than the others: the search over bases and the refinement of the one
    it keeps share the scratch arrays allocated once here, which the enumeration reuses for
    every row subset.
    """
    n, r = W.shape
    G = np.empty((r, r))
    dual_round = -ROUNDING * _norm(c_r)
    xi_size = _abs_max(xi)
    primal_round = -ROUNDING * xi_size
    u_s = np.empty(r)
    lam_s = np.empty(r)
    best_score = 0.0
    best = np.full(r, -1)
    idx = np.arange(r)
    while True:
        det = _adjugate(W, idx, G)
        adet = abs(det)
        if adet > SINGULAR_TOL:
            # As in _basis_solution, but with the sign applied to the sums (the same numbers
            # up to the sign of a zero), and u only for dual feasible bases.
            sign = 1.0 if det > 0.0 else -1.0
            lam_min, lam_sum = np.inf, 0.0
            for k in range(r):
                acc = 0.0
                for j in range(r):
                    acc += G[k, j] * c_r[j]
                lam_min = min(lam_min, sign * acc)
                lam_sum += sign * acc
            # min lam_B >= -dual_tol sum(lam_B) (at least max|lam_B| where it can hold) - rounding
            if lam_min + dual_tol * lam_sum >= dual_round:
                for j in range(r):
                    acc = 0.0
                    for k in range(r):
                        acc += G[k, j] * xi[idx[k]]
                    u_s[j] = sign * acc
                slack_min = np.inf
                for i in range(n):
                    acc = 0.0
                    for p in range(r):
                        acc += W[i, p] * u_s[p]
                    slack_min = min(slack_min, acc - xi[i] * adet)  # (W u - xi) |det|
                primal = slack_min + FEAS_TOL * _abs_max(u_s)
                if primal >= (-FEAS_TOL * xi_size) * adet + primal_round:
                    # Bases feasible up to rounding alone (|det| <= 1 for unit rows) come
                    # first, then the best conditioned: one that needs FEAS_TOL is optimal
                    # only to FEAS_TOL.
                    exact = lam_min >= dual_round and slack_min >= primal_round
                    score = adet + (2.0 if exact else 0.0)
                    if score > best_score:
                        best_score = score
                        best[:] = idx
        if not _next_subset(idx, n):
            break
    if best[0] < 0:
        return False, np.empty(0), np.empty(0)
    adet = _basis_solution(W, xi, c_r, best, G, u_s, lam_s)
    u = np.empty(r)
    lam_B = np.empty(r)
    for k in range(r):
        u[k] = u_s[k] / adet
        lam_B[k] = lam_s[k] / adet
    if adet < REFINE_BELOW:
        # Cramer's rule is forward but not backward stable: on an ill-conditioned basis one
        # step of iterative refinement restores small residuals in W_B u = xi_B, W_B^T lam = c.
        inv_T = np.empty((r, r))  # W_B^{-T}
        W_B = np.empty((r, r))
        for k in range(r):
            for j in range(r):
                inv_T[k, j] = G[k, j] / adet
                W_B[k, j] = W[best[k], j]
        res_u = dense.matvec(W_B, u)
        res_lam = dense.rmatvec(W_B, lam_B)
        for k in range(r):
            res_u[k] = xi[best[k]] - res_u[k]
            res_lam[k] = c_r[k] - res_lam[k]
        du = dense.rmatvec(inv_T, res_u)
        dlam = dense.matvec(inv_T, res_lam)
        for k in range(r):
            u[k] += du[k]
            lam_B[k] += dlam[k]
    n_keep, negative = 0, False
    for k in range(r):
        n_keep += lam_B[k] > 0.0
        negative = negative or lam_B[k] < 0.0
    if negative:
        # Within tolerance, but clipping it would leave a residual in V^T lam = c: refit c on
        # the positive multipliers' rows instead.
        A = np.empty((r, n_keep))
        keep = np.empty(n_keep, dtype=np.int64)
        t = 0
        for k in range(r):
            if lam_B[k] > 0.0:
                keep[t] = k
                for j in range(r):
                    A[j, t] = W[best[k], j]
                t += 1
        refit = dense.lstsq(A, c_r, -1.0)[0]
        for k in range(r):
            lam_B[k] = 0.0
        for t in range(n_keep):
            lam_B[keep[t]] = max(refit[t], 0.0)
    lam = np.zeros(n)
    for k in range(r):
        lam[best[k]] = lam_B[k]
    return True, u, lam


@njit(cache=CACHE)
def _farkas(W: np.ndarray, xi: np.ndarray) -> tuple[bool, np.ndarray]:
    """A vector ``y >= 0``, ``1^T y = 1``, ``W^T y = 0`` with ``xi^T y > 0``: ``(found, y)``.

    ``y`` is tried on every (r + 1)-subset ``S`` of the rows of W (n, r) (rank r, (near-)unit
    rows), where it is the signed-minor null vector ``z_k = (-1)^k det W_{S - S_k}`` of
    ``W_S^T`` over ``1^T z``; the one with the largest ``xi^T y`` is kept.
    """
    n, r = W.shape
    k = r + 1
    if n < k:
        return False, np.empty(0)
    # det W_R of every r-subset R, at sum_s R_s n^(r - 1 - s)
    dets = np.empty(n**r)
    if r > 0:
        G = np.empty((r, r))
        face = np.arange(r)
        while True:
            key = 0
            for s in range(r):
                key = key * n + face[s]
            dets[key] = _adjugate(W, face, G)
            if not _next_subset(face, n):
                break
    xi_size = _abs_max(xi)
    z = np.empty(k)
    best_z = np.empty(k)
    best_score = -np.inf
    best = np.full(k, -1)
    idx = np.arange(k)
    while True:
        total = 0.0
        for t in range(k):
            if r == 0:
                z[t] = 1.0
            else:
                key = 0
                for s in range(k):
                    if s != t:
                        key = key * n + idx[s]
                z[t] = dets[key] * (1.0 if t % 2 == 0 else -1.0)
            total += z[t]
        sign = 1.0 if total > 0.0 else (-1.0 if total < 0.0 else 0.0)
        # y = z / |total| up to rounding: a few ulps (unit-row minors)
        allowance = FEAS_TOL * abs(total) + ROUNDING
        gain = 0.0  # xi^T y |total|
        z_min = np.inf
        for t in range(k):
            z[t] *= sign
            gain += z[t] * xi[idx[t]]
            z_min = min(z_min, z[t])
        if z_min >= -allowance and gain > allowance * xi_size:
            score = gain / max(abs(total), ROUNDING)
            if best[0] < 0 or score > best_score:
                best_score = score
                best[:] = idx
                best_z[:] = z
        if not _next_subset(idx, n):
            break
    if best[0] < 0:
        return False, np.empty(0)
    y_sum = 0.0
    for t in range(k):
        best_z[t] = max(best_z[t], 0.0)
        y_sum += best_z[t]
    out = np.zeros(n)
    for t in range(k):
        out[best[t]] = best_z[t] / y_sum
    return True, out


@njit(cache=CACHE)
def _descent_ray(W: np.ndarray, c_r: np.ndarray) -> tuple[bool, np.ndarray]:
    """A unit extreme ray ``d`` of ``{W d >= 0}`` (rank r, unit rows) with ``c_r^T d < 0``:
    the null vector of r - 1 rows with the most negative ``c_r^T d``, as ``(found, d)``."""
    n, r = W.shape
    if r == 0 or n < r - 1:
        return False, np.empty(0)
    bound = -FEAS_TOL * _norm(c_r)
    d = np.empty(r)
    best_d = np.empty(r)
    best_cd = np.inf
    found = False
    idx = np.arange(r - 1)
    while True:
        _null_vector(W, idx, d)
        size = 0.0
        for p in range(r):
            size += d[p] * d[p]
        size = math.sqrt(size)
        if size > RANK_TOL:
            cd = 0.0
            for p in range(r):
                d[p] /= size
                cd += d[p] * c_r[p]
            flip = -1.0 if cd > 0.0 else (1.0 if cd < 0.0 else -0.0)
            for p in range(r):
                d[p] *= flip
            cd = -abs(cd)
            good = cd < bound
            for i in range(n):
                if not good:
                    break
                acc = 0.0
                for p in range(r):
                    acc += W[i, p] * d[p]
                good = acc >= -FEAS_TOL
            if good and (not found or cd < best_cd):
                found = True
                best_cd = cd
                best_d[:] = d
        if not _next_subset(idx, n):
            break
    return found, best_d


@njit(cache=CACHE)
def _outcome(
    W: np.ndarray, xi: np.ndarray, c: np.ndarray, Q: np.ndarray, reduced: bool, dual_tol: float
) -> tuple[int, np.ndarray, np.ndarray, float, np.ndarray]:
    """The three outcomes in coordinates ``W = V Q``, ``v = Q u`` (``reduced`` False: ``Q`` is
    the identity, unused). W has (near-)unit rows and rank ``r = W.shape[1]``; ``lam`` and a
    Farkas ``y`` refer to W's rows. Returns as :func:`solve`."""
    n, r = W.shape
    c_r = c
    c_perp = np.zeros(3)
    perp = False
    if reduced:
        c_r = dense.rmatvec(Q, c)
        c_perp = dense.matvec(Q, c_r)
        for j in range(3):
            c_perp[j] = c[j] - c_perp[j]
        perp = not _norm(c_perp) <= FEAS_TOL * _norm(c)
    none = np.empty(0)
    if not perp:
        if r > 0:
            found, u, lam = _optimal_basis(W, xi, c_r, dual_tol)
        else:  # V = 0 and c = 0: v = 0 is optimal unless some 0 >= xi_i fails
            found, u, lam = True, np.zeros(0), np.zeros(n)
            bound = FEAS_TOL * _abs_max(xi)
            for i in range(n):
                if xi[i] > bound:
                    found = False
        if found:
            v = dense.matvec(Q, u) if reduced else u
            return OPTIMAL, v, lam, dense.dot(c, v), none
    found, y = _farkas(W, xi)
    if found:
        return INFEASIBLE, none, none, np.inf, y
    if perp:
        size = _norm(c_perp)
        for j in range(3):
            c_perp[j] = -c_perp[j] / size
        return UNBOUNDED, none, none, -np.inf, c_perp
    found, d = _descent_ray(W, c_r)
    if not found:
        return UNDECIDED, none, none, np.nan, none
    return UNBOUNDED, none, none, -np.inf, dense.matvec(Q, d) if reduced else d


@njit(cache=CACHE)
def _row_space(V: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(W, Q, reduced)`` for unit rows V (n, 3): ``W = V Q`` with ``Q`` (3, r) an orthonormal
    basis of V's row space, ``r = rank V``; for r = 3, ``W = V`` and ``reduced`` is False."""
    n = V.shape[0]
    if n >= 3 and _has_volume(V):
        return V, np.eye(3), False
    if n > 0:
        # Rank < 3: the row space is spanned by V's leading right singular vectors.
        right = dense.svd(V)[2]  # columns: right singular vectors, largest first
        for r in range(min(n, 2), 0, -1):
            Q = np.empty((3, r))
            for i in range(3):
                for j in range(r):
                    Q[i, j] = right[i, j]
            W = dense.matmul(V, Q)
            if _has_volume(W):
                return W, Q, True
    return np.zeros((n, 0)), np.zeros((3, 0)), True


# ---------------------------------------------------------------------------------------------
# Entry points


@njit(cache=CACHE)
def solve(
    V: np.ndarray, xi: np.ndarray, c: np.ndarray, dual_tol: float = FEAS_TOL
) -> tuple[int, np.ndarray, np.ndarray, float, np.ndarray]:
    """The velocity LP ``min c^T v s.t. V v >= xi`` and its dual, for V (n, 3), xi (n,), c (3,).

    Returns ``(status, v, lam, value, certificate)``: ``status`` one of :data:`OPTIMAL`
    (``v`` (3,), ``lam`` (n,), ``value = c^T v``), :data:`INFEASIBLE` (a Farkas vector (n,),
    ``value = inf``), :data:`UNBOUNDED` (a unit descent ray (3,), ``value = -inf``) or
    :data:`UNDECIDED` (none of the three certified); arrays not returned are empty.

    Scaling row i (and ``xi_i``) by ``1 / |V_i|`` leaves the velocity LP unchanged and scales
    ``lam_i`` by ``|V_i|``; zero rows are the constraints ``0 >= xi_i``. ``dual_tol``: how
    negative (relative to their sum) a basis's multipliers may be and it still count as
    optimal (:data:`FEAS_TOL`; :data:`BOUNDARY_TOL` for a second attempt).
    """
    n = V.shape[0]
    norm = np.empty(n)
    keep = np.empty(n, dtype=np.int64)
    m = 0
    worst = -1
    for i in range(n):
        norm[i] = math.sqrt(V[i, 0] * V[i, 0] + V[i, 1] * V[i, 1] + V[i, 2] * V[i, 2])
        if norm[i] == 0.0:
            if worst < 0 or xi[i] > xi[worst]:
                worst = i
        else:
            keep[m] = i
            m += 1
    none = np.empty(0)
    cost = c.copy()  # writable, whatever the caller's flags
    if worst >= 0 and xi[worst] > FEAS_TOL * _abs_max(xi):
        y = np.zeros(n)
        y[worst] = 1.0
        return INFEASIBLE, none, none, np.inf, y
    U = np.empty((m, 3))
    xi_u = np.empty(m)
    for t in range(m):
        i = keep[t]
        for j in range(3):
            U[t, j] = V[i, j] / norm[i]
        xi_u[t] = xi[i] / norm[i]
    W, Q, reduced = _row_space(U)
    status, v, lam_u, value, cert = _outcome(W, xi_u, cost, Q, reduced, dual_tol)
    if status == OPTIMAL:
        lam = np.zeros(n)
        for t in range(m):
            lam[keep[t]] = lam_u[t] / norm[keep[t]]
        return status, v, lam, value, cert
    if status == INFEASIBLE:
        y_sum = 0.0
        for t in range(m):
            cert[t] /= norm[keep[t]]
            y_sum += cert[t]
        y = np.zeros(n)
        for t in range(m):
            y[keep[t]] = cert[t] / y_sum
        return status, v, lam_u, value, y
    return status, v, lam_u, value, cert


@njit(cache=CACHE)
def form_closure(V: np.ndarray) -> bool:
    """Form closure: ``V v >= 0`` only for ``v = 0``, for V (n, 3).

    No extreme ray ``+-(V_i x V_j)`` of an independent pair of unit rows (``|V_i x V_j| >
    RANK_TOL``) is admissible to ``V_k d >= -FEAS_TOL``, and some pair is independent; see
    :func:`grasp_env.solvers.fastlp.form_closure_fast`.
    """
    n = V.shape[0]
    U = np.empty((n, 3))
    m = 0
    for i in range(n):
        size = math.sqrt(V[i, 0] * V[i, 0] + V[i, 1] * V[i, 1] + V[i, 2] * V[i, 2])
        if size > 0.0:
            for j in range(3):
                U[m, j] = V[i, j] / size
            m += 1
    if m < 4:
        return False
    d = np.empty(3)
    independent = False
    idx = np.arange(2)
    while True:
        _cross(U, idx[0], idx[1], d)
        size = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if size > RANK_TOL:
            independent = True
            for p in range(3):
                d[p] /= size
            up, down = True, True  # d, resp. -d, is admissible
            for i in range(m):
                acc = 0.0
                for p in range(3):
                    acc += U[i, p] * d[p]
                up = up and acc >= -FEAS_TOL
                down = down and acc <= FEAS_TOL
            if up or down:
                return False
        if not _next_subset(idx, m):
            break
    return independent
