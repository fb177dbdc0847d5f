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
#: Free directions of dependent sets that differ by less than this angle (rad) are one: the
#: sets share a dependence (say, two faces flush at both ends), and their singular vectors
#: differ only by the rounding of its rows.
SAME_DIRECTION = 1e-6


@njit(cache=CACHE)
def free_rows(model, V: np.ndarray) -> np.ndarray:
    """``V_ob`` (m, 3) with the directions free to tolerance taken out of the rows they are
    free for; ``V`` itself (the same array) when there are none.

    With ``d = (v_x, v_y, size omega)`` a twist as the displacement it gives the object's
    farthest vertex, a pair of rows whose second singular value, or a triple whose third,
    is at most ``eta = tol / size`` is dependent to tolerance along that singular vector
    ``z``: moving the object by its own size along ``z`` changes none of their gaps by more
    than ``tol`` (:func:`dependences`). Each row of a dependence is projected onto the
    complement of its dependences' directions (:func:`project`); the other rows are kept as
    they are (the support under an object pinched between parallel faces still holds it
    up)."""
    if V.shape[0] < 2:
        return V
    Vs = V.copy()
    for i in range(V.shape[0]):
        Vs[i, 2] /= model.size
    directions, members = dependences(Vs, model.tol / model.size)
    if directions.shape[0] == 0:
        return V
    out = project(Vs, directions, members)
    for i in range(V.shape[0]):
        out[i, 2] *= model.size
    return out


@njit(cache=CACHE)
def dependences(Vs: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """The dependences to tolerance of rows ``Vs`` (twists as displacements ``d``): their
    directions (g, 3) and rows (g, m). Sets whose directions agree (to
    :data:`SAME_DIRECTION`) share one dependence: its direction is taken from all their rows
    at once (the singular vector of their union), so that every row of it is projected
    along the very same direction and the projected rows are exactly dependent, to
    rounding."""
    m = Vs.shape[0]
    groups = np.zeros((0, 3))  # a direction of each dependence
    members = np.zeros((0, m), dtype=np.bool_)  # the rows of each dependence
    for i in range(m):
        for j in range(i + 1, m):
            a, b = Vs[i], Vs[j]
            cx = a[1] * b[2] - a[2] * b[1]
            cy = a[2] * b[0] - a[0] * b[2]
            cz = a[0] * b[1] - a[1] * b[0]
            # |a x b| = s1 s2 <= (|a| + |b|) s2: only a pair that may pass is decomposed
            if math.sqrt(cx * cx + cy * cy + cz * cz) <= (_norm(a) + _norm(b)) * eta:
                groups, members = _join(Vs, np.array([i, j]), eta, groups, members)
            for k in range(j + 1, m):
                c = Vs[k]
                det = cx * c[0] + cy * c[1] + cz * c[2]
                # |det| = s1 s2 s3 <= |V_S|_F^2 s3 / 2
                if abs(det) <= 0.5 * (_norm(a) ** 2 + _norm(b) ** 2 + _norm(c) ** 2) * eta:
                    groups, members = _join(Vs, np.array([i, j, k]), eta, groups, members)
    for g in range(groups.shape[0]):
        groups[g] = _smallest(Vs[members[g]].copy())[1]  # from all the rows at once
    return groups, members


@njit(cache=CACHE)
def project(Vs: np.ndarray, directions: np.ndarray, members: np.ndarray) -> np.ndarray:
    """``Vs`` with each row of a dependence projected onto the complement of its
    dependences' directions (at most :data:`MAX_FREE`)."""
    out = Vs.copy()
    for i in range(Vs.shape[0]):
        basis = np.zeros((MAX_FREE, 3))
        count = 0
        for g in range(directions.shape[0]):
            if not members[g, i] or count == MAX_FREE:
                continue
            z = directions[g].copy()
            for t in range(count):
                z -= (z[0] * basis[t, 0] + z[1] * basis[t, 1] + z[2] * basis[t, 2]) * basis[t]
            size = _norm(z)
            if size > SAME_DIRECTION:
                basis[count] = z / size
                count += 1
        for t in range(count):
            along = out[i, 0] * basis[t, 0] + out[i, 1] * basis[t, 1] + out[i, 2] * basis[t, 2]
            for j in range(3):
                out[i, j] -= along * basis[t, j]
    return out


@njit(cache=CACHE)
def _norm(a: np.ndarray) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit(cache=CACHE)
def _smallest(sub: np.ndarray) -> tuple[float, np.ndarray]:
    """The singular value and right singular vector of ``sub``'s rows (2 or more) that tell
    its dependence: the second of a pair (whose third is always zero), else the third."""
    _, sv, Z = dense.svd(sub)
    k = min(sub.shape[0], 3) - 1
    return sv[k], Z[:, k].copy()


@njit(cache=CACHE)
def _join(Vs, rows: np.ndarray, eta: float, groups: np.ndarray, members: np.ndarray):
    """``(groups, members)`` with the set ``rows`` of ``Vs`` added where it is dependent to
    tolerance (its telling singular value at most ``eta``): to the dependence of the same
    direction, or as a new one."""
    sub = np.empty((rows.shape[0], 3))
    for r in range(rows.shape[0]):
        sub[r] = Vs[rows[r]]
    value, z = _smallest(sub)
    if value > eta:
        return groups, members
    for g in range(groups.shape[0]):
        w = groups[g]
        cx = z[1] * w[2] - z[2] * w[1]
        cy = z[2] * w[0] - z[0] * w[2]
        cz = z[0] * w[1] - z[1] * w[0]
        if math.sqrt(cx * cx + cy * cy + cz * cz) <= SAME_DIRECTION:
            for r in range(rows.shape[0]):
                members[g, rows[r]] = True
            return groups, members
    new_groups = np.empty((groups.shape[0] + 1, 3))
    new_groups[:-1] = groups
    new_groups[-1] = z
    new_members = np.zeros((members.shape[0] + 1, members.shape[1]), dtype=np.bool_)
    new_members[:-1] = members
    for r in range(rows.shape[0]):
        new_members[-1, rows[r]] = True
    return new_groups, new_members
