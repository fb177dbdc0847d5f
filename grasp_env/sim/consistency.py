"""Consistency of an active contact set at a placement: what the simulator's step checks.

After a Newton step along the hand's path, the active set ``E`` (rows of ``keys``) is still
valid when no other vertex has entered a body, no body overlaps the object, no active
contact's point has slid past the end of its edge, and the contacts still hold the object
with non-negative forces. These kernels return the signed violations (positive beyond the
limit), in length units; see :meth:`grasp_env.simulator.Simulator._check`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim import clearance
from grasp_env.sim.placement import EDGE, contact_rows
from grasp_env.sim.pose import independent_forces
from grasp_env.solvers import dense


@njit(cache=CACHE)
def pinned_vertices(keys: np.ndarray) -> np.ndarray:
    """The ``(body, kind, vertex)`` each contact pins: the object vertex of an edge contact,
    the hand vertex of a tip contact, shape (m, 3)."""
    out = np.empty((keys.shape[0], 3), dtype=np.int64)
    for i in range(keys.shape[0]):
        out[i, 0], out[i, 1] = keys[i, 0], keys[i, 1]
        out[i, 2] = keys[i, 2] if keys[i, 1] == EDGE else keys[i, 3]
    return out


@njit(cache=CACHE)
def _edge_ends(T: np.ndarray, L: np.ndarray) -> np.ndarray:
    """How far each contact point lies beyond an end of its edge (<= 0 on the edge), in
    length units; -inf on the support (an edge without ends)."""
    out = np.empty(T.shape[0])
    for i in range(T.shape[0]):
        out[i] = max(-T[i], T[i] - 1.0) * L[i] if math.isfinite(L[i]) else -np.inf
    return out


@njit(cache=CACHE)
def violations(
    world: np.ndarray, n_object: int, n_vertices: int, keys: np.ndarray, margin: float,
    com: np.ndarray, g: np.ndarray, length: float,
) -> tuple[float, np.ndarray, float, int, np.ndarray, int, float, float]:  # fmt: skip
    """Violations of the active set ``keys`` at placement ``world``, for gravity wrench ``g``
    about ``com`` (forces in weights; moments are divided by ``length``, the palm width, so
    that the residual's rows share units).

    Returns ``(gap, gap_key, depth, body, ends, lost, force, residual)``:

    * ``gap``, ``gap_key``: the smallest vertex-in-body gap of a vertex not pinned by the
      set, over the bodies within ``margin`` of the object (``gap_key[0] = -1`` for none);
    * ``depth``, ``body``: the deepest overlap of a hand body (``body = -1`` for none);
    * ``ends``: :func:`_edge_ends` of each contact;
    * ``lost``, ``force``: the contact of least force and that force, for up to three
      independent contacts balancing ``g`` (``lost = -1`` otherwise);
    * ``residual``: the norm of the equilibrium residual with those forces (least squares
      with non-negative forces when there are more contacts or they are dependent).
    """
    near = clearance.near_bodies(world, n_object, margin)
    gap, gap_key = clearance.min_gap(world, n_object, n_vertices, near, pinned_vertices(keys))
    depth, body = clearance.max_overlap(world, n_object, n_vertices, near)
    m = keys.shape[0]
    P, N, _, T, L = contact_rows(world, n_object, n_vertices, keys)
    ends = _edge_ends(T, L)
    lost, force, residual = -1, 0.0, 0.0
    if m > 0:
        W = np.empty((3, m))  # the wrench columns, moments in weight x palm width
        for i in range(m):
            W[0, i], W[1, i] = N[i, 0], N[i, 1]
            W[2, i] = ((P[i, 0] - com[0]) * N[i, 1] - (P[i, 1] - com[1]) * N[i, 0]) / length
        ok = False
        if m <= 3:
            lam, ok = independent_forces(W, g)
        if ok:
            for k in range(3):
                acc = 0.0
                for i in range(m):
                    acc += W[k, i] * lam[i]
                r = acc - g[k]
                residual += r * r
            residual = math.sqrt(residual)
            lost = int(np.argmin(lam))
            force = lam[lost]
        else:
            residual = dense.nnls(W, g)[1]
    return gap, gap_key, depth, body, ends, lost, force, residual


@njit(cache=CACHE)
def geometry_terms(
    world: np.ndarray, n_object: int, n_vertices: int, keys: np.ndarray
) -> np.ndarray:
    """The terms of :func:`geometry_violation`, shape (3,): the deepest penetration by a
    vertex not pinned by ``keys`` (minus the smallest gap), the deepest overlap of a hand body
    (minus its separation; about zero for a body that touches), and how far an active
    contact lies past the end of its edge."""
    gap, _ = clearance.min_gap(world, n_object, n_vertices, np.arange(4), pinned_vertices(keys))
    out = np.array([-gap, -np.inf, -np.inf])
    out[1] = clearance.max_overlap(world, n_object, n_vertices, np.arange(1, 4))[0]
    _, _, _, T, L = contact_rows(world, n_object, n_vertices, keys)
    ends = _edge_ends(T, L)
    for i in range(ends.shape[0]):
        out[2] = max(out[2], ends[i])
    return out


@njit(cache=CACHE)
def geometry_violation(
    world: np.ndarray, n_object: int, n_vertices: int, keys: np.ndarray
) -> float:
    """The worst geometric violation of the active set ``keys``: penetration by a vertex not
    pinned by it, overlap of a hand body, or a contact point past the end of its edge."""
    return geometry_terms(world, n_object, n_vertices, keys).max()
