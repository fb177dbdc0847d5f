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

from grasp_env.sim.placement import SUPPORT, world_points

#: Points of the scan that brackets the first support crossing of a move.
SCAN = 65


@njit(cache=True)
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


@njit(cache=True)
def lowest_point(model, h: np.ndarray) -> float:
    """Lowest height of any hand vertex at hand configuration ``h``."""
    q = np.zeros(3)
    world = world_points(model.points, model.body, model.n_vertices, model.half, q, h)
    low = np.inf
    for i in range(model.n_object, model.n_vertices):
        low = min(low, world[i, 1])
    return low


@njit(cache=True)
def support_limit(model, h0: np.ndarray, h1: np.ndarray) -> tuple[float, bool]:
    """Largest ``s`` in [0, 1] before a hand vertex enters the support, and whether the move
    is cut short. Hand vertex heights are smooth in ``s``: a scan of :data:`SCAN` points
    brackets the first crossing below ``-tol``, and bisection locates it to ``tol``."""
    dh = h1 - h0
    tol = model.tol
    lo = hi = -1.0
    for k in range(1, SCAN):
        s = k / (SCAN - 1)
        if lowest_point(model, h0 + s * dh) < -tol:
            lo, hi = (k - 1) / (SCAN - 1), s
            break
    if hi < 0.0:
        return 1.0, False
    while hi - lo > 1e-16 and lowest_point(model, h0 + lo * dh) > tol:  # touching, not above
        mid = 0.5 * (lo + hi)
        if lowest_point(model, h0 + mid * dh) < 0.0:
            hi = mid
        else:
            lo = mid
    return lo, True
