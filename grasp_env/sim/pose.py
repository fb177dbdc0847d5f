"""The object pose on a set of closed contacts: Newton's method on their gap equations.

``phi_E(q, h) = 0`` for the active contacts ``E`` (rows of ``keys``, see
:mod:`grasp_env.sim.placement`) is solved for the object pose ``q`` with the exact
Jacobian ``V_ob`` (the gap gradient, rows ``[n_i, r_i x n_i]``), scaled so that a rotation
counts like a translation of the radius of gyration (``scale = (1, 1, rho)``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.placement import (
    TIP,
    contact_rows_into,
    object_points_into,
    world_points_into,
)
from grasp_env.solvers import dense

#: Newton iterations before a solve counts as failed.
ITERATIONS = 30


@njit(cache=CACHE)
def constraint_matrix(P: np.ndarray, N: np.ndarray, com: np.ndarray) -> np.ndarray:
    """``V_ob`` (m, 3) (eq. 9): row i maps an object twist to the normal velocity of the
    object's material point at contact i, ``[n_i, r_i x n_i]`` with ``r_i = p_i - com``."""
    V = np.empty((P.shape[0], 3))
    constraint_matrix_into(P, N, com, V)
    return V


@njit(cache=CACHE, inline="always")
def constraint_matrix_into(P: np.ndarray, N: np.ndarray, com: np.ndarray, V: np.ndarray) -> None:
    """:func:`constraint_matrix` into ``V`` (m, 3); ``com``'s first two entries are the
    centre of mass."""
    for i in range(P.shape[0]):
        rx, ry = P[i, 0] - com[0], P[i, 1] - com[1]
        V[i, 0] = N[i, 0]
        V[i, 1] = N[i, 1]
        V[i, 2] = rx * N[i, 1] - ry * N[i, 0]


@njit(cache=CACHE)
def independent_forces(W: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, bool]:
    """Least-squares forces ``lam`` with ``W lam ~ g`` for up to three contact wrenches (the
    columns of ``W``), and False when the wrenches are dependent. Three wrenches: a direct
    solve after a unit-column volume test (> 1e-10); fewer: the normal equations when the
    unit-column Gram determinant exceeds 1e-6 (squaring the condition number is harmless
    there), else least squares after a rank test (1e-10)."""
    m = W.shape[1]
    norms = np.empty(m)
    for j in range(m):
        norms[j] = math.sqrt(W[0, j] * W[0, j] + W[1, j] * W[1, j] + W[2, j] * W[2, j])
        if norms[j] == 0.0:
            return np.zeros(m), False
    U = W / norms
    if m == 3:
        volume, lam, ok = dense.det_and_solve(U, W, g)
        if abs(volume) <= 1e-10:
            return np.zeros(m), False
        return lam, ok
    G = np.empty((m, m))  # U^T U, summed in U's row order
    b = np.empty(m)  # U^T g
    for i in range(m):
        for j in range(m):
            acc = 0.0
            for k in range(3):
                acc += U[k, i] * U[k, j]
            G[i, j] = acc
        acc = 0.0
        for k in range(3):
            acc += U[k, i] * g[k]
        b[i] = acc
    volume, lam, ok = dense.det_and_solve(G, G, b)
    if volume > 1e-6 and ok:
        for j in range(m):
            lam[j] /= norms[j]
        return lam, True
    if dense.rank(W, 1e-10) < m:
        return np.zeros(m), False
    return dense.lstsq(W, g, -1.0)[0], True


@njit(cache=CACHE, inline="always")
def largest_step(dz: np.ndarray) -> float:
    """The largest ``|dz[k]|`` of a step's three pose entries; NaN if any is NaN (as numpy's
    ``max``), which no bound rejects."""
    largest = 0.0
    for k in range(3):
        step = abs(dz[k])
        if step != step:
            return step
        largest = max(largest, step)
    return largest


@njit(cache=CACHE)
def newton(
    points: np.ndarray, body: np.ndarray, n_object: int, n_vertices: int, half: float,
    q0: np.ndarray, h: np.ndarray, keys: np.ndarray, scale: np.ndarray, newton_tol: float,
    tol: float, size: float,
) -> tuple[np.ndarray, bool]:  # fmt: skip
    """Solve ``phi_E(q, h) = 0`` from ``q0`` by least-motion Newton steps: ``(q, ok)``.

    Converged when every gap is within ``newton_tol``. Dependent equations (more than three
    contacts, several on one straight edge, or equations dependent to tolerance: singular
    values of the scaled Jacobian at most ``tol / size``, along which a displacement of the
    object's size changes no gap by more than ``tol``) may be consistent only to the
    contacts' own tolerance: no step is taken along their dependent directions, and they
    count as solved when least squares stalls within half of ``tol``. A step larger than the
    object's ``size`` left Newton's basin.
    """
    m = keys.shape[0]
    q = q0.copy()
    last = np.inf
    redundant = False
    # the iterations' arrays, made once (a solve runs up to ITERATIONS of them)
    world = np.empty_like(points)
    rows = np.empty((m, 7))
    P, N, F = rows[:, 0:2], rows[:, 2:4], rows[:, 4]
    J = np.empty((m, 3))
    LU = np.empty((3, 3))
    perm = np.empty(3, dtype=np.int64)
    rhs = np.empty(m)
    du = np.empty(3)
    world_points_into(points, body, n_vertices, half, q, h, world)  # the hand's rows stay
    for it in range(ITERATIONS):
        if it > 0:
            object_points_into(points, n_object, n_vertices, q, world)
        contact_rows_into(world, n_object, n_vertices, keys, rows)
        res = 0.0
        for i in range(m):
            res = max(res, abs(F[i]))
        if res <= newton_tol:
            return q, True
        if redundant and res <= 0.5 * tol and res > 0.5 * last:
            return q, True
        last = res
        constraint_matrix_into(P, N, q, J)
        for i in range(m):
            for k in range(3):
                J[i, k] *= scale[k]
            rhs[i] = -F[i]
        ok = False
        # square and well conditioned (its smallest singular value above tol / size, as the
        # rows, of norm at most 4, bound the other two): no SVD needed
        if m == 3:
            LU[:] = J
            sign = dense.lu_in_place(LU, perm)
            if abs(dense.lu_det(LU, sign)) > max(1e-8, 16.0 * tol / size):
                ok = dense.lu_solve(LU, perm, rhs, du)
        if not ok:
            redundant = dense.lstsq_into(J, rhs, 1e-12, tol / size, du) < m
        if largest_step(du) > size:
            return q, False  # a near-singular step far outside Newton's basin
        for k in range(3):
            q[k] = q[k] + du[k] * scale[k]
        for k in range(3):
            if not math.isfinite(q[k]):
                return q, False
    return q, False


