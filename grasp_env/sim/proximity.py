"""How far the hand is from the object: fingertip positions and hand-object distances, for
the env's observation (``hand_features``), compiled so that they cost about a microsecond.

Distances are Euclidean, between the convex polygons of the placement ``world``
(:func:`grasp_env.sim.placement.world_points`), and zero where the bodies touch or overlap.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.clearance import separation
from grasp_env.sim.placement import world_points

#: Fingertip rows among each finger's 4 vertices (:func:`grasp_env.core.geometry.fingertip_index`).
TIP_ROW = (3, 0)
#: Layout of :func:`hand_features`: fingertip 1 and 2 ``(x, y)`` in the palm frame, then the
#: distances of the palm, finger 1, finger 2, fingertip 1 and fingertip 2 from the object.
TIPS, DISTANCES = slice(0, 4), slice(4, 9)
N_FEATURES = 9


@njit(cache=CACHE)
def _segment_distance(px, py, ax, ay, bx, by) -> float:
    """Distance of the point ``(px, py)`` from the segment ``a b``."""
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    t = 0.0
    if length2 > 0.0:
        t = min(max(((px - ax) * dx + (py - ay) * dy) / length2, 0.0), 1.0)
    ex, ey = ax + t * dx - px, ay + t * dy - py
    return math.sqrt(ex * ex + ey * ey)


@njit(cache=CACHE)
def point_distance(world: np.ndarray, first: int, n: int, px: float, py: float) -> float:
    """Distance of ``(px, py)`` from the convex counter-clockwise polygon in rows
    ``first .. first + n - 1`` of ``world``; zero on or inside it."""
    inside = True
    best = np.inf
    for k in range(n):
        ax, ay = world[first + k, 0], world[first + k, 1]
        j = first + (k + 1) % n
        bx, by = world[j, 0], world[j, 1]
        if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0.0:
            inside = False
        best = min(best, _segment_distance(px, py, ax, ay, bx, by))
    return 0.0 if inside else best


@njit(cache=CACHE)
def body_distance(world: np.ndarray, n_object: int, n_vertices: int, b: int) -> float:
    """Distance between the object and hand body ``b`` (1 palm, 2 finger 1, 3 finger 2); zero
    where they touch or overlap (the separating-axis test, which also catches edges that
    cross with no vertex inside)."""
    if separation(world, n_object, n_vertices, b) <= 0.0:
        return 0.0
    first = n_object + 4 * (b - 1)
    best = np.inf
    for i in range(4):
        best = min(
            best, point_distance(world, 0, n_object, world[first + i, 0], world[first + i, 1])
        )
    for k in range(n_object):
        best = min(best, point_distance(world, first, 4, world[k, 0], world[k, 1]))
    return best


@njit(cache=CACHE)
def hand_features(
    points: np.ndarray, body: np.ndarray, n_object: int, n_vertices: int, half: float,
    q: np.ndarray, h: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """Fingertip positions in the palm frame and hand-object distances at ``(q, h)``, laid
    out as :data:`TIPS` and :data:`DISTANCES` say (lengths in the scene's units); the model's
    stacked ``points`` and ``body`` (:class:`grasp_env.sim.model.Model`)."""
    world = world_points(points, body, n_vertices, half, q, h)
    out = np.empty(N_FEATURES)
    c, s = math.cos(h[2]), math.sin(h[2])
    for f in range(2):
        row = n_object + 4 * (f + 1) + TIP_ROW[f]
        dx, dy = world[row, 0] - h[0], world[row, 1] - h[1]
        out[2 * f] = c * dx + s * dy
        out[2 * f + 1] = -s * dx + c * dy
        out[7 + f] = point_distance(world, 0, n_object, world[row, 0], world[row, 1])
    for b in range(1, 4):
        out[3 + b] = body_distance(world, n_object, n_vertices, b)
    return out
