"""Exact basis enumeration for the velocity LP (eqs. 19-21) and its dual, the force LP (22-24).

The simulator's hot-path LP has three variables (the object twist) and a handful of rows (the
contacts), so every basis can be tried at once with numpy instead of pivoting::

    velocity LP (primal):  min c^T v        s.t.  V v >= xi,          v in R^3 free
    force LP (dual):       max xi^T lam     s.t.  V^T lam = c,        lam >= 0

with ``V = V_ob`` (n, 3) of :mod:`grasp_env.mechanics` (rows ``[n_i, r_i x n_i]``), ``xi``
(n,) from eq. 20 and ``c = m gamma = (0, m g, 0)``.

Method. Scaling row i (and ``xi_i``) by ``1 / |V_i|`` leaves the velocity LP unchanged and
scales ``lam_i`` by ``|V_i|``, so the rows are made unit first (zero rows are the constraints
``0 >= xi_i``). Let ``r = rank V`` and ``Q`` (3, r) an orthonormal basis of V's row space
(``Q = I`` when r = 3); the problem lives in the coordinates ``W = V Q``, ``v = Q u``.

* A basis is an r-subset ``B`` of the rows with ``W_B`` nonsingular; its primal point is
  ``u = W_B^{-1} xi_B`` and its multipliers ``lam_B = W_B^{-T} Q^T c`` (zero off ``B``).
  Complementary slackness holds by construction, so a basis with ``lam_B >= 0`` and
  ``W u >= xi`` is an optimal primal-dual pair, and one exists whenever both LPs are
  feasible (the simplex method ends on one). All bases are solved at once with closed-form
  adjugates (cross products for r = 3); the best conditioned optimal one is returned,
  preferring those that need no tolerance beyond rounding.
* Otherwise the velocity LP is infeasible if a Farkas vector exists: ``y >= 0``,
  ``1^T y = 1``, ``V^T y = 0``, ``xi^T y > 0``. The vertices of that polytope have supports
  of r + 1 rows, on which ``y`` is the signed-minor null vector of ``W_S^T``; all are tried.
* Otherwise it is unbounded, which a descent ray (``V d >= 0``, ``c^T d < 0``) certifies:
  ``-c_perp`` when ``c`` leaves the row space, else an extreme ray of the pointed cone
  ``{W d >= 0}``, the null vector of r - 1 rows; all are tried.

In exact arithmetic exactly one of the three is found. A problem that is both primal and dual
infeasible is reported ``"infeasible"``, as HiGHS does.

Tolerances. All are relative, so the outcome does not change when rows of V (with their
``xi_i``) or c are scaled by positive factors; below, rows are unit and ``|xi|_inf`` is that
of ``xi_i / |V_i|``; ``eps`` is the machine epsilon.

* :data:`RANK_TOL` = 1e-10: ``rank V`` is the largest r for which some r rows span a volume
  ``|det W_B| > RANK_TOL`` (for r < 3, within the span of V's leading r right singular
  vectors). Extreme rays use pairs of rows with ``|a x b| > RANK_TOL``.
* :data:`SINGULAR_TOL` = 1e-13: row subsets with ``|det W_B|`` below it are not bases.
* :data:`FEAS_TOL` = 1e-9. A basis is dual feasible when
  ``min lam_B >= -FEAS_TOL sum(lam_B) - 16 eps |c| / |det W_B|`` and primal feasible when
  ``min_i (W_i u - xi_i) >= -FEAS_TOL (|xi|_inf + |u|_inf) - 16 eps |xi|_inf / |det W_B|``:
  relative to the basis's own solution, plus the rounding error of Cramer's rule, which
  grows as ``1 / |det W_B|``. The returned pair is refined by one step of iterative
  refinement when ``|det W_B| < 1e-3``, and a multiplier in ``[-tol, 0)`` is not clipped
  (that would leave a residual in ``V^T lam = c``) but ``c`` is refit on the others.
  A Farkas vector needs ``xi^T y > FEAS_TOL |xi|_inf`` (plus rounding), ``c`` leaves the row
  space when ``|c_perp| > FEAS_TOL |c|``, and a unit ray needs ``W_i d >= -FEAS_TOL`` and
  ``c^T d < -FEAS_TOL |c|``.

Accuracy therefore follows the conditioning of the returned basis, as for any solver: the
tests see 1e-9 relative agreement with planted optima, also with rows 1e-8 from parallel,
and ~1e-8 when V itself is within 1e-8 of rank 2.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from grasp_env.errors import SolverError
from grasp_env.sim import dense

RANK_TOL = 1e-10
"""Unit-row determinant (volume) an r-subset must exceed for ``rank V >= r``."""

SINGULAR_TOL = 1e-13
"""Unit-row determinant below which a row subset is not tried as a basis."""

FEAS_TOL = 1e-9
"""Relative feasibility, sign and certificate tolerance (see the module docstring)."""

_ROUNDING = 16 * np.finfo(float).eps
"""Absolute rounding allowance on ``|det|``-scaled multipliers and slacks, per unit data."""

_REFINE_BELOW = 1e-3
"""Unit-row determinant below which the chosen basis's solution is refined (one step)."""


