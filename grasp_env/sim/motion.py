"""The object's motion for a hand velocity: the active set and the least-motion twist
(section 3.1, eqs. 19-24).

The velocity LP ``min W v_y s.t. V v >= xi`` and its dual, the force LP, give the object
twist and the contact forces (:mod:`grasp_env.solvers.velocity_lp`, or HiGHS on the reference
path). The contacts with positive force, and the touching ones the hand pushes on, form the
active set ``E``; of the optimal twists the least-motion one is kept
(:mod:`grasp_env.solvers.least_norm`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, objmode

from grasp_env.compiled import CACHE
from grasp_env.errors import SolverError
from grasp_env.sim import contact_sets
from grasp_env.sim.dependence import free_rows
from grasp_env.sim.hand import contact_xi
from grasp_env.sim.placement import contact_rows
from grasp_env.sim.pose import constraint_matrix
from grasp_env.solvers import dense, least_norm, lp, velocity_lp

#: Outcomes of a plan: the object moves with the hand, the hand cannot move on, the object
#: falls.
MOVE, JAM, FALL = 0, 1, 2


def reference_motion_lp(V: np.ndarray, xi: np.ndarray, weight: float) -> tuple:
    """The motion LP through HiGHS (:func:`grasp_env.solvers.lp.velocity_lp`, whose duals are the
    contact forces), as ``(status, v, lam, value)`` with :mod:`grasp_env.solvers.velocity_lp`'s
    status codes."""
    res = lp.velocity_lp(V, xi, weight)
    if res.status == "optimal":
        return velocity_lp.OPTIMAL, res.x, -res.duals_ub, res.value
    status = velocity_lp.INFEASIBLE if res.status == "infeasible" else velocity_lp.UNBOUNDED
    return status, np.zeros(3), np.zeros(len(xi)), res.value


@njit(cache=CACHE)
def motion_lp(model, V: np.ndarray, xi: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, float]:
    """``min W v_y s.t. V v >= xi`` and its dual: ``(status, v, lam, value)``. The exact basis
    enumeration; where it cannot decide at its tolerance, again with the looser dual
    tolerance of a cost on the boundary of equilibrium (a force just reaching zero,
    :data:`grasp_env.solvers.velocity_lp.BOUNDARY_TOL`); HiGHS on the reference path and where
    that cannot decide either (through Python: with ``model.python_lp`` False a
    ``SolverError`` instead, for the caller to move again from Python)."""
    if not model.reference_lp:
        cost = np.array([0.0, model.weight, 0.0])
        for dual_tol in (velocity_lp.FEAS_TOL, velocity_lp.BOUNDARY_TOL):
            status, v, lam, value, _ = velocity_lp.solve(V, xi, cost, dual_tol)
            if status != velocity_lp.UNDECIDED:
                return status, v, lam, value
    if not model.python_lp:
        raise SolverError("the motion LP needs the reference solver, through Python")
    with objmode(status="int64", v="float64[:]", lam="float64[:]", value="float64"):
        status, v, lam, value = reference_motion_lp(V, xi, model.weight)
    return status, v, lam, value


@njit(cache=CACHE)
def solve_lp(
    model, world: np.ndarray, q: np.ndarray, h: np.ndarray, dh: np.ndarray, keys: np.ndarray
) -> tuple[int, float, np.ndarray, np.ndarray]:
    """The motion of the object touching ``keys`` for hand velocity ``dh``:
    ``(outcome, value, E, v)`` with the potential-energy rate, the active set and the
    least-motion object twist (per unit of the path parameter)."""
    m = keys.shape[0]
    L = model.length
    P, N, _, _, _ = contact_rows(world, model.n_object, model.n_vertices, keys)
    V = free_rows(model, constraint_matrix(P, N, q[:2]))
    xi = contact_xi(model, h, dh, keys, P, N)
    Vl = V * model.per_length
    if m > 0 and not np.any(xi):
        # The hand moves no contact (the object on the support, the fingers in free space):
        # v = 0 is optimal, with every contact tight, whenever the contacts hold the object
        # exactly; only the borderline cases need the LP.
        if dense.nnls(Vl.T.copy(), model.gravity)[1] <= 1e-12 * model.weight:
            return MOVE, 0.0, keys, np.zeros(3)
    status, v_lp, lam, value = motion_lp(model, Vl, xi / L)
    if status == velocity_lp.INFEASIBLE:
        return JAM, 0.0, keys, np.zeros(3)
    if status == velocity_lp.UNBOUNDED:
        return FALL, 0.0, keys, np.zeros(3)
    # the least-motion twist among the optimal ones: the contacts with force kept tight,
    # the others kept apart or tight, in twists scaled to displacements
    pos = lam > model.ftol
    n_pos = 0
    for i in range(m):
        n_pos += pos[i]
    A_eq, b_eq = np.empty((n_pos, 3)), np.empty(n_pos)
    A_in, b_in = np.empty((m - n_pos, 3)), np.empty(m - n_pos)
    e = f = 0
    for i in range(m):
        if pos[i]:
            for k in range(3):
                A_eq[e, k] = V[i, k] * model.scale[k]
            b_eq[e] = xi[i] / L
            e += 1
        else:
            for k in range(3):
                A_in[f, k] = V[i, k] * model.scale[k]
            b_in[f] = xi[i] / L
            f += 1
    w, ok = least_norm.least_norm(A_eq, b_eq, A_in, b_in, 1e-9)
    v = np.empty(3)
    for k in range(3):
        if ok:
            v[k] = w[k] * L * model.scale[k]
        else:
            v[k] = v_lp[k] * L * model.per_length[k] / model.scale[k] * model.scale[k]
    largest = 0.0
    for i in range(m):
        largest = max(largest, abs(xi[i]))
    bound = 1e-9 * max(L, largest)
    for i in range(m):  # the contacts with force, and those the twist keeps touching
        slack = 0.0
        for k in range(3):
            slack += V[i, k] * v[k]
        pos[i] = pos[i] or slack - xi[i] <= bound
    return MOVE, value * L, keys[pos], v


@njit(cache=CACHE)
def plan(
    model, world: np.ndarray, q: np.ndarray, h: np.ndarray, dh: np.ndarray, keys: np.ndarray,
    allow_fall: bool,
) -> tuple[int, np.ndarray, np.ndarray]:  # fmt: skip
    """Active set and least-motion twist for hand velocity ``dh``: ``(outcome, E, v)``.

    At a vertex-vertex touch each choice of candidate contacts
    (:func:`grasp_env.sim.contact_sets.choices`) is tried, and the one with the lowest
    potential-energy rate (the object's choice, eq. 19) is kept; all candidates at once
    (always admissible) is the last choice. With ``allow_fall`` False (a fall just found no
    way down) choices that would fall are skipped.
    """
    options = contact_sets.choices(model, world, keys)
    if len(options) > 1:
        options.append(keys)
    found = False
    best_value = np.inf
    best_E, best_v = keys, np.zeros(3)
    for choice in options:
        outcome, value, E, v = solve_lp(model, world, q, h, dh, choice)
        if outcome == FALL:
            if allow_fall:
                return FALL, keys, np.zeros(3)
            continue
        if outcome == JAM:
            continue
        if not found or value < best_value - 1e-12 * model.weight * model.length:
            found, best_value, best_E, best_v = True, value, E, v
    if not found:
        return JAM, keys, np.zeros(3)
    return MOVE, best_E, best_v
