"""Tiny exact least-norm problems in three variables: ``min 1/2 |w|^2 s.t. A w = b,
C w >= d`` (the compiled active-set enumeration of :mod:`grasp_env.solvers.least_norm`).

The simulator uses it for the least-motion object velocity on the LP's optimal face and
for the steepest admissible descent of a fall.
"""

from __future__ import annotations

import numpy as np

from grasp_env.errors import SolverError
from grasp_env.solvers import least_norm as kernel


def least_norm(
    A: np.ndarray, b: np.ndarray, C: np.ndarray, d: np.ndarray, tol: float = 1e-10
) -> np.ndarray:
    """Solve ``min 1/2 |w|^2 s.t. A w = b, C w >= d`` for ``w`` in R^3.

    Args:
        A, b: equality rows (m, 3) and (m,).
        C, d: inequality rows (k, 3) and (k,).
        tol: feasibility and multiplier tolerance, relative to the rows' scale.

    Raises:
        SolverError: the constraints are infeasible (status ``"infeasible"``).
    """
    w, found = kernel.least_norm(_rows(A), _vector(b), _rows(C), _vector(d), float(tol))
    if not found:
        raise SolverError("least-norm problem has no feasible point", status="infeasible")
    return w


def _rows(M: np.ndarray) -> np.ndarray:
    """``M`` as contiguous float rows of 3 (a copy only when needed)."""
    M = np.ascontiguousarray(M, dtype=np.float64)
    return M if M.ndim == 2 else M.reshape(-1, 3)


def _vector(v: np.ndarray) -> np.ndarray:
    """``v`` as a contiguous float vector (a copy only when needed)."""
    v = np.ascontiguousarray(v, dtype=np.float64)
    return v if v.ndim == 1 else v.reshape(-1)