@dataclass(frozen=True)
class FastLPResult:
    """Outcome of :func:`solve_velocity_lp`.

    Attributes:
        status: ``"optimal"``, ``"infeasible"`` (no ``v`` with ``V v >= xi``: a jam) or
            ``"unbounded"`` (``V v >= xi`` is feasible but ``c^T v`` has no lower bound, the
            force LP is infeasible: a fall).
        v: a primal optimum (3,), the object twist, or None.
        lam: a dual optimum (n,), the contact forces of the force LP, ``lam >= 0``, or None.
        value: ``c^T v = xi^T lam`` when optimal, ``inf`` when infeasible, ``-inf`` when
            unbounded (the convention of :class:`grasp_env.lp.LPResult`).
        certificate: when infeasible a Farkas vector ``y`` (n,), ``y >= 0``, ``1^T y = 1``,
            ``V^T y = 0``, ``xi^T y > 0``; when unbounded a unit twist ``d`` (3,) with
            ``V d >= 0`` and ``c^T d < 0``; None when optimal.
    """

    status: str
    v: np.ndarray | None
    lam: np.ndarray | None
    value: float
    certificate: np.ndarray | None = None


# ---------------------------------------------------------------------------------------------
# Index arrays, cached per n. Per-subset arrays are component-major, shape (..., m), so that
# reductions over a subset's r entries run over the leading axis (fast in numpy).


@cache
def _subsets(n: int, k: int) -> np.ndarray:
    """All k-subsets of range(n) in lexicographic order, shape (C(n, k), k), read-only."""
    out = np.array(list(itertools.combinations(range(n), k)), dtype=np.intp).reshape(-1, k)
    out.setflags(write=False)
    return out


@cache
def _subsets_T(n: int, k: int) -> np.ndarray:
    """``_subsets(n, k).T``, contiguous, shape (k, C(n, k))."""
    out = np.ascontiguousarray(_subsets(n, k).T)
    out.setflags(write=False)
    return out


@cache
def _faces(n: int, k: int) -> np.ndarray:
    """Position in ``_subsets(n, k - 1)`` of each k-subset minus its j-th element, (k, C(n, k))."""
    where = {tuple(s): i for i, s in enumerate(_subsets(n, k - 1).tolist())}
    rows = [[where[tuple(s[:j] + s[j + 1 :])] for j in range(k)] for s in _subsets(n, k).tolist()]
    out = np.array(rows, dtype=np.intp).reshape(-1, k).T.copy()
    out.setflags(write=False)
    return out


