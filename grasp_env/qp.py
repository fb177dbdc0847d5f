"""Tiny exact least-norm problems in three variables, by enumerating active sets.

``min 1/2 |w|^2  s.t.  A w = b,  C w >= d`` with ``w`` in R^3 has at most three independent
active rows at the optimum, so trying every small active set and keeping the one that meets
the KKT conditions solves it exactly. The simulator uses it for the least-motion object
velocity on the LP's optimal face and for the steepest admissible descent of a fall.
"""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np

from grasp_env.errors import SolverError
from grasp_env.sim import dense


def _min_norm_eq(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-norm solution of ``A w = b`` (least squares if inconsistent), its multipliers and
    the residual norm. ``w = A^T mu``."""
    if len(A) == 0:
        return np.zeros(3), np.zeros(0), 0.0
    # lstsq on A itself (not A A^T, which squares the condition number)
    w = dense.lstsq(A, b, 1e-13)[0]
    mu = dense.lstsq(A.T.copy(), w, 1e-13)[0]
    r = dense.matvec(A, w) - b
    return w, mu, math.sqrt(dense.dot(r, r))


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
    scale = max(1.0, float(np.abs(b).max(initial=0.0)), float(np.abs(d).max(initial=0.0)))
    best = None
    for size in range(0, min(3, len(C)) + 1):
        for S in combinations(range(len(C)), size):
            idx = list(S)
            AS = np.vstack([A, C[idx]]) if size else A
            bS = np.concatenate([b, d[idx]]) if size else b
            w, mu, res = _min_norm_eq(AS.reshape(-1, 3), bS)
            if res > tol * scale:
                continue
            if size and mu[len(A) :].min() < -tol * scale:
                continue
            if len(C) and (dense.matvec(C, w) - d).min() < -tol * scale:
                continue
            nrm = dense.dot(w, w)
            if best is None or nrm < best[0] - 1e-15:
                best = (nrm, w)
        if best is not None:
            return best[1]
    raise SolverError("least-norm problem has no feasible point", status="infeasible")
