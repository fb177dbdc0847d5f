"""Sets of contacts as int arrays: membership, editing, and the choices a vertex-vertex
touch leaves.

A contact is a row ``(body, kind, object_feature, hand_feature)`` (see
:mod:`grasp_env.sim.placement`); a set of contacts is an array of such rows (m, 4), kept in
order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.placement import EDGE, SUPPORT, contact_rows, place

NONE = np.full(4, -1, dtype=np.int64)


@njit(cache=CACHE)
def empty() -> np.ndarray:
    """The empty set of contacts."""
    return np.zeros((0, 4), dtype=np.int64)


@njit(cache=CACHE)
def same(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the contact rows ``a`` and ``b`` are the same contact."""
    return a[0] == b[0] and a[1] == b[1] and a[2] == b[2] and a[3] == b[3]


@njit(cache=CACHE)
def index(keys: np.ndarray, key: np.ndarray) -> int:
    """Position of ``key`` in ``keys``, or -1."""
    for i in range(keys.shape[0]):
        if same(keys[i], key):
            return i
    return -1


@njit(cache=CACHE)
def equal(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the two sets hold the same contacts in the same order."""
    if a.shape[0] != b.shape[0]:
        return False
    for i in range(a.shape[0]):
        if not same(a[i], b[i]):
            return False
    return True


@njit(cache=CACHE)
def with_key(keys: np.ndarray, key: np.ndarray) -> np.ndarray:
    """``keys`` with ``key`` appended."""
    out = np.empty((keys.shape[0] + 1, 4), dtype=np.int64)
    out[:-1] = keys
    out[-1] = key
    return out


@njit(cache=CACHE)
def without(keys: np.ndarray, key: np.ndarray) -> np.ndarray:
    """``keys`` without ``key``."""
    keep = np.ones(keys.shape[0], dtype=np.bool_)
    for i in range(keys.shape[0]):
        keep[i] = not same(keys[i], key)
    return keys[keep].copy()


@njit(cache=CACHE)
def all_on_support(keys: np.ndarray) -> bool:
    """Whether the set is non-empty and every contact is on the support."""
    if keys.shape[0] == 0:
        return False
    for i in range(keys.shape[0]):
        if keys[i, 0] != SUPPORT:
            return False
    return True


@njit(cache=CACHE)
def choices(model, world: np.ndarray, keys: np.ndarray) -> list:
    """Contact sets to try: one candidate per vertex-vertex touch.

    Contacts of one hand body at one point (to ``4 tol``) are the candidate edges of a
    vertex-vertex touch, whose admissible half-planes form a union: each combination of one
    candidate per touch is a choice (the single contacts first, then the touches' picks in
    order). Without touches the only choice is ``keys`` itself.
    """
    m = keys.shape[0]
    P = contact_rows(world, model.n_object, model.n_vertices, keys)[0]
    group = np.empty(m, dtype=np.int64)  # the group of each contact (its first member)
    size = np.zeros(m, dtype=np.int64)
    for i in range(m):
        group[i] = i
        for j in range(i):
            if (
                group[j] == j
                and keys[j, 0] == keys[i, 0]
                and keys[j, 0] != SUPPORT
                and max(abs(P[j, 0] - P[i, 0]), abs(P[j, 1] - P[i, 1])) <= 4.0 * model.tol
            ):
                group[i] = j
                break
        size[group[i]] += 1
    out = [keys]
    multi = np.array([i for i in range(m) if size[i] > 1], dtype=np.int64)
    if multi.shape[0] == 0:
        return out
    out.pop()
    single = np.array([i for i in range(m) if size[group[i]] == 1], dtype=np.int64)
    members = [np.array([i for i in range(m) if group[i] == g], dtype=np.int64) for g in multi]
    pick = np.zeros(multi.shape[0], dtype=np.int64)  # mixed-radix counter, last digit fastest
    while True:
        choice = np.empty((single.shape[0] + multi.shape[0], 4), dtype=np.int64)
        for t in range(single.shape[0]):
            choice[t] = keys[single[t]]
        for t in range(multi.shape[0]):
            choice[single.shape[0] + t] = keys[members[t][pick[t]]]
        out.append(choice)
        d = multi.shape[0] - 1
        while d >= 0 and pick[d] == members[d].shape[0] - 1:
            pick[d] = 0
            d -= 1
        if d < 0:
            return out
        pick[d] += 1


@njit(cache=CACHE)
def supporting_pairs(model, q: np.ndarray, h: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """``keys`` with the contacts of each straight edge that holds three or more object
    vertices reduced to its outermost two at ``(q, h)`` (the pair farthest apart, first
    found); ``keys`` itself when there are none (then nothing is placed)."""
    m = keys.shape[0]
    P = np.empty((0, 2))  # contact points, placed only when an edge holds three or more
    keep = np.ones(m, dtype=np.bool_)
    reduced = False
    for i in range(m):
        if keys[i, 1] != EDGE:
            continue
        first = True  # i is the first contact on its edge
        for j in range(i):
            if keys[j, 1] == EDGE and keys[j, 0] == keys[i, 0] and keys[j, 3] == keys[i, 3]:
                first = False
        if not first:
            continue
        members = [j for j in range(i, m) if keys[j, 1] == EDGE and keys[j, 0] == keys[i, 0]
                   and keys[j, 3] == keys[i, 3]]  # fmt: skip
        if len(members) < 3:
            continue
        if P.shape[0] == 0:
            P = contact_rows(place(model, q, h), model.n_object, model.n_vertices, keys)[0]
        best, a, b = -1.0, -1, -1
        for x in range(len(members)):
            for y in range(x + 1, len(members)):
                u, w = members[x], members[y]
                d = abs(P[u, 0] - P[w, 0]) + abs(P[u, 1] - P[w, 1])
                if d > best:
                    best, a, b = d, u, w
        for j in members:
            if j != a and j != b:
                keep[j] = False
                reduced = True
    if not reduced:
        return keys
    return keys[keep].copy()