@cache
def _triple_gathers(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flat indices that build every triple's adjugate from the outer product of ``V.ravel()``.

    For triple rows (a, b, c) the adjugate rows are (b x c, c x a, a x b); component j of
    ``p x q`` is ``p[j+1] q[j+2] - p[j+2] q[j+1]`` (indices mod 3), a difference of two
    entries of ``outer(V.ravel(), V.ravel())``. Returns ``K1, K2`` (3, 3, m) into that outer
    product (flattened) and ``Ka`` (3, m) into ``V.ravel()`` (the first row, for the det).
    """
    T = _subsets(n, 3)
    p = T[:, [1, 2, 0]].T[:, None, :]  # (k, 1, m): first factor's row
    q = T[:, [2, 0, 1]].T[:, None, :]
    j = np.arange(3)[None, :, None]
    j1, j2 = (j + 1) % 3, (j + 2) % 3
    K1 = (3 * p + j1) * (3 * n) + 3 * q + j2
    K2 = (3 * p + j2) * (3 * n) + 3 * q + j1
    Ka = 3 * T[:, 0][None, :] + np.arange(3)[:, None]
    for a in (K1, K2, Ka):
        a.setflags(write=False)
    return K1, K2, Ka


_ALTERNATING = [np.array([(-1.0) ** j for j in range(k)])[:, None] for k in range(5)]


def _norm(x: np.ndarray) -> float:
    return math.sqrt(dense.dot(x, x))


# ---------------------------------------------------------------------------------------------
# Closed-form adjugates and null vectors


def _adjugate(W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Adjugate rows and determinants of every r-subset ``W_B`` of the rows of W.

    Args:
        W: rows (n, r), r in {1, 2, 3}; the subsets are ``_subsets(n, r)`` (m of them).

    Returns:
        ``G`` (r, r, m) with ``G[:, :, i] = det(W_B) W_B^{-T}`` (row k is orthogonal to every
        row of ``W_B`` but the k-th, with which its dot product is the determinant) and
        ``det`` (m,).
    """
    n, r = W.shape
    if r == 3:
        K1, K2, Ka = _triple_gathers(n)
        flat = W.ravel()
        outer = np.multiply.outer(flat, flat).ravel()
        G = outer.take(K1) - outer.take(K2)
        det = (flat.take(Ka) * G[0]).sum(axis=0)
        return G, det
    a, *rest = W[_subsets_T(n, r)]  # (m, r) each
    if r == 2:
        b = rest[0]
        det = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        return np.array([[b[:, 1], -b[:, 0]], [-a[:, 1], a[:, 0]]]), det
    return np.ones((1, 1, len(a))), a[:, 0].copy()


def _null_rows(W: np.ndarray) -> np.ndarray:
    """Null vector of every (r - 1)-subset ``W_R`` of the rows of W (n, r), shape (r, m).

    Signed minors: ``a x b`` for r = 3, ``(a_1, -a_0)`` for r = 2, ``1`` for r = 1.
    """
    n, r = W.shape
    if r == 1:
        return np.ones((1, 1))
    R = W[_subsets_T(n, r - 1)].transpose(0, 2, 1)  # (r - 1, r, m)
    if r == 2:
        return np.array([R[0, 1], -R[0, 0]])
    a, b = R
    return a[[1, 2, 0]] * b[[2, 0, 1]] - a[[2, 0, 1]] * b[[1, 2, 0]]


# ---------------------------------------------------------------------------------------------
# The three outcomes, for W (n, r) of rank r with (near-)unit rows and xi scaled with them


def _optimal_basis(
    W: np.ndarray, xi: np.ndarray, c_r: np.ndarray, G: np.ndarray, det: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """The primal-dual feasible basis with the largest ``|det|``, as ``(u, lam)``, or None.

    Works with ``|det|``-scaled quantities (``lam_B |det|``, ``u |det|``), so singular subsets
    need no division; their rounding errors are a few ulps of ``|c|`` and ``|xi|_inf``, which
    the tests allow for on top of ``FEAS_TOL`` (module docstring).
    """
    n, r = W.shape
    B = _subsets_T(n, r)
    G = G * np.sign(det)  # now G[:, :, i] = |det| W_B^{-T}
    adet = np.abs(det)
    lam_s = (G * c_r[None, :, None]).sum(axis=1)  # lam_B |det| = G c_r, (r, m)
    lam_min = lam_s.min(axis=0)
    dual_round = -_ROUNDING * _norm(c_r)
    # min lam_B >= -FEAS_TOL sum(lam_B) (at least max|lam_B| wherever it can hold) - rounding.
    dual_ok = lam_min + FEAS_TOL * lam_s.sum(axis=0) >= dual_round
    if not dual_ok.any():
        return None
    u_s = (G * xi.take(B)[:, None, :]).sum(axis=0)  # u |det| = G^T xi_B, (r, m)
    slack_s = dense.matmul(W, u_s) - xi[:, None] * adet  # (W u - xi) |det|, (n, m)
    slack_min = slack_s.min(axis=0)
    xi_size = np.abs(xi).max()
    primal_round = -_ROUNDING * xi_size
    primal_ok = (
        slack_min + FEAS_TOL * np.abs(u_s).max(axis=0)
        >= (-FEAS_TOL * xi_size) * adet + primal_round
    )
    # Prefer bases feasible up to rounding alone (|det| <= 1 for unit rows), then the best
    # conditioned: a basis that needs FEAS_TOL is optimal only to FEAS_TOL.
    exact = (lam_min >= dual_round) & (slack_min >= primal_round)
    ok = dual_ok & primal_ok & (adet > SINGULAR_TOL)
    j = int(np.argmax(ok * (adet + 2.0 * exact)))
    if not ok[j]:
        return None
    u = u_s[:, j] / adet[j]
    lam_B = lam_s[:, j] / adet[j]
    if adet[j] < _REFINE_BELOW:
        # Cramer's rule is forward but not backward stable: on an ill-conditioned basis one
        # step of iterative refinement restores small residuals in W_B u = xi_B, W_B^T lam = c.
        inv_T = G[:, :, j] / adet[j]  # W_B^{-T}
        W_B = W[B[:, j]]
        u += dense.rmatvec(inv_T, xi[B[:, j]] - dense.matvec(W_B, u))
        lam_B += dense.matvec(inv_T, c_r - dense.rmatvec(W_B, lam_B))
    if lam_B.min() < 0:
        # Within tolerance, but clipping it would leave a residual in V^T lam = c: refit c on
        # the positive multipliers' rows instead.
        keep = lam_B > 0
        refit = dense.lstsq(W[B[keep, j]].T.copy(), c_r, -1.0)[0]
        lam_B = np.zeros(r)
        lam_B[keep] = np.maximum(refit, 0.0)
    lam = np.zeros(n)
    lam[B[:, j]] = lam_B
    return u, lam


def _farkas(W: np.ndarray, xi: np.ndarray, det: np.ndarray | None) -> np.ndarray | None:
    """A vector ``y >= 0``, ``1^T y = 1``, ``W^T y = 0`` with ``xi^T y > 0``, or None.

    Args:
        W: rows (n, r) of rank r, (near-)unit norms.
        xi: (n,).
        det: determinants of all r-subsets of W (``_subsets`` order); None when r = 0.
    """
    n, r = W.shape
    if n < r + 1:
        return None
    S = _subsets_T(n, r + 1)
    z = np.ones((1, n)) if r == 0 else det.take(_faces(n, r + 1)) * _ALTERNATING[r + 1]
    total = z.sum(axis=0)
    z = z * np.sign(total)  # y = z / |total| up to rounding: a few ulps (unit-row minors)
    allowance = FEAS_TOL * np.abs(total) + _ROUNDING
    gain = (z * xi.take(S)).sum(axis=0)  # xi^T y |total|
    xi_size = np.abs(xi).max()
    certified = (z.min(axis=0) >= -allowance) & (gain > allowance * xi_size)
    if not certified.any():
        return None
    j = int(np.argmax(np.where(certified, gain / np.maximum(np.abs(total), _ROUNDING), -np.inf)))
    y = np.maximum(z[:, j], 0.0)
    out = np.zeros(n)
    out[S[:, j]] = y / y.sum()
    return out


def _descent_ray(W: np.ndarray, c_r: np.ndarray) -> np.ndarray | None:
    """A unit extreme ray ``d`` of ``{W d >= 0}`` (rank r, unit rows) with ``c_r^T d < 0``."""
    n, r = W.shape
    if r == 0 or n < r - 1:
        return None
    D = _null_rows(W)
    size = np.sqrt((D * D).sum(axis=0))
    nonzero = size > RANK_TOL
    if not nonzero.any():
        return None
    D = D[:, nonzero] / size[nonzero]
    cd = dense.rmatvec(D, c_r)
    D = D * -np.sign(cd)
    cd = -np.abs(cd)
    good = (dense.matmul(W, D) >= -FEAS_TOL).all(axis=0) & (cd < -FEAS_TOL * _norm(c_r))
    if not good.any():
        return None
    return D[:, int(np.argmin(np.where(good, cd, np.inf)))]


def _outcome(
    W: np.ndarray,
    xi: np.ndarray,
    c: np.ndarray,
    Q: np.ndarray | None,
    G: np.ndarray | None = None,
    det: np.ndarray | None = None,
) -> FastLPResult:
    """The three outcomes in reduced coordinates ``W = V Q`` (``Q = None``: the identity).

    W has (near-)unit rows and rank r = ``W.shape[1]``; ``G, det`` are the adjugates and
    determinants of its r-subsets (None when r = 0). ``lam`` and a Farkas ``y`` refer to W's
    rows.
    """
    r = W.shape[1]
    c_perp = None
    c_r = c
    if Q is not None:
        c_r = dense.rmatvec(Q, c)
        c_perp = c - dense.matvec(Q, c_r)
        if _norm(c_perp) <= FEAS_TOL * _norm(c):
            c_perp = None
    if c_perp is None:
        if r > 0:
            best = _optimal_basis(W, xi, c_r, G, det)
        elif (xi > FEAS_TOL * np.abs(xi).max(initial=0.0)).any():
            best = None
        else:  # V = 0 and c = 0: v = 0 is optimal
            best = np.zeros(0), np.zeros(len(xi))
        if best is not None:
            u, lam = best
            v = u if Q is None else dense.matvec(Q, u)
            return FastLPResult("optimal", v, lam, dense.dot(c, v))
    y = _farkas(W, xi, det)
    if y is not None:
        return FastLPResult("infeasible", None, None, math.inf, y)
    if c_perp is not None:
        return FastLPResult("unbounded", None, None, -math.inf, -c_perp / _norm(c_perp))
    d = _descent_ray(W, c_r)
    if d is None:
        raise SolverError(
            "velocity LP: no optimal basis, Farkas vector or descent ray within tolerance",
            status="fastlp_undecided",
        )
    return FastLPResult("unbounded", None, None, -math.inf, d if Q is None else dense.matvec(Q, d))


def _solve_unit_rows(V: np.ndarray, xi: np.ndarray, c: np.ndarray) -> FastLPResult:
    """:func:`solve_velocity_lp` for rows of unit norm: find rank V, then the outcome."""
    n = len(V)
    if n >= 3:
        G, det = _adjugate(V)
        if np.abs(det).max() > RANK_TOL:
            return _outcome(V, xi, c, None, G, det)
    if n:
        # Rank < 3: the row space is spanned by V's leading right singular vectors.
        right = dense.svd(V)[2]  # columns: right singular vectors, largest first
        for r in (2, 1):
            if n >= r:
                Q = right[:, :r].copy()
                W = dense.matmul(V, Q)
                G, det = _adjugate(W)
                if np.abs(det).max() > RANK_TOL:
                    return _outcome(W, xi, c, Q, G, det)
    return _outcome(np.zeros((n, 0)), xi, c, np.zeros((3, 0)))


# ---------------------------------------------------------------------------------------------
# Public API


def solve_velocity_lp(V: np.ndarray, xi: np.ndarray, c: np.ndarray) -> FastLPResult:
    """Solve the velocity LP (eqs. 19-21) and the force LP (eqs. 22-24) by basis enumeration::

        min c^T v  s.t.  V v >= xi,  v in R^3 free;     max xi^T lam  s.t.  V^T lam = c, lam >= 0

    Args:
        V: the object's constraint matrix ``V_ob`` (n, 3), n >= 0, rows ``[n_i, r_i x n_i]``
            in the world frame with moments about the centre of mass (eq. 9).
        xi: normal hand velocities at the contacts (n,) (eq. 20).
        c: the cost, (3,); ``(0, m g, 0)`` for the paper's potential-energy rate.

    Returns:
        A :class:`FastLPResult`; on ``"optimal"``, ``v`` and ``lam`` are an optimal primal-dual
        pair (``V v >= xi``, ``V^T lam = c``, ``lam >= 0``, ``lam_i (V v - xi)_i = 0``) to the
        relative tolerances of the module docstring.

    Raises:
        SolverError: (status ``"fastlp_undecided"``) when rounding leaves none of the three
            outcomes certified: only for a problem within the tolerances of the boundary
            between two outcomes, or so ill-conditioned (bases with unit-row determinants
            near ``SINGULAR_TOL``) that its answer is not determined in double precision.
            The caller may fall back to :func:`grasp_env.lp.solve`.
    """
    V = np.asarray(V, dtype=float).reshape(-1, 3)
    xi = np.asarray(xi, dtype=float).reshape(-1)
    c = np.asarray(c, dtype=float).reshape(3)
    row_norm = np.sqrt((V * V).sum(axis=1))
    if not row_norm.all():
        return _with_zero_rows(V, xi, c, row_norm)
    # Scaling row i by 1/|V_i| leaves the velocity LP unchanged and scales lam_i by |V_i|.
    res = _solve_unit_rows(V / row_norm[:, None], xi / row_norm, c)
    if res.status == "optimal":
        return FastLPResult("optimal", res.v, res.lam / row_norm, res.value)
    if res.status == "infeasible":
        y = res.certificate / row_norm
        return FastLPResult("infeasible", None, None, math.inf, y / y.sum())
    return res


def _with_zero_rows(
    V: np.ndarray, xi: np.ndarray, c: np.ndarray, row_norm: np.ndarray
) -> FastLPResult:
    """Rows ``V_i = 0`` are the constraints ``0 >= xi_i``: a Farkas vector ``e_i`` or void."""
    zero = row_norm == 0
    worst = int(np.argmax(np.where(zero, xi, -np.inf)))
    if xi[worst] > FEAS_TOL * np.abs(xi).max():
        y = np.zeros(len(V))
        y[worst] = 1.0
        return FastLPResult("infeasible", None, None, math.inf, y)
    res = solve_velocity_lp(V[~zero], xi[~zero], c)
    if res.status == "optimal":
        lam = np.zeros(len(V))
        lam[~zero] = res.lam
        return FastLPResult("optimal", res.v, lam, res.value)
    if res.status == "infeasible":
        y = np.zeros(len(V))
        y[~zero] = res.certificate
        return FastLPResult("infeasible", None, None, math.inf, y)
    return res


def form_closure_fast(V: np.ndarray) -> bool:
    """Form closure (section 2.5): ``V v >= 0`` only for ``v = 0`` (V's rows positively span R^3).

    With ``rank V = 3`` the cone ``{V d >= 0}`` is pointed, so it is not ``{0}`` exactly when it
    has an extreme ray, which is ``+-(V_i x V_j)`` for an independent pair of rows; with
    ``rank V = 2`` such a cross product has ``V d = 0``, and with ``rank V <= 1`` no pair is
    independent. Rays count as admissible to ``V_i d >= -FEAS_TOL`` (unit rows and d), pairs as
    independent to ``RANK_TOL``.

    Args:
        V: the object's constraint matrix (n, 3) (eq. 9).
    """
    V = np.asarray(V, dtype=float).reshape(-1, 3)
    row_norm = np.sqrt((V * V).sum(axis=1))
    V = V[row_norm > 0] / row_norm[row_norm > 0, None]
    if len(V) < 4:
        return False
    D = _null_rows(V)
    size = np.sqrt((D * D).sum(axis=0))
    nonzero = size > RANK_TOL
    if not nonzero.any():
        return False
    M = dense.matmul(V, D[:, nonzero] / size[nonzero])
    escape = (M >= -FEAS_TOL).all(axis=0) | (M <= FEAS_TOL).all(axis=0)
    return not bool(escape.any())
