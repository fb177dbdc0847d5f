"""A whole hand move, compiled: the paper's active-set method (section 3.1) from ``s = 0`` to
the end of a straight-line hand path ``h(s) = h0 + s (h1 - h0)``, in one call: :func:`run`
(from compiled code, with a :class:`grasp_env.sim.model.Model`) or :func:`run_packed` (from
Python, the model packed into arrays).

A move is cut short where a hand vertex would enter the support
(:func:`grasp_env.sim.hand.support_limit`), skipped where the hand stays clear of an object
resting on the support (:func:`hand_stays_clear`), followed increment by increment
(:func:`grasp_env.sim.increments.advance`), and ends with the contacts and forces of the
state it reaches (:func:`at_rest`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.errors import SimulationError
from grasp_env.sim import contact_sets
from grasp_env.sim.clearance import separation
from grasp_env.sim.equilibrium import rest_forces
from grasp_env.sim.events import NO_CHECK
from grasp_env.sim.fall import fall, held_here, touching
from grasp_env.sim.hand import along, support_limit, vertex_speeds
from grasp_env.sim.increments import advance
from grasp_env.sim.model import unpack
from grasp_env.sim.placement import contact_rows, place, world_points_into


@njit(cache=CACHE)
def new_log() -> list:
    """An empty event log (:mod:`grasp_env.sim.events`)."""
    log = [(NO_CHECK, 0.0, contact_sets.empty())]
    log.pop()
    return log


@njit(cache=CACHE)
def settle(model, q: np.ndarray, h: np.ndarray, solves: np.ndarray):
    """The object at ``(q, h)`` after any fall to rest: ``(q, events)``."""
    events = new_log()
    if not held_here(model, q, h, model.ftol):
        q = fall(model, q, h, 0.0, events, solves)[0]
    return q, events


#: Rounds of conservative advancement :func:`hand_stays_clear` takes before it leaves a move
#: that keeps coming closer to the object to the full simulation.
CLEAR_ROUNDS = 8


@njit(cache=CACHE)
def hand_stays_clear(model, q: np.ndarray, h0: np.ndarray, dh: np.ndarray, known: np.ndarray):
    """Whether a move ``dh`` from ``h0`` leaves alone an object resting on the support
    alone: every hand body stays farther from it than contact detection looks (``10 tol``)
    all along, so no contact is made or lost and the object stays at rest.

    Conservative advancement: a body's separating distance along its best axis (a lower
    bound on its distance) shrinks by at most how far its vertices move
    (:func:`grasp_env.sim.hand.vertex_speeds`), so from ``s`` the hand may go on until the
    first body could have used up its clearance; the distances are measured again there,
    up to ``CLEAR_ROUNDS`` times. A hand that passes close by the object is cleared in a few
    rounds; one that comes within the margin is not."""
    if not contact_sets.all_on_support(known):
        return False
    travel = vertex_speeds(model, dh)
    margin = 10.0 * model.tol
    s = 0.0
    world = np.empty_like(model.points)
    for _ in range(CLEAR_ROUNDS):
        h = along(h0, dh, s)
        world_points_into(model.points, model.body, model.n_vertices, model.half, q, h, world)
        ds = np.inf
        for b in range(1, 4):
            clear = separation(world, model.n_object, model.n_vertices, b) - margin
            if clear <= 0.0:
                return False
            if travel[b - 1] > 0.0:
                ds = min(ds, clear / travel[b - 1])
        s += ds
        if s > 1.0:
            return True
    return False


#: Layout of the float array :func:`run` returns: the object pose, the hand, the ``s``
#: reached, the support limit ``s_end``, and the flags ``blocked``, ``jammed`` and
#: ``untouched`` as 0.0 or 1.0 (one array crosses back into Python at once).
OUT_Q, OUT_H = slice(0, 3), slice(3, 8)
OUT_S, OUT_S_END, OUT_BLOCKED, OUT_JAMMED, OUT_UNTOUCHED = 8, 9, 10, 11, 12
OUT_SIZE = 13
#: Columns of the contact rows :func:`at_rest` returns, one row per contact.
ROW_POINT, ROW_NORMAL, ROW_GAP, ROW_FORCE = slice(0, 2), slice(2, 4), 4, 5
ROW_SIZE = 6


@njit(cache=CACHE)
def run(
    model, q: np.ndarray, h0: np.ndarray, h1: np.ndarray, known: np.ndarray, use_known: bool,
    solves: np.ndarray,
):  # fmt: skip
    """A straight-line hand move from ``h0`` toward ``h1``, stopped short where a hand vertex
    would enter the support, and the state it ends in, in one call: ``(out, events, keys,
    rows)``, with ``out`` laid out as ``OUT_*`` says (the support limit ``s_end``, with
    ``blocked`` when it cuts the move short, and the ``s`` reached) and ``(keys, rows)``
    :func:`at_rest` of the final state.

    ``untouched``: the object rested on the support alone (``known``, when ``use_known``) and
    no hand body came near it (:func:`hand_stays_clear`), so nothing about it changed; the
    move loop and ``at_rest`` are skipped (its keys and rows are then empty). Otherwise the
    move is followed from ``s = 0`` to ``s_end`` (:func:`grasp_env.sim.increments.advance`;
    ``known`` are the contacts touching at the start when ``use_known``, else they are
    detected), or the object settles where the hand does not move. A non-finite end state
    raises ``SimulationError``.
    """
    s_end, blocked = support_limit(model, h0, h1)
    dh = h1 - h0
    if use_known and hand_stays_clear(model, q, h0, s_end * dh, known):
        out = _out(q, along(h0, dh, s_end), s_end, s_end, blocked, False, True)
        return out, new_log(), contact_sets.empty(), np.zeros((0, ROW_SIZE))
    if not np.any(dh) or s_end <= 0.0:  # the hand stays where it is
        q, events = settle(model, q, h0, solves)
        s, jammed = 0.0, False
    else:
        q, s, jammed, events = advance(model, q, h0, dh, s_end, known, use_known, new_log(), solves)
    h = h0 + s * dh
    if not (_finite(q) and _finite(h)):
        raise SimulationError("the move ended in a non-finite state")
    keys, rows = at_rest(model, q, h)
    return _out(q, h, s, s_end, blocked, jammed, False), events, keys, rows


@njit(cache=CACHE, inline="always")
def _finite(x: np.ndarray) -> bool:
    """``np.isfinite(x).all()`` for a 1-D array, without its array."""
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            return False
    return True


@njit(cache=CACHE)
def _out(q, h, s, s_end, blocked, jammed, untouched) -> np.ndarray:
    """The ``OUT_*`` array of a move's end (the hand ``h`` an array or a tuple)."""
    out = np.empty(OUT_SIZE)
    out[OUT_Q] = q
    for i in range(5):
        out[OUT_H.start + i] = h[i]
    out[OUT_S], out[OUT_S_END] = s, s_end
    out[OUT_BLOCKED], out[OUT_JAMMED], out[OUT_UNTOUCHED] = blocked, jammed, untouched
    return out