@njit(cache=CACHE)
def newton_held(
    points: np.ndarray, body: np.ndarray, n_object: int, n_vertices: int, half: float,
    q0: np.ndarray, h: np.ndarray, keys: np.ndarray, scale: np.ndarray, rho: float,
    g: np.ndarray, newton_tol: float, size: float,
) -> tuple[np.ndarray, bool]:  # fmt: skip
    """Pose held by fewer than three contacts: ``phi_E(q, h) = 0`` together with the
    object's equilibrium ``W_E(q) lam = g`` (the KKT conditions of least potential energy on
    the contacts' family of poses), by Newton on ``(q, lam)``: ``(q, ok)``.

    ``g`` is the gravity wrench in object weights. The Jacobian is exact: an edge contact's
    wrench ``(n, r x n)`` turns with the object only through ``r``
    (``d(r x n)/dtheta = -r . n``), a tip contact's through its normal (``dn/dtheta = k x
    n``, ``d(r x n)/d(x, y) = (-n_y, n_x)``, ``d(r x n)/dtheta = r . n``).
    """
    m = keys.shape[0]
    rows = np.array([1.0, 1.0, 1.0 / rho])  # force, force, moment / rho
    q = q0.copy()
    lam = np.zeros(m)
    # the iterations' arrays, made once
    world = np.empty_like(points)
    contact = np.empty((m, 7))
    P, N, F = contact[:, 0:2], contact[:, 2:4], contact[:, 4]
    V = np.empty((m, 3))
    W = np.empty((3, m))  # wrench columns
    eq = np.empty(3)
    dM = np.empty((3, 3))
    J = np.empty((m + 3, 3 + m))
    rhs = np.empty(m + 3)
    LU = np.empty((m + 3, m + 3))
    perm = np.empty(m + 3, dtype=np.int64)
    dz = np.empty(m + 3)
    world_points_into(points, body, n_vertices, half, q, h, world)  # the hand's rows stay
    for it in range(ITERATIONS):
        if it > 0:
            object_points_into(points, n_object, n_vertices, q, world)
        contact_rows_into(world, n_object, n_vertices, keys, contact)
        constraint_matrix_into(P, N, q, V)
        W[:] = V.T
        if it == 0:
            lam, ok = independent_forces(W, g)
            if not ok:
                lam = dense.lstsq(W, g, -1.0)[0]
        for j in range(3):
            acc = 0.0
            for i in range(m):
                acc += W[j, i] * lam[i]
            eq[j] = (acc - g[j]) * rows[j]
        solved = True  # every gap and equilibrium residual within bounds (NaN is not)
        for i in range(m):
            solved = solved and abs(F[i]) <= newton_tol
        for j in range(3):
            solved = solved and abs(eq[j]) <= 1e-12
        if solved:
            return q, True
        # dM[j, k]: derivative of the equilibrium rows (j) by the pose (k), sum_i lam_i dw_i
        dM[:] = 0.0
        for i in range(m):
            rn = (P[i, 0] - q[0]) * N[i, 0] + (P[i, 1] - q[1]) * N[i, 1]
            if keys[i, 1] == TIP:
                dM[2, 0] += lam[i] * -N[i, 1]
                dM[2, 1] += lam[i] * N[i, 0]
                dM[0, 2] += lam[i] * -N[i, 1]
                dM[1, 2] += lam[i] * N[i, 0]
                dM[2, 2] += lam[i] * rn
            else:
                dM[2, 2] += lam[i] * -rn
        J[:] = 0.0
        for i in range(m):
            for k in range(3):
                J[i, k] = V[i, k] * scale[k]
            rhs[i] = -F[i]
        for j in range(3):
            for k in range(3):
                J[m + j, k] = dM[j, k] * scale[k] * rows[j]
            for i in range(m):
                J[m + j, 3 + i] = W[j, i] * rows[j]
            rhs[m + j] = -eq[j]
        LU[:] = J
        dense.lu_in_place(LU, perm)
        if not dense.lu_solve(LU, perm, rhs, dz):
            return q, False
        if largest_step(dz) > size:
            return q, False
        for k in range(3):
            q[k] = q[k] + dz[k] * scale[k]
        for i in range(m):
            lam[i] = lam[i] + dz[3 + i]
    return q, False
