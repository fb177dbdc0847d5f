"""The motion LP of a hand velocity (eqs. 19-24) by either path: the exact basis
enumeration (:mod:`grasp_env.solvers.fastlp`) or HiGHS (:mod:`grasp_env.solvers.lp`), and
the force LP (eqs. 22-24) that the tests check duality with."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from grasp_env.errors import SolverError
from grasp_env.solvers import fastlp, lp
from grasp_env.solvers.lp import LPStatus


@dataclass(frozen=True)
class MotionLP:
    """Solution of the velocity LP (eqs. 19-21) and its dual, the force LP (eqs. 22-24).

    Attributes:
        status: ``"optimal"``, ``"infeasible"`` (velocity LP: the hand motion cannot happen, a
            jam) or ``"unbounded"`` (velocity LP: the object can lower its potential energy
            without limit, the force LP is infeasible: a fall).
        velocity: an optimal object twist (3,) or None.
        forces: the contact forces ``lambda`` (n,) of the force LP or None.
        value: the common optimum ``m g^T dq_ob = xi^T lambda`` (duality).
    """

    status: LPStatus
    velocity: np.ndarray | None
    forces: np.ndarray | None
    value: float


def force_lp(V: np.ndarray, xi_: np.ndarray, weight: float) -> lp.LPResult:
    """Force formulation (eqs. 22-24): ``max xi^T lam  s.t.  V^T lam = m gamma, lam >= 0``.

    Returned as the minimisation of ``-xi^T lam``: its ``value`` is minus the optimum. A
    reference for the tests, solved at tight tolerances (1e-10): at HiGHS' default dual
    tolerance a cost of 1e-5 beside one of 1 (``xi`` of a slow contact beside a fast one) may
    stop at a vertex short of the optimum by a percent of that small term.
    """
    b = np.array([0.0, weight, 0.0])
    return lp.solve(-xi_, A_eq=V.T, b_eq=b, bounds=(0, None), tolerance=1e-10)


def motion_lp(V: np.ndarray, xi_: np.ndarray, weight: float, solver: str = "fast") -> MotionLP:
    """Object motion for a hand velocity: both formulations, checked against each other.

    The velocity LP gives the object twist and its dual values the contact forces, which solve the
    force LP (their optima agree by duality, eq. 19 = eq. 22; the tests check it with
    :func:`force_lp`). ``solver="fast"`` uses the exact basis enumeration of
    :mod:`grasp_env.solvers.fastlp` (falling back to HiGHS when it cannot decide); ``"highs"`` is
    the reference path.
    """
    if solver == "fast":
        try:
            res = fastlp.solve_velocity_lp(V, xi_, np.array([0.0, weight, 0.0]))
            return MotionLP(res.status, res.v, res.lam, res.value)
        except SolverError:
            pass  # undecided in double precision: the reference path decides
    vel = lp.velocity_lp(V, xi_, weight)
    if vel.status != "optimal":
        return MotionLP(vel.status, None, None, vel.value)
    # The force LP's solution is the velocity LP's dual (HiGHS marginals of V v >= xi).
    return MotionLP("optimal", vel.x, -vel.duals_ub, vel.value)
