"""World geometry of every body, and the gaps of contacts, for an object pose and a hand.

The scene's bodies are stacked once into one array of body-frame points (see
:class:`grasp_env.mechanics.contacts.Placement`): the object's vertices, the palm's, finger 1's and
finger 2's (4 each), then the same bodies' outward edge normals; ``body`` gives each row's
body (0 object, 1 palm, 2 finger 1, 3 finger 2). One rotation per body places them all.

A contact is a row ``(body, kind, object_feature, hand_feature)`` of an int array ``keys``
(:mod:`grasp_env.mechanics.contacts` explains the two kinds); its normal points into the object and
its gap is positive when the bodies are apart.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE

SUPPORT = 0
EDGE, TIP = 0, 1


@njit(cache=CACHE)
def world_points(
    points: np.ndarray, body: np.ndarray, n_vertices: int, half: float, q: np.ndarray,
    h: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """World coordinates of the stacked body-frame ``points`` for object pose ``q`` and hand
    configuration ``h``; rows before ``n_vertices`` are points (rotated and moved), the rest
    directions (rotated only). ``half`` is half the palm width (the joints' offset)."""
    out = np.empty_like(points)
    world_points_into(points, body, n_vertices, half, q, h, out)
    return out


@njit(cache=CACHE, inline="always")
def world_points_into(
    points: np.ndarray, body: np.ndarray, n_vertices: int, half: float, q: np.ndarray,
    h, out: np.ndarray,
) -> None:  # fmt: skip
    """:func:`world_points` into ``out`` (for a loop that places the bodies at every
    iteration without allocating; ``h`` an array or a tuple)."""
    th = h[2]
    c, s = math.cos(th), math.sin(th)
    ox = (q[0], h[0], h[0] - c * half, h[0] + c * half)
    oy = (q[1], h[1], h[1] - s * half, h[1] + s * half)
    th1, th2 = th + h[3], th + h[4]
    cos_b = (math.cos(q[2]), c, math.cos(th1), math.cos(th2))
    sin_b = (math.sin(q[2]), s, math.sin(th1), math.sin(th2))
    for i in range(points.shape[0]):
        b = body[i]
        x, y = points[i, 0], points[i, 1]
        out[i, 0] = cos_b[b] * x - sin_b[b] * y
        out[i, 1] = sin_b[b] * x + cos_b[b] * y
        if i < n_vertices:
            if b == 0:
                out[i, 0] += ox[0]
                out[i, 1] += oy[0]
            elif b == 1:
                out[i, 0] += ox[1]
                out[i, 1] += oy[1]
            elif b == 2:
                out[i, 0] += ox[2]
                out[i, 1] += oy[2]
            else:
                out[i, 0] += ox[3]
                out[i, 1] += oy[3]


@njit(cache=CACHE, inline="always")
def object_points_into(
    points: np.ndarray, n_object: int, n_vertices: int, q: np.ndarray, out: np.ndarray
) -> None:
    """:func:`world_points_into` for the object's rows alone (its vertices and its normals),
    with the same arithmetic: for Newton's iterations, which move the object and not the
    hand."""
    c, s = math.cos(q[2]), math.sin(q[2])
    for i in range(n_object):
        x, y = points[i, 0], points[i, 1]
        out[i, 0] = c * x - s * y
        out[i, 1] = s * x + c * y
        out[i, 0] += q[0]
        out[i, 1] += q[1]
    for i in range(n_vertices, n_vertices + n_object):
        x, y = points[i, 0], points[i, 1]
        out[i, 0] = c * x - s * y
        out[i, 1] = s * x + c * y


@njit(cache=CACHE)
def contact_rows(
    world: np.ndarray, n_object: int, n_vertices: int, keys: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points (m, 2), normals into the object (m, 2), gaps (m,), edge parameters (m,) and
    edge lengths (m,) of the contacts ``keys`` (m, 4) at the placement ``world``.

    The edge parameter places the vertex's projection along its edge (0 at the edge's first
    vertex, 1 at its second); on the support it is 0.5 and the length infinite.

    The five are views of one new array: one allocation instead of five, at every check.
    """
    rows = np.empty((keys.shape[0], 7))
    contact_rows_into(world, n_object, n_vertices, keys, rows)
    return rows[:, 0:2], rows[:, 2:4], rows[:, 4], rows[:, 5], rows[:, 6]


@njit(cache=CACHE, inline="always")
def contact_rows_into(
    world: np.ndarray, n_object: int, n_vertices: int, keys: np.ndarray, rows: np.ndarray
) -> None:
    """:func:`contact_rows` into the columns of ``rows`` (m, 7): points, normals, gaps,
    edge parameters, edge lengths (for Newton's iterations, without allocating)."""
    m = keys.shape[0]
    P, N, F, T, L = rows[:, 0:2], rows[:, 2:4], rows[:, 4], rows[:, 5], rows[:, 6]
    for i in range(m):
        body, kind, k, j = keys[i, 0], keys[i, 1], keys[i, 2], keys[i, 3]
        if kind == EDGE:
            px, py = world[k, 0], world[k, 1]
            if body == SUPPORT:
                P[i, 0], P[i, 1] = px, py
                N[i, 0], N[i, 1] = 0.0, 1.0
                F[i], T[i], L[i] = py, 0.5, np.inf
                continue
            first = n_object + 4 * (body - 1)
            a = first + j
            b = first + (j + 1) % 4
            nx, ny = world[n_vertices + a, 0], world[n_vertices + a, 1]
        else:
            p = n_object + 4 * (body - 1) + j
            px, py = world[p, 0], world[p, 1]
            a = k
            b = (k + 1) % n_object
            nx, ny = world[n_vertices + a, 0], world[n_vertices + a, 1]
        dx, dy = world[b, 0] - world[a, 0], world[b, 1] - world[a, 1]
        rx, ry = px - world[a, 0], py - world[a, 1]
        L2 = dx * dx + dy * dy
        P[i, 0], P[i, 1] = px, py
        F[i] = nx * rx + ny * ry
        T[i] = (rx * dx + ry * dy) / L2
        L[i] = L2**0.5
        if kind == EDGE:
            N[i, 0], N[i, 1] = nx, ny
        else:
            N[i, 0], N[i, 1] = -nx, -ny


@njit(cache=CACHE)
def place(model, q: np.ndarray, h: np.ndarray) -> np.ndarray:
    """:func:`world_points` of a :class:`~grasp_env.sim.model.Model`'s bodies at ``(q, h)``."""
    return world_points(model.points, model.body, model.n_vertices, model.half, q, h)
