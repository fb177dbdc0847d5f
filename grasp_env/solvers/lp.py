"""Small linear programs: the reference path through HiGHS (``scipy.optimize.linprog``).

Every LP of the project goes through :func:`solve`, which returns a :class:`LPResult` with the
status in words (``"optimal"``, ``"infeasible"``, ``"unbounded"``) and the duals of the
inequality and equality rows, so a faster specialised solver can replace it behind one name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from grasp_env.errors import SolverError

#: How an LP ended.
LPStatus = Literal["optimal", "infeasible", "unbounded"]
_STATUS: dict[int, LPStatus] = {0: "optimal", 2: "infeasible", 3: "unbounded"}


@dataclass(frozen=True)
class LPResult:
    """Outcome of ``min c^T x s.t. A_ub x <= b_ub, A_eq x = b_eq, bounds``.

    ``duals_ub`` (<= 0) and ``duals_eq`` are the sensitivities of the optimum to ``b_ub`` and
    ``b_eq`` (HiGHS marginals); they are ``None`` unless the status is ``"optimal"``.
    """

    status: LPStatus
    x: np.ndarray | None
    value: float
    duals_ub: np.ndarray | None = None
    duals_eq: np.ndarray | None = None


def solve(
    c: np.ndarray,
    A_ub: np.ndarray | None = None,
    b_ub: np.ndarray | None = None,
    A_eq: np.ndarray | None = None,
    b_eq: np.ndarray | None = None,
    bounds: object = (None, None),
    tolerance: float | None = None,
) -> LPResult:
    """Solve a small LP with HiGHS; raise :class:`SolverError` on any status but the three
    above. ``tolerance`` sets HiGHS' primal and dual feasibility tolerances (absolute; 1e-7 by
    default)."""
    from scipy.optimize import linprog  # on first use: scipy.optimize is slow to import

    if A_ub is not None and len(A_ub) == 0:
        A_ub = b_ub = None
    if A_eq is not None and len(A_eq) == 0:
        A_eq = b_eq = None

    tolerances = (
        {}
        if tolerance is None
        else {"primal_feasibility_tolerance": tolerance, "dual_feasibility_tolerance": tolerance}
    )

    def highs(cost: np.ndarray, **options: Any):
        """HiGHS on these constraints with objective ``cost``."""
        return linprog(
            cost,
            A_ub=A_ub,
            b_ub=b_ub,
            A_eq=A_eq,
            b_eq=b_eq,
            bounds=bounds,
            method="highs",
            options={**tolerances, **options},
        )

    res = highs(c)
    if res.status in (2, 4):
        # HiGHS' presolve may only say "infeasible or unbounded", or (rarely, on tiny
        # degenerate problems) call a feasible one infeasible: decide without presolve, and
        # failing that by the feasibility problem (zero objective).
        res = highs(c, presolve=False)
        if res.status == 4:
            res.status = 3 if highs(np.zeros_like(c)).status == 0 else 2
    status = _STATUS.get(res.status)
    if status is None:
        raise SolverError(f"HiGHS failed: {res.message}", status=f"highs_{res.status}")
    if status == "unbounded":
        return LPResult(status, None, -np.inf)
    if status == "infeasible":
        return LPResult(status, None, np.inf)
    duals_ub = res.ineqlin.marginals if A_ub is not None else np.zeros(0)
    duals_eq = res.eqlin.marginals if A_eq is not None else np.zeros(0)
    return LPResult(status, res.x, float(res.fun), duals_ub, duals_eq)


#: HiGHS' feasibility tolerances for the second solve of :func:`velocity_lp`.
TIGHT = 1e-10


def velocity_lp(V: np.ndarray, xi: np.ndarray, weight: float) -> LPResult:
    """The velocity formulation of the motion LP (eqs. 19-21), ``min W v_y  s.t.  V v >= xi``
    with ``v`` free; its duals (``-duals_ub``) are the contact forces of the force LP.

    HiGHS' feasibility tolerance is absolute (1e-7): for ``xi`` of 1e-5 it would leave rows
    violated by a hundredth of their size. The LP is solved with ``xi`` scaled to about one
    (by a power of two, exactly): ``v`` and the optimum scale with ``xi``, the forces do not.
    An optimum is solved again at :data:`TIGHT` (rows held to 1e-7 of ``xi`` can leave the
    optimum off by a fraction of a percent on degenerate contact sets), and kept where HiGHS
    reports one: on nearly dependent rows it may not, and the first answer stands.
    """
    xi = np.asarray(xi, dtype=float)
    largest = float(np.max(np.abs(xi), initial=0.0))
    scale = math.ldexp(1.0, math.frexp(largest)[1]) if 0.0 < largest < math.inf else 1.0
    problem = {"A_ub": -V, "b_ub": -xi / scale, "bounds": (None, None)}
    cost = np.array([0.0, weight, 0.0])
    res = solve(cost, **problem)
    if res.status != "optimal":
        return res
    try:
        tight = solve(cost, **problem, tolerance=TIGHT)
        if tight.status == "optimal":
            res = tight
    except SolverError:
        pass  # the first answer stands
    return LPResult(res.status, res.x * scale, res.value * scale, res.duals_ub, res.duals_eq)
