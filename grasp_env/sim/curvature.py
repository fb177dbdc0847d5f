"""Descents blocked at second order: the object wedged by the curvature of its contacts.

Contacts dependent to tolerance (:mod:`grasp_env.sim.dependence`) are free to first order
along their dependence, and a non-negative self-stress ``mu`` of their rows (``mu . V = 0``:
two fingertips whose lines of action coincide, three contacts whose normals meet in a point)
keeps every admissible motion ``d`` tight on them. Along ``d`` their gaps then change at
second order only, by ``kappa_i(d) / 2`` per squared displacement; the sum weighted by ``mu``
does not depend on the second-order correction of the path (``mu . V a = 0``). Where it is
negative, by more than the tolerance resolves over the object's size, no correction keeps
every gap open (Farkas), and ``d`` is no way down. An object whose every first-order
descent is so blocked is wedged: held where it is (docs/simulator.md, *Wedged*).

The same curvature decides whether an equilibrium on one or two contacts is a rest at all
(:func:`unstable`): weighted by the forces instead of a self-stress, it is the potential
energy's second derivative along the poses that keep the contacts closed.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.dependence import dependences, project
from grasp_env.sim.placement import TIP, contact_rows
from grasp_env.sim.pose import constraint_matrix
from grasp_env.solvers import dense


@njit(cache=CACHE)
def gap_hessians(P: np.ndarray, N: np.ndarray, kinds: np.ndarray, com, size: float):
    """Second derivatives (m, 3, 3) of the contacts' gaps along a straight line in the pose,
    in displacements ``d = (v_x, v_y, size omega)`` and times ``size`` (unit-free): an edge
    contact (object vertex at ``r`` from the centre of mass on a fixed line of inward normal
    ``n``) curves by ``-(n . r) omega^2``; a tip contact (a fixed hand point on an object edge
    turning with the object) by ``2 omega (J n) . v + (n . r) omega^2``, ``J`` the quarter
    turn."""
    m = P.shape[0]
    H = np.zeros((m, 3, 3))
    for i in range(m):
        nr = N[i, 0] * (P[i, 0] - com[0]) + N[i, 1] * (P[i, 1] - com[1])
        if kinds[i] == TIP:
            H[i, 0, 2] = H[i, 2, 0] = -N[i, 1]
            H[i, 1, 2] = H[i, 2, 1] = N[i, 0]
            H[i, 2, 2] = nr / size
        else:
            H[i, 2, 2] = -nr / size
    return H


@njit(cache=CACHE)
def scaled_rows(model, world: np.ndarray, com: np.ndarray, keys: np.ndarray):
    """The contacts ``keys``' points ``P``, normals ``N`` and rows ``V`` (moments over the
    object's size), the rows ``Vs`` with those dependent to tolerance made exactly dependent,
    their dependence ``members`` and ``eta = tol / size``: what both second-order tests read."""
    P, N, _, _, _ = contact_rows(world, model.n_object, model.n_vertices, keys)
    V = constraint_matrix(P, N, com)
    for i in range(V.shape[0]):
        V[i, 2] /= model.size
    eta = model.tol / model.size
    directions, members = dependences(V, eta)
    Vs = project(V, directions, members)
    return P, N, V, Vs, members, eta


@njit(cache=CACHE)
def unstable(model, world: np.ndarray, com: np.ndarray, keys: np.ndarray) -> bool:
    """Whether the object, in equilibrium on the contacts ``keys``, sits at no minimum of
    its potential energy along the poses that keep them closed: some unit displacement
    ``u`` free of their rows has ``lam . kappa(u) > 2 eta``, ``lam`` the forces (summing to
    1) and ``kappa`` as in :func:`wedged`.

    Along such a path the gaps' second-order change ``kappa(u)`` is taken up by a correction
    ``c`` with ``V c = -kappa(u)``, and the potential changes by ``g . c = lam . V c =
    -lam . kappa(u)``: it falls both ways, by more than the tolerance resolves over the
    object's size (a potential maximum or saddle: an object next to it moves away). A
    curvature the tolerance does not resolve counts as flat, as in :func:`wedged`."""
    P, N, V, Vs, _, eta = scaled_rows(model, world, com, keys)
    lam, _ = dense.nnls(Vs.T.copy(), np.array([0.0, 1.0, 0.0]))
    total = lam.sum()
    if total <= 0.0:
        return False
    _, sv, Z = dense.svd(Vs)
    rank = 0
    for j in range(3):
        if sv[j] > eta * sv[0]:
            rank += 1
    B = Z[:, rank:].copy()  # the directions free of the rows: one or two (rank >= 1)
    H = gap_hessians(P, N, keys[:, 1], com, model.size)
    Hm = np.zeros((3, 3))
    for i in range(V.shape[0]):
        Hm += (lam[i] / total) * H[i]
    F = dense.matmul(dense.matmul(B.T.copy(), Hm), B)
    if F.shape[0] == 1:
        top = F[0, 0]
    else:  # the larger eigenvalue of the symmetric 2 x 2 form
        top = 0.5 * (F[0, 0] + F[1, 1]) + math.hypot(0.5 * (F[0, 0] - F[1, 1]), F[0, 1])
    return top > 2.0 * eta


@njit(cache=CACHE)
def self_stresses(Vs: np.ndarray, members: np.ndarray, eta: float) -> np.ndarray:
    """Minimal non-negative self-stresses (rows of the result, summing to 1) of ``Vs``'s
    rows (free directions taken out) among pairs and triples of one dependence
    (``members``): the only ones a first-order descent can meet (one over three independent
    rows would leave no motion at all)."""
    m = Vs.shape[0]
    out = np.zeros((0, m))
    for g in range(members.shape[0]):
        rows = np.flatnonzero(members[g])
        k = rows.shape[0]
        for a in range(k):
            for b in range(a + 1, k):
                out = _add(Vs, np.array([rows[a], rows[b]]), eta, out)
                for c in range(b + 1, k):
                    out = _add(Vs, np.array([rows[a], rows[b], rows[c]]), eta, out)
    return out


@njit(cache=CACHE)
def _add(Vs: np.ndarray, sub: np.ndarray, eta: float, out: np.ndarray) -> np.ndarray:
    """``out`` with the self-stress of rows ``sub`` added, if they have a minimal
    non-negative one not yet in ``out``."""
    k = sub.shape[0]
    A = np.empty((3, k))
    for j in range(k):
        A[:, j] = Vs[sub[j]]
    _, sv, Z = dense.svd(A)
    if sv[k - 1] > eta * sv[0] or (k == 3 and sv[1] <= eta * sv[0]):
        return out  # independent, or a dependent pair inside the triple
    mu = Z[:, k - 1].copy()
    if mu.sum() < 0.0:
        mu = -mu
    if mu.min() <= eta * mu.max():
        return out  # not non-negative
    row = np.zeros(Vs.shape[0])
    row[sub] = mu / mu.sum()
    for i in range(out.shape[0]):
        if np.all(out[i] == row):
            return out
    new = np.empty((out.shape[0] + 1, Vs.shape[0]))
    new[:-1] = out
    new[-1] = row
    return new


@njit(cache=CACHE)
def wedged(model, world: np.ndarray, com: np.ndarray, keys: np.ndarray, eps: float) -> bool:
    """Whether every first-order descent of the object on the contacts ``keys`` steeper than
    ``eps`` (a unit displacement ``d`` with ``V d >= 0`` and ``-d_y > eps``) is blocked at
    second order: some self-stress ``mu`` (:func:`self_stresses`) has ``mu . kappa(d) < -2
    eta`` (``eta = tol / size``: over the object's size the weighted gaps would close by
    more than the tolerance).

    ``d`` lies in the null space of the self-stresses' rows: a ray, or a plane in which the
    descents form an arc of ``d = (cos t, sin t)``. There each ``mu``'s term is ``alpha +
    beta cos 2t + gamma sin 2t``, so the worst ``d`` (largest least term) is an end of the
    arc, a stationary point of one term or a point where two are equal."""
    P, N, V, Vs, members, eta = scaled_rows(model, world, com, keys)
    stresses = self_stresses(Vs, members, eta)
    if stresses.shape[0] == 0:
        return False
    in_s = np.zeros(V.shape[0], dtype=np.bool_)
    for j in range(stresses.shape[0]):
        in_s |= stresses[j] > 0.0
    _, sv, Z = dense.svd(Vs[in_s].copy())
    rank = 0
    for j in range(3):
        if sv[j] > eta * sv[0]:
            rank += 1
    if rank == 3:
        return True  # no motion at all
    B = Z[:, rank:].copy()  # the null space of the self-stresses' rows, (3, k)
    H = gap_hessians(P, N, keys[:, 1], com, model.size)
    k = B.shape[1]
    forms = np.zeros((stresses.shape[0], k, k))
    for j in range(stresses.shape[0]):
        Hm = np.zeros((3, 3))
        for i in range(V.shape[0]):
            Hm += stresses[j, i] * H[i]
        forms[j] = dense.matmul(dense.matmul(B.T.copy(), Hm), B)
        for a in range(k):
            forms[j, a, a] += 2.0 * eta
    others = dense.matmul(Vs[~in_s].copy(), B) if (~in_s).any() else np.zeros((0, k))
    down = -B[1].copy()
    if k == 1:
        for sign in (1.0, -1.0):
            if sign * down[0] > eps and np.all(sign * others[:, 0] >= 0.0):
                if _least(forms, np.array([sign])) >= 0.0:
                    return False
        return True
    angles = _candidates(forms, others, down, eps, eta)
    for t in angles:
        u = np.array([math.cos(t), math.sin(t)])
        if dense.dot(u, down) < eps - 1e-12:
            continue
        if others.shape[0] > 0 and dense.matvec(others, u).min() < -1e-12:
            continue
        if _least(forms, u) >= 0.0:
            return False
    return True


@njit(cache=CACHE)
def _least(forms: np.ndarray, u: np.ndarray) -> float:
    """The least of the quadratic forms at ``u``."""
    least = np.inf
    for j in range(forms.shape[0]):
        least = min(least, dense.dot(u, dense.matvec(forms[j], u)))
    return least


@njit(cache=CACHE)
def _candidates(forms, others, down, eps: float, eta: float) -> list:
    """Angles where the largest least term on the arc of descents may lie: the arc's ends
    (a row or the descent bound turning active), the terms' stationary points and the
    points where two terms are equal; each also half and a whole turn on."""
    out = []
    for i in range(others.shape[0]):
        if math.hypot(others[i, 0], others[i, 1]) > eta:
            base = math.atan2(others[i, 1], others[i, 0])
            out.append(base + 0.5 * math.pi)
            out.append(base - 0.5 * math.pi)
    rho = math.hypot(down[0], down[1])
    if rho > eps:
        base = math.atan2(down[1], down[0])
        out.append(base + math.acos(eps / rho))
        out.append(base - math.acos(eps / rho))
    for j in range(forms.shape[0]):
        F = forms[j]
        out.append(0.5 * math.atan2(F[0, 1], 0.5 * (F[0, 0] - F[1, 1])))
        for l in range(j + 1, forms.shape[0]):
            D = F - forms[l]
            alpha, beta, gamma = 0.5 * (D[0, 0] + D[1, 1]), 0.5 * (D[0, 0] - D[1, 1]), D[0, 1]
            R = math.hypot(beta, gamma)
            if R > abs(alpha):
                base = math.atan2(gamma, beta)
                out.append(0.5 * (base + math.acos(-alpha / R)))
                out.append(0.5 * (base - math.acos(-alpha / R)))
    full = []
    for t in out:
        for turn in range(4):
            full.append(t + 0.5 * math.pi * turn)
    return full
