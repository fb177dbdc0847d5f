"""Contacts that depend on each other to tolerance.

Contacts are only known to the contact tolerance ``tol``, and so is how they depend on each
other. Two contacts whose lines of action coincide to tolerance, or three whose lines meet in
one point (or are parallel) to tolerance, leave the object a direction in which displacing it
by its own size changes none of their gaps by more than ``tol``: faces parallel to tolerance,
a wedge whose angle is below what the tolerance resolves. Forces along such a direction would
grow without bound on the rounding of the geometry, and the sign of that rounding would
decide whether the object is squeezed out or wedged. The direction is taken as what it is to
tolerance: free. Those contacts neither resist nor push along it; the motion LP, the holding
test, the fall's descent and Newton's method all see the same rows (:func:`free_rows`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.solvers import dense

#: Most free directions one contact can take part in: a row dependent along three directions
#: would be zero, and every row holds a unit normal.
MAX_FREE = 2


@njit(cache=CACHE)
def free_rows(model, V: np.ndarray) -> np.ndarray:
    """``V_ob`` (m, 3) with the directions free to tolerance taken out of the rows they are
    free for; ``V`` itself (the same array) when there are none.

    With ``d = (v_x, v_y, size omega)`` a twist as the displacement it gives the object's
    farthest vertex, a pair of rows whose second singular value, or a triple whose third,
    is at most ``eta = tol / size`` is dependent to tolerance along its singular vector
    ``z``: moving the object by its own size along ``z`` changes neither gap by more than
    ``tol``. Each row of such a set is projected onto the complement of its sets' free
    directions, so that those contacts are exactly dependent and ``z`` is free for them;
    the other rows are kept as they are (the support under an object pinched between
    parallel faces still holds it up)."""
    m = V.shape[0]
    if m < 2:
        return V
    eta = model.tol / model.size
    Vs = V.copy()
    for i in range(m):
        Vs[i, 2] /= model.size
    dirs = np.zeros((m, MAX_FREE, 3))  # each row's free directions, orthonormal
    count = np.zeros(m, dtype=np.int64)
    found = False
    for i in range(m):
        for j in range(i + 1, m):
            a, b = Vs[i], Vs[j]
            cx = a[1] * b[2] - a[2] * b[1]
            cy = a[2] * b[0] - a[0] * b[2]
            cz = a[0] * b[1] - a[1] * b[0]
            # |a x b| = s1 s2 <= (|a| + |b|) s2: only a pair that may pass is decomposed
            bound = (_norm(a) + _norm(b)) * eta
            if math.sqrt(cx * cx + cy * cy + cz * cz) <= bound:
                found = _mark(Vs, np.array([i, j]), 1, eta, dirs, count) or found
            for k in range(j + 1, m):
                c = Vs[k]
                det = cx * c[0] + cy * c[1] + cz * c[2]
                # |det| = s1 s2 s3 <= |V_S|_F^2 s3 / 2
                frob = _norm(a) ** 2 + _norm(b) ** 2 + _norm(c) ** 2
                if abs(det) <= 0.5 * frob * eta:
                    found = _mark(Vs, np.array([i, j, k]), 2, eta, dirs, count) or found
    if not found:
        return V
    for i in range(m):
        for t in range(count[i]):
            along = Vs[i, 0] * dirs[i, t, 0] + Vs[i, 1] * dirs[i, t, 1] + Vs[i, 2] * dirs[i, t, 2]
            for j in range(3):
                Vs[i, j] -= along * dirs[i, t, j]
        Vs[i, 2] *= model.size
    return Vs


@njit(cache=CACHE)
def _norm(a: np.ndarray) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit(cache=CACHE)
def _mark(Vs, rows, rank: int, eta: float, dirs, count) -> bool:
    """Whether the rows ``rows`` of ``Vs`` are dependent to tolerance (their singular value
    number ``rank + 1`` at most ``eta``); if so, its singular vector is added to each row's
    free directions (orthonormalised against those it has; one already in their span is
    not added again)."""
    sub = np.empty((rows.shape[0], 3))
    for r in range(rows.shape[0]):
        sub[r] = Vs[rows[r]]
    _, sv, Z = dense.svd(sub)
    if sv[rank] > eta:
        return False
    for r in range(rows.shape[0]):
        i = rows[r]
        z = Z[:, rank].copy()
        for t in range(count[i]):
            along = z[0] * dirs[i, t, 0] + z[1] * dirs[i, t, 1] + z[2] * dirs[i, t, 2]
            z -= along * dirs[i, t]
        size = _norm(z)
        if size <= 1e-6 or count[i] == MAX_FREE:
            continue  # already free along it
        dirs[i, count[i]] = z / size
        count[i] += 1
    return True
