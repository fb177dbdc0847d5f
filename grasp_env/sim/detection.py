"""Contact detection: the vertex-edge pairs of a placement that touch, as contact keys.

The placement is the ``world`` array of :func:`grasp_env.sim.placement.world_points`
(object vertices, hand vertices, then their outward edge normals). A contact key is a row
``(body, kind, object_feature, hand_feature)``: kind 0 (edge) puts object vertex
``object_feature`` on edge ``hand_feature`` of hand body ``body`` (the support's line y = 0
has the one edge 0), kind 1 (tip) puts vertex ``hand_feature`` of hand body ``body`` on
object edge ``object_feature`` (from vertex k to k + 1).

A pair is a contact when all of these hold:

* the body is near the object (:func:`grasp_env.sim.clearance.near_bodies`, margin
  ``10 tol``);
* the vertex lies within ``tol`` of the edge's line (``|gap| <= tol``);
* its projection falls on the edge, or past an end with the vertex within ``tol`` of that
  end (Euclidean distance, as for "touching" anywhere else): events are located to within
  the tolerance, so a vertex that has just reached an edge's end (a vertex-vertex touch)
  may project a hair outside it; on the support every vertex counts;
* the vertex's two adjacent edges leave on its own side of the edge's line (locally
  valid): for convex bodies that line then separates them near the contact, so its
  half-plane is a valid frictionless constraint. At a vertex-vertex touch this rejects the
  candidate edges that would cut through the other body. Nearly flush edges (an edge along
  an edge) pass: a neighbour may dip behind the line by ``max(4 tol, 1e-7 |d|)``, an angle
  of 1e-7 rad and at least a few tolerances (an edge that has just come to lie along
  another, located to within ``tol`` at both of its ends). A vertex inside the edge it
  touches (more than ``2 tol`` from either end) passes too when its neighbours reach at
  most ``4 tol`` into the other body: an edge along an edge at an angle just over that
  slack, the two crossing within their overlap, has both end contacts within the
  tolerance;
* it is not in ``exclude``;
* no contact of the same body kept before it has the same point (to within ``2 tol`` in
  each coordinate) and normal (cosine above ``1 - 1e-9``): a vertex-vertex touch along
  flush edges is seen both as an edge and as a tip contact, and the one kept is the first.
  Two bodies touching the object at one point (crossed fingers along one face) are two
  contacts.

Pairs are visited edge contacts first (the support, then hand bodies 1-3, each by object
vertex then hand edge), then tip contacts (hand bodies 1-3, each by hand vertex then object
edge), so that of coincident duplicates the edge-kind one is kept. An edge lying along an
edge yields its two end contacts.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.clearance import near_bodies
from grasp_env.sim.placement import EDGE, SUPPORT, TIP

#: Cosine above which two contact normals count as the same.
SAME_NORMAL = 1.0 - 1e-9
#: Angle (rad) by which a locally valid vertex's neighbour may dip behind the edge's line.
FLUSH_ANGLE = 1e-7


@njit(cache=CACHE)
def _locally_valid(
    world: np.ndarray, first: int, count: int, v: int, nx: float, ny: float, tol: float
) -> bool:
    """True when both neighbours of vertex ``first + v`` of the polygon in rows ``first ..
    first + count - 1`` lie on the side of the line through it that the normal ``(nx, ny)``
    points to (the vertex's own side of the edge it touches), up to the flush slack."""
    px, py = world[first + v, 0], world[first + v, 1]
    for nbr in (first + (v - 1) % count, first + (v + 1) % count):
        dx, dy = world[nbr, 0] - px, world[nbr, 1] - py
        if nx * dx + ny * dy < -max(4.0 * tol, FLUSH_ANGLE * math.hypot(dx, dy)):
            return False
    return True


@njit(cache=CACHE)
def _least(c: np.ndarray, e: np.ndarray, u: float) -> float:
    """The least of the linear functions ``c + u e`` at ``u``."""
    out = np.inf
    for k in range(c.shape[0]):
        out = min(out, c[k] + u * e[k])
    return out


@njit(cache=CACHE)
def _cut_depth(world: np.ndarray, n_vertices: int, p: int, q: int, first: int, count: int) -> float:
    """How deep the segment from point row ``p`` to ``q`` reaches into the convex polygon in
    rows ``first .. first + count - 1`` (outward edge normals ``n_vertices`` rows further
    on): the largest, along the segment, of its least distance inside the edges' lines
    (<= 0 outside). That least distance is a minimum of linear functions of the position
    along the segment, so its largest value lies at an end or where two of them cross."""
    px, py = world[p, 0], world[p, 1]
    dx, dy = world[q, 0] - px, world[q, 1] - py
    c = np.empty(count)  # inward distance of the segment at its start, per edge line
    e = np.empty(count)  # and its rate along the segment
    for i in range(count):
        a, nrm = first + i, n_vertices + first + i
        c[i] = -((px - world[a, 0]) * world[nrm, 0] + (py - world[a, 1]) * world[nrm, 1])
        e[i] = -(dx * world[nrm, 0] + dy * world[nrm, 1])
    best = max(_least(c, e, 0.0), _least(c, e, 1.0))  # the segment's ends
    for i in range(count):
        for j in range(i + 1, count):
            if e[i] != e[j]:
                u = (c[j] - c[i]) / (e[i] - e[j])
                if 0.0 < u < 1.0:
                    best = max(best, _least(c, e, u))
    return best


@njit(cache=CACHE)
def _along_within_tolerance(
    world: np.ndarray, n_vertices: int, first: int, count: int, v: int, a: int, b: int,
    other: int, other_count: int, tol: float,
) -> bool:  # fmt: skip
    """Whether vertex ``first + v`` of its polygon, inside the edge from point row ``a`` to
    ``b`` of the other polygon (rows ``other .. other + other_count - 1``) by more than two
    tolerances from either end, has neighbours that reach at most four tolerances into that
    polygon: an edge lying along an edge at an angle just over the flush slack, where the
    two cross within their overlap, both end contacts within the tolerance. At a
    vertex-vertex touch the angle rule (:func:`_locally_valid`) alone decides."""
    ex, ey = world[b, 0] - world[a, 0], world[b, 1] - world[a, 1]
    L2 = ex * ex + ey * ey
    t = ((world[first + v, 0] - world[a, 0]) * ex + (world[first + v, 1] - world[a, 1]) * ey) / L2
    if min(t, 1.0 - t) * math.sqrt(L2) <= 2.0 * tol:
        return False
    for nbr in (first + (v - 1) % count, first + (v + 1) % count):
        if _cut_depth(world, n_vertices, first + v, nbr, other, other_count) > 4.0 * tol:
            return False
    return True


@njit(cache=CACHE)
def _excluded(exclude: np.ndarray, body: int, kind: int, k: int, j: int) -> bool:
    """Whether the key ``(body, kind, k, j)`` is a row of ``exclude``."""
    for i in range(exclude.shape[0]):
        if (
            exclude[i, 0] == body
            and exclude[i, 1] == kind
            and exclude[i, 2] == k
            and exclude[i, 3] == j
        ):
            return True
    return False


@njit(cache=CACHE)
def _on_edge(
    world: np.ndarray, v: int, a: int, b: int, nrm: int, slack: float
) -> tuple[bool, float]:
    """Whether point row ``v`` projects onto the edge from point row ``a`` to ``b``, or lies
    past one of its ends within ``slack`` of that end, and its gap to the edge's line
    (normal row ``nrm``)."""
    rx, ry = world[v, 0] - world[a, 0], world[v, 1] - world[a, 1]
    dx, dy = world[b, 0] - world[a, 0], world[b, 1] - world[a, 1]
    gap = rx * world[nrm, 0] + ry * world[nrm, 1]
    L = math.sqrt(dx * dx + dy * dy)
    t = (rx * dx + ry * dy) / (L * L)
    over = max(-t, t - 1.0, 0.0) * L  # how far past an end, along the edge
    return over == 0.0 or over * over + gap * gap <= slack * slack, gap


@njit(cache=CACHE)
def _keep(
    out: np.ndarray, seen: np.ndarray, count: int, key: tuple, p: tuple, n: tuple, tol: float
) -> int:
    """Append ``key`` with point ``p`` and normal ``n`` unless a kept contact of the same body
    has the same point and normal; the new count."""
    for i in range(count):
        if (
            out[i, 0] == key[0]
            and abs(p[0] - seen[i, 0]) <= 2.0 * tol
            and abs(p[1] - seen[i, 1]) <= 2.0 * tol
            and n[0] * seen[i, 2] + n[1] * seen[i, 3] > SAME_NORMAL
        ):
            return count
    out[count, 0], out[count, 1], out[count, 2], out[count, 3] = key
    seen[count, 0], seen[count, 1], seen[count, 2], seen[count, 3] = p[0], p[1], n[0], n[1]
    return count + 1


@njit(cache=CACHE)
def detect(
    world: np.ndarray, n_object: int, n_vertices: int, tol: float, exclude: np.ndarray
) -> np.ndarray:
    """Contact keys (m, 4) at the placement ``world``: the vertex-edge pairs within ``tol``
    that pass the rules of the module docstring, skipping the rows of ``exclude`` (e, 4)."""
    bodies = near_bodies(world, n_object, 10.0 * tol)
    cap = n_object * (1 + 2 * 4 * 3)  # support, then both kinds with 3 four-sided bodies
    out = np.empty((cap, 4), dtype=np.int64)
    seen = np.empty((cap, 4))  # point and normal of each kept contact
    count = 0
    for body in bodies:  # object vertex k on edge j of the body
        if body == SUPPORT:
            for k in range(n_object):
                y = world[k, 1]
                if (
                    abs(y) <= tol
                    and not _excluded(exclude, SUPPORT, EDGE, k, 0)
                    and _locally_valid(world, 0, n_object, k, 0.0, 1.0, tol)
                ):
                    key = (SUPPORT, EDGE, k, 0)
                    count = _keep(out, seen, count, key, (world[k, 0], y), (0.0, 1.0), tol)
            continue
        first = n_object + 4 * (body - 1)
        for k in range(n_object):
            for j in range(4):
                a, nrm = first + j, n_vertices + first + j
                on, gap = _on_edge(world, k, a, first + (j + 1) % 4, nrm, tol)
                if not (abs(gap) <= tol and on) or _excluded(exclude, body, EDGE, k, j):
                    continue
                nx, ny = world[nrm, 0], world[nrm, 1]
                if _locally_valid(world, 0, n_object, k, nx, ny, tol) or _along_within_tolerance(
                    world, n_vertices, 0, n_object, k, a, first + (j + 1) % 4, first, 4, tol
                ):
                    key = (body, EDGE, k, j)
                    count = _keep(out, seen, count, key, (world[k, 0], world[k, 1]), (nx, ny), tol)
    for body in bodies:  # vertex j of the body on object edge k
        if body == SUPPORT:
            continue
        first = n_object + 4 * (body - 1)
        for j in range(4):
            for k in range(n_object):
                on, gap = _on_edge(world, first + j, k, (k + 1) % n_object, n_vertices + k, tol)
                if not (abs(gap) <= tol and on) or _excluded(exclude, body, TIP, k, j):
                    continue
                nx, ny = world[n_vertices + k, 0], world[n_vertices + k, 1]
                if _locally_valid(world, first, 4, j, nx, ny, tol) or _along_within_tolerance(
                    world, n_vertices, first, 4, j, k, (k + 1) % n_object, 0, n_object, tol
                ):
                    p = (world[first + j, 0], world[first + j, 1])
                    count = _keep(out, seen, count, (body, TIP, k, j), p, (-nx, -ny), tol)
    return out[:count].copy()