@njit(cache=CACHE)
def at_rest(model, q: np.ndarray, h: np.ndarray):
    """The contacts of a state at rest: ``(keys, rows)``, a row per contact with its point,
    normal, gap and force (``ROW_*``), the forces the least total force in equilibrium
    (:func:`grasp_env.sim.equilibrium.rest_forces`)."""
    world = place(model, q, h)
    keys = touching(model, world, contact_sets.empty())
    P, N, gaps, _, _ = contact_rows(world, model.n_object, model.n_vertices, keys)
    rows = np.empty((keys.shape[0], ROW_SIZE))
    rows[:, ROW_POINT] = P
    rows[:, ROW_NORMAL] = N
    rows[:, ROW_GAP] = gaps
    rows[:, ROW_FORCE] = rest_forces(model, world, q[:2], keys)
    return keys, rows


@njit(cache=CACHE)
def run_packed(
    points, body, scale, per_length, gravity, reach, numbers, q, h0, h1, known, use_known,
    solves,
):  # fmt: skip
    """:func:`run` of a model in its :func:`grasp_env.sim.model.pack` form: the entry point
    from Python, where a model crosses as arrays."""
    model = unpack(points, body, scale, per_length, gravity, reach, numbers)
    return run(model, q, h0, h1, known, use_known, solves)
