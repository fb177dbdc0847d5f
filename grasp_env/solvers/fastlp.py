"""Exact basis enumeration for the velocity LP (eqs. 19-21) and its dual, the force LP (22-24).

The simulator's hot-path LP has three variables (the object twist) and a handful of rows (the
contacts), so every basis can be tried instead of pivoting, in one compiled call
(:func:`grasp_env.solvers.velocity_lp.solve`: numba, no BLAS, the same bits on every machine)::

    velocity LP (primal):  min c^T v        s.t.  V v >= xi,          v in R^3 free
    force LP (dual):       max xi^T lam     s.t.  V^T lam = c,        lam >= 0

with ``V = V_ob`` (n, 3) of :mod:`grasp_env.mechanics.closure` (rows ``[n_i, r_i x n_i]``), ``xi``
(n,) from eq. 20 and ``c = m gamma = (0, m g, 0)``.

Method. Scaling row i (and ``xi_i``) by ``1 / |V_i|`` leaves the velocity LP unchanged and
scales ``lam_i`` by ``|V_i|``, so the rows are made unit first (zero rows are the constraints
``0 >= xi_i``). Let ``r = rank V`` and ``Q`` (3, r) an orthonormal basis of V's row space
(``Q = I`` when r = 3); the problem lives in the coordinates ``W = V Q``, ``v = Q u``.

* A basis is an r-subset ``B`` of the rows with ``W_B`` nonsingular; its primal point is
  ``u = W_B^{-1} xi_B`` and its multipliers ``lam_B = W_B^{-T} Q^T c`` (zero off ``B``).
  Complementary slackness holds by construction, so a basis with ``lam_B >= 0`` and
  ``W u >= xi`` is an optimal primal-dual pair, and one exists whenever both LPs are
  feasible (the simplex method ends on one). Every basis is solved with its closed-form
  adjugate (cross products for r = 3); the optimal one with the largest ``|det W_B|`` is
  returned, preferring those that need no tolerance beyond rounding.
* Otherwise the velocity LP is infeasible if a Farkas vector exists: ``y >= 0``,
  ``1^T y = 1``, ``V^T y = 0``, ``xi^T y > 0``. The vertices of that polytope have supports
  of r + 1 rows, on which ``y`` is the signed-minor null vector of ``W_S^T``; all are tried
  and the one with the largest ``xi^T y`` is returned.
* Otherwise it is unbounded, which a descent ray (``V d >= 0``, ``c^T d < 0``) certifies:
  ``-c_perp`` when ``c`` leaves the row space, else an extreme ray of the pointed cone
  ``{W d >= 0}``, the null vector of r - 1 rows; all are tried and the steepest (least
  ``c^T d``) is returned.

In exact arithmetic exactly one of the three is found. A problem that is both primal and dual
infeasible is reported ``"infeasible"``, as HiGHS does. Row subsets are visited in
lexicographic order, and of equally good candidates the first is kept.

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

from dataclasses import dataclass

import numpy as np

from grasp_env.errors import SolverError
from grasp_env.solvers import velocity_lp
from grasp_env.solvers.lp import LPStatus
from grasp_env.solvers.velocity_lp import FEAS_TOL, RANK_TOL, SINGULAR_TOL

__all__ = [
    "FEAS_TOL",
    "RANK_TOL",
    "SINGULAR_TOL",
    "FastLPResult",
    "form_closure_fast",
    "solve_velocity_lp",
]

_STATUS = {
    velocity_lp.OPTIMAL: "optimal",
    velocity_lp.INFEASIBLE: "infeasible",
    velocity_lp.UNBOUNDED: "unbounded",
}


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
            unbounded (the convention of :class:`grasp_env.solvers.lp.LPResult`).
        certificate: when infeasible a Farkas vector ``y`` (n,), ``y >= 0``, ``1^T y = 1``,
            ``V^T y = 0``, ``xi^T y > 0``; when unbounded a unit twist ``d`` (3,) with
            ``V d >= 0`` and ``c^T d < 0``; None when optimal.
    """

    status: LPStatus
    v: np.ndarray | None
    lam: np.ndarray | None
    value: float
    certificate: np.ndarray | None = None


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
            The caller may fall back to :func:`grasp_env.solvers.lp.solve`.
    """
    V, xi, c = _arrays(V, xi, c)
    status, v, lam, value, certificate = velocity_lp.solve(V, xi, c)
    if status == velocity_lp.UNDECIDED:
        raise SolverError(
            "velocity LP: no optimal basis, Farkas vector or descent ray within tolerance",
            status="fastlp_undecided",
        )
    if status == velocity_lp.OPTIMAL:
        return FastLPResult("optimal", v, lam, value)
    return FastLPResult(_STATUS[status], None, None, value, certificate)


def _writeable(a: np.ndarray) -> np.ndarray:
    return a if a.flags.writeable else a.copy()


def _arrays(
    V: np.ndarray, xi: np.ndarray, c: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``V`` (n, 3), ``xi`` (n,) and ``c`` (3,) as contiguous, writeable float arrays for the
    kernel (a read-only array, such as a state's, is copied: the compiled kernel takes one
    type of array, and another would be compiled again)."""
    V, xi, c = (_writeable(np.ascontiguousarray(a, dtype=float)) for a in (V, xi, c))
    if V.ndim != 2 or V.shape[1] != 3:
        V = V.reshape(-1, 3)
    if xi.ndim != 1:
        xi = xi.reshape(-1)
    if c.shape != (3,):
        c = c.reshape(3)
    if len(xi) != len(V):
        raise ValueError(f"xi has {len(xi)} entries for {len(V)} rows of V")
    return V, xi, c


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
    return velocity_lp.form_closure(np.ascontiguousarray(V, dtype=float).reshape(-1, 3))
