"""Clearance between the object and the other bodies at a placement: the smallest
vertex-in-body gap, and the separating-axis overlap of convex polygons.

The placement is the ``world`` array of :func:`grasp_env.sim.placement.world_points`
(object vertices, hand vertices, then their edge normals). Bodies are numbered 0 support,
1 palm, 2 finger 1, 3 finger 2; a contact key is ``(body, kind, object_feature,
hand_feature)`` with kind 0 an object vertex on a body's edge and 1 a hand vertex on an
object edge.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.placement import EDGE, SUPPORT, TIP


@njit(cache=CACHE)
def _edge_gap(world, n_vertices, v, a, nrm) -> float:
    """Gap of point row ``v`` to the line through point row ``a`` with normal row ``nrm``."""
    return (world[v, 0] - world[a, 0]) * world[n_vertices + nrm, 0] + (
        world[v, 1] - world[a, 1]
    ) * world[n_vertices + nrm, 1]


@njit(cache=CACHE)
def near_bodies(world: np.ndarray, n_object: int, margin: float) -> np.ndarray:
    """Bodies whose bounding box comes within ``margin`` of the object's: the support when
    the object's lowest point is within ``margin`` of y = 0, hand bodies (1-3) by box."""
    lo_x = hi_x = world[0, 0]
    lo_y = hi_y = world[0, 1]
    for k in range(1, n_object):
        lo_x, hi_x = min(lo_x, world[k, 0]), max(hi_x, world[k, 0])
        lo_y, hi_y = min(lo_y, world[k, 1]), max(hi_y, world[k, 1])
    lo_x, lo_y, hi_x, hi_y = lo_x - margin, lo_y - margin, hi_x + margin, hi_y + margin
    out = np.empty(4, dtype=np.int64)
    count = 0
    if lo_y <= 0.0:
        out[count] = SUPPORT
        count += 1
    for b in range(1, 4):
        first = n_object + 4 * (b - 1)
        plo_x = phi_x = world[first, 0]
        plo_y = phi_y = world[first, 1]
        for j in range(first + 1, first + 4):
            plo_x, phi_x = min(plo_x, world[j, 0]), max(phi_x, world[j, 0])
            plo_y, phi_y = min(plo_y, world[j, 1]), max(phi_y, world[j, 1])
        if plo_x <= hi_x and plo_y <= hi_y and phi_x >= lo_x and phi_y >= lo_y:
            out[count] = b
            count += 1
    return out[:count]


@njit(cache=CACHE)
def _excluded(exclude: np.ndarray, body: int, kind: int, vertex: int) -> bool:
    for i in range(exclude.shape[0]):
        if exclude[i, 0] == body and exclude[i, 1] == kind and exclude[i, 2] == vertex:
            return True
    return False


@njit(cache=CACHE)
def min_gap(
    world: np.ndarray, n_object: int, n_vertices: int, bodies: np.ndarray, exclude: np.ndarray
) -> tuple[float, np.ndarray]:
    """Smallest vertex-in-body gap over the vertices of the object and of ``bodies`` not
    pinned by a ``(body, kind, vertex)`` row of ``exclude``, and the key of that pair
    (``key[0] = -1`` when there is none).

    A vertex's gap to a convex body is the largest of its edge gaps, exact while the vertex is
    inside, so no penetration by a vertex goes unnoticed; the key names the edge of largest
    gap, the one the vertex entered through.
    """
    worst = np.inf
    key = np.full(4, -1, dtype=np.int64)
    for b in bodies:
        if b == SUPPORT:
            for k in range(n_object):
                if world[k, 1] < worst and not _excluded(exclude, 0, EDGE, k):
                    worst = world[k, 1]
                    key[0], key[1], key[2], key[3] = 0, EDGE, k, 0
            continue
        first = n_object + 4 * (b - 1)
        for k in range(n_object):  # object vertex k in hand body b
            inside, edge = -np.inf, 0
            for j in range(4):
                gap = _edge_gap(world, n_vertices, k, first + j, first + j)
                if gap > inside:
                    inside, edge = gap, j
            if inside < worst and not _excluded(exclude, b, EDGE, k):
                worst = inside
                key[0], key[1], key[2], key[3] = b, EDGE, k, edge
        for j in range(4):  # hand vertex j in the object
            inside, edge = -np.inf, 0
            for k in range(n_object):
                gap = _edge_gap(world, n_vertices, first + j, k, k)
                if gap > inside:
                    inside, edge = gap, k
            if inside < worst and not _excluded(exclude, b, TIP, j):
                worst = inside
                key[0], key[1], key[2], key[3] = b, TIP, edge, j
    return worst, key


@njit(cache=CACHE)
def separation(world: np.ndarray, n_object: int, n_vertices: int, b: int) -> float:
    """Separating-axis distance of the object from hand body ``b``: the largest gap between
    them along an edge normal of either polygon, a lower bound on their distance (minus the
    overlap depth when they overlap)."""
    first = n_object + 4 * (b - 1)
    best = -np.inf
    for j in range(4):  # hand edge j: how far the object reaches behind it
        reach = np.inf
        for k in range(n_object):
            reach = min(reach, _edge_gap(world, n_vertices, k, first + j, first + j))
        best = max(best, reach)
    for k in range(n_object):  # object edge k
        reach = np.inf
        for j in range(4):
            reach = min(reach, _edge_gap(world, n_vertices, first + j, k, k))
        best = max(best, reach)
    return best


@njit(cache=CACHE)
def max_overlap(
    world: np.ndarray, n_object: int, n_vertices: int, bodies: np.ndarray
) -> tuple[float, int]:
    """Deepest overlap of the object with a hand body in ``bodies`` (minus its
    :func:`separation`; <= 0 when apart) and that body, or ``(-inf, -1)`` for none. Catches
    convex polygons whose edges cross with no vertex of either inside the other."""
    depth, body = -np.inf, -1
    for b in bodies:
        if b == SUPPORT:
            continue
        d = -separation(world, n_object, n_vertices, b)
        if d > depth:
            depth, body = d, b
    return depth, body
