"""The hand along a straight-line move: how fast it pushes each contact, and where it would
enter the support.

A move is ``h(s) = h0 + s dh`` in ``(x_p, y_p, theta_p, q1, q2)``. The palm frame's origin
moves with ``(dh_x, dh_y)`` and turns at ``dh_theta``; each finger's frame origin is its
joint, at ``-+ half`` along the palm's x axis, and turns at ``dh_theta + dq_i``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.placement import SUPPORT

#: Points of the scan that brackets the first support crossing of a move.
SCAN = 65


@njit(cache=CACHE)
def contact_xi(
    model, h: np.ndarray, dh: np.ndarray, keys: np.ndarray, P: np.ndarray, N: np.ndarray
) -> np.ndarray:
    """``xi_i = n_i . v_hand(p_i)`` (eq. 20) for the contacts ``keys`` at points ``P`` with
    normals ``N``: the normal velocity of the hand body's material point there; zero on the
    support."""
    c, s = math.cos(h[2]), math.sin(h[2])
    half = model.half
    out = np.zeros(keys.shape[0])
    for i in range(keys.shape[0]):
        b = keys[i, 0]
        if b == SUPPORT:
            continue
        ox, oy, vx, vy, w = h[0], h[1], dh[0], dh[1], dh[2]
        if b > 1:  # a finger: its joint, carried by the palm's turn
            side = -1.0 if b == 2 else 1.0
            rx, ry = side * c * half, side * s * half
            ox, oy = h[0] + rx, h[1] + ry
            vx, vy = dh[0] - dh[2] * ry, dh[1] + dh[2] * rx
            w = dh[2] + dh[1 + b]
        rx, ry = P[i, 0] - ox, P[i, 1] - oy
        out[i] = N[i, 0] * (vx - w * ry) + N[i, 1] * (vy + w * rx)
    return out


@njit(cache=CACHE)
def lowest_point(model, h) -> float:
    """Lowest height of any hand vertex at hand configuration ``h`` (an array or a tuple:
    :func:`along`), the hand rows of :func:`grasp_env.sim.placement.world_points`, heights
    only."""
    s = math.sin(h[2])
    low = np.inf
    for b in range(1, 4):
        if b == 1:
            oy, angle = h[1], h[2]
        elif b == 2:
            oy, angle = h[1] - s * model.half, h[2] + h[3]
        else:
            oy, angle = h[1] + s * model.half, h[2] + h[4]
        sb, cb = math.sin(angle), math.cos(angle)
        first = model.n_object + 4 * (b - 1)
        for i in range(first, first + 4):
            low = min(low, sb * model.points[i, 0] + cb * model.points[i, 1] + oy)
    return low


@njit(cache=CACHE)
def vertex_speeds(model, dh: np.ndarray) -> tuple[float, float, float]:
    """A bound on how far any vertex of each hand body (palm, finger 1, finger 2) moves
    over the move ``dh``: its frame origin's travel (the joints ride the palm's turn) plus
    its turn times ``reach``."""
    turn = abs(dh[2])
    slide = math.hypot(dh[0], dh[1])
    joints = slide + turn * model.half
    return (
        slide + turn * model.reach[0],
        joints + abs(dh[2] + dh[3]) * model.reach[1],
        joints + abs(dh[2] + dh[4]) * model.reach[2],
    )


@njit(cache=CACHE, inline="always")
def along(h0: np.ndarray, dh: np.ndarray, s: float) -> tuple[float, float, float, float, float]:
    """The hand ``h0 + s dh`` of a move, as a tuple: the same arithmetic as the arrays',
    without allocating one at every point a loop evaluates."""
    return (
        h0[0] + s * dh[0], h0[1] + s * dh[1], h0[2] + s * dh[2], h0[3] + s * dh[3],
        h0[4] + s * dh[4],
    )  # fmt: skip


@njit(cache=CACHE)
def max_drop(model, dh: np.ndarray) -> float:
    """A bound on how far any hand vertex can descend over the move ``dh``: the palm's
    origin moves by ``|dh_y|``, the joints by at most ``half |dh_theta|`` more, and each body
    turns its vertices (within ``reach`` of its frame origin) by its own angle."""
    turn = abs(dh[2])
    joints = abs(dh[1]) + turn * model.half
    drop = abs(dh[1]) + turn * model.reach[0]
    drop = max(drop, joints + abs(dh[2] + dh[3]) * model.reach[1])
    return max(drop, joints + abs(dh[2] + dh[4]) * model.reach[2])


@njit(cache=CACHE)
def support_limit(model, h0: np.ndarray, h1: np.ndarray) -> tuple[float, bool]:
    """Largest ``s`` in [0, 1] before a hand vertex enters the support, and whether the move
    is cut short.

    Hand vertex heights are smooth in ``s``: the first of :data:`SCAN` evenly spaced points
    below ``-tol`` brackets the crossing, and bisection locates it to ``tol``. Points that
    :func:`max_drop` keeps above ``-tol`` (from the last point evaluated) are not
    evaluated, so a hand well clear of the support costs one evaluation.
    """
    dh = h1 - h0
    tol = model.tol
    n = SCAN - 1
    per_point = max_drop(model, dh) / n  # how far a vertex may descend between points
    k = 0  # the next point to evaluate
    while True:
        low = lowest_point(model, along(h0, dh, k / n))
        if k > 0 and low < -tol:
            break
        # the next `clear` points cannot lie below -tol
        clear = float(n) if per_point == 0.0 else min(n, (low + tol) / per_point * (1.0 - 1e-9))
        k += 1 + max(0, int(clear))  # clear >= 0 is floored
        if k > n:
            return 1.0, False
    lo, hi = (k - 1) / n, k / n
    while hi - lo > 1e-16 and lowest_point(model, along(h0, dh, lo)) > tol:  # touching, not above
        mid = 0.5 * (lo + hi)
        if lowest_point(model, along(h0, dh, mid)) < 0.0:
            hi = mid
        else:
            lo = mid
    return lo, True
