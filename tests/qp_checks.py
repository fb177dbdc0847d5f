"""Independent checks of a least-norm QP solution, shared by the QP and closure tests."""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear, minimize


def kkt_violation(w, A, b, C, d, active_tol=1e-9) -> float:
    """Largest violation of the KKT conditions of ``min |w|^2/2 s.t. A w = b, C w >= d``:
    primal feasibility, and ``w = A^T mu + C_act^T lam`` with ``lam >= 0`` on the rows
    active to within ``active_tol`` (bounded least squares for the multipliers)."""
    viol = [0.0]
    if len(A):
        viol.append(float(np.abs(A @ w - b).max()))
    if len(C):
        viol.append(float(max(0.0, (d - C @ w).max())))
    act = C[np.abs(C @ w - d) <= active_tol] if len(C) else np.zeros((0, 3))
    M = np.vstack([A, act]).T
    if M.shape[1] == 0:
        return max(*viol, float(np.abs(w).max()))
    lower = np.r_[np.full(len(A), -np.inf), np.zeros(len(act))]
    fit = lsq_linear(M, w, bounds=(lower, np.full(M.shape[1], np.inf)), method="bvls")
    return max(*viol, float(np.abs(M @ fit.x - w).max()))


def slsqp(A, b, C, d, start) -> np.ndarray | None:
    """SLSQP's solution, or None when it reports failure."""
    cons = []
    if len(A):
        cons.append({"type": "eq", "fun": lambda x: A @ x - b, "jac": lambda x: A})
    if len(C):
        cons.append({"type": "ineq", "fun": lambda x: C @ x - d, "jac": lambda x: C})
    res = minimize(
        lambda x: 0.5 * x @ x,
        start,
        jac=lambda x: x,
        constraints=cons,
        method="SLSQP",
        options={"ftol": 1e-15, "maxiter": 500},
    )
    return res.x if res.success else None
