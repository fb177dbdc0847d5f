"""Small linear programs: the reference path through HiGHS (``scipy.optimize.linprog``).

Every LP of the project goes through :func:`solve`, which returns a :class:`LPResult` with the
status in words (``"optimal"``, ``"infeasible"``, ``"unbounded"``) and the duals of the
inequality and equality rows, so a faster specialised solver can replace it behind one name.
"""

from __future__ import annotations

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
) -> LPResult:
    """Solve a small LP with HiGHS; raise :class:`SolverError` on any status but the three above."""
    from scipy.optimize import linprog  # on first use: scipy.optimize is slow to import

    if A_ub is not None and len(A_ub) == 0:
        A_ub = b_ub = None
    if A_eq is not None and len(A_eq) == 0:
        A_eq = b_eq = None

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
            **options,
        )

    res = highs(c)
    if res.status in (2, 4):
        # HiGHS' presolve may only say "infeasible or unbounded", or (rarely, on tiny
        # degenerate problems) call a feasible one infeasible: decide without presolve, and
        # failing that by the feasibility problem (zero objective).
        res = highs(c, options={"presolve": False})
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


def velocity_lp(V: np.ndarray, xi: np.ndarray, weight: float) -> LPResult:
    """The velocity formulation of the motion LP (eqs. 19-21), ``min W v_y  s.t.  V v >= xi``
    with ``v`` free; its duals (``-duals_ub``) are the contact forces of the force LP."""
    return solve(np.array([0.0, weight, 0.0]), A_ub=-V, b_ub=-xi, bounds=(None, None))
