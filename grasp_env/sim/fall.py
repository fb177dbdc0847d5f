"""Quasi-static falls: the object follows the steepest admissible descent of its potential
energy (gravity projected onto the admissible cone, in the mass metric) until contacts
hold it.

Each fall step keeps the descent's tight contacts closed (Newton on their equations) and is
shortened to the first new contact or edge end; where three or more tight contacts are
dependent to tolerance and no step keeping them all closed goes down, it lets one go (their
curvature opens it). Near a stable rest on one or two contacts (a cradle, where descent
converges only linearly) the rest pose is solved for directly.
Events are appended to the move's log (:mod:`grasp_env.sim.events`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.errors import SimulationError, WorkLimitError
from grasp_env.sim import consistency, contact_sets, detection
from grasp_env.sim.curvature import unstable
from grasp_env.sim.dependence import free_rows
from grasp_env.sim.equilibrium import ROUNDING, held, held_or_wedged
from grasp_env.sim.events import FALL_END, FALL_START
from grasp_env.sim.increment import (
    band_target,
    false_position,
    geometry_violation,
    newton,
    newton_held,
)
from grasp_env.sim.placement import SUPPORT, contact_rows, place
from grasp_env.sim.pose import constraint_matrix
from grasp_env.solvers import dense, least_norm

#: Halvings of a fall step that lowers nothing before it counts as no way down.
HALVINGS = 50


@njit(cache=CACHE)
def touching(model, world: np.ndarray, exclude: np.ndarray) -> np.ndarray:
    """The contacts at a placement (:func:`grasp_env.sim.detection.detect`)."""
    return detection.detect(world, model.n_object, model.n_vertices, model.tol, exclude)


@njit(cache=CACHE)
def held_here(model, q: np.ndarray, h: np.ndarray, ftol: float, wedge: bool = False) -> bool:
    """Whether the contacts touching at ``(q, h)`` hold the object, to ``ftol`` (with
    ``wedge``, or wedge it: :func:`grasp_env.sim.equilibrium.held_or_wedged`)."""
    world = place(model, q, h)
    keys = touching(model, world, contact_sets.empty())
    if wedge:
        return held_or_wedged(model, world, q[:2], keys, ftol, 0.0)
    return held(model, world, q[:2], keys, ftol, 0.0)


@njit(cache=CACHE)
def descent(model, world: np.ndarray, q: np.ndarray, keys: np.ndarray):
    """Steepest admissible descent (scaled twist) for contacts ``keys``, and the contacts it
    keeps closed: ``a = argmin |a - g|^2 s.t. C a >= 0`` (gravity projected on the cone), the
    directions free to tolerance admissible both ways
    (:func:`grasp_env.sim.dependence.free_rows`)."""
    g = np.array([0.0, -1.0, 0.0])
    P, N, _, _, _ = contact_rows(world, model.n_object, model.n_vertices, keys)
    Cs = free_rows(model, constraint_matrix(P, N, q[:2])) * model.scale
    w, ok = least_norm.least_norm(np.zeros((0, 3)), np.zeros(0), Cs, -dense.matvec(Cs, g), 1e-10)
    if not ok:
        raise SimulationError("fall direction infeasible")
    a = w + g
    tight = dense.matvec(Cs, a) <= 1e-10
    return a, keys[tight].copy()


@njit(cache=CACHE)
def fall_step(model, q: np.ndarray, h: np.ndarray, E: np.ndarray, d: np.ndarray, solves):
    """One fall step of at most ``d``, shortened to the first new contact or edge end:
    ``(q_new, at_event, moved)``; ``at_event`` when the step was shortened to an event,
    ``moved`` False when no point along ``d`` was admissible (``q_new`` is ``q``).

    The event is located on the term of the geometric violation
    (:func:`grasp_env.sim.consistency.geometry_terms`) that the nearest violated point
    violates: a point with nothing violated is the event when that term lies within
    tolerance of its limit. (The other terms may sit there already: a hand body touching the
    object overlaps it by about zero.) The search is :func:`grasp_env.sim.increment.locate`'s:
    false position toward :func:`grasp_env.sim.increment.band_target` with the Illinois rule,
    halving where the term is not known at both ends (a failed solve)."""
    q1, ok = newton(model, q + d, h, E, solves)
    trigger = -1  # the term violated at hi; -1: not known (a failed solve)
    hi_terms = np.zeros(3)
    if ok:
        hi_terms = _terms(model, q1, h, E)
        if hi_terms.max() <= model.tol:
            return q1, False, True
        trigger = int(np.argmax(hi_terms))
    lo_terms = _terms(model, q, h, E)
    lo, hi, q_lo, moved = 0.0, 1.0, q, False
    kept = 0  # +1: lo was kept by the last point, -1: hi was
    lo_value = hi_value = np.nan
    target = 0.0  # the trigger's band target, set with the trigger
    if trigger >= 0:
        target = band_target(lo_terms[trigger], model.tol)
        lo_value, hi_value = lo_terms[trigger] - target, hi_terms[trigger] - target
    for _ in range(200):
        mid = false_position(lo, hi, lo_value, hi_value)
        if hi - lo < 1e-16 or not lo < mid < hi:
            break  # located to rounding (near 1 doubles are 1.1e-16 apart)
        q_mid, ok = newton(model, q + mid * d, h, E, solves)
        if not ok:
            hi, trigger, lo_value, hi_value, kept = mid, -1, np.nan, np.nan, 0
            continue
        terms = _terms(model, q_mid, h, E)
        if terms.max() > model.tol:
            new_trigger = int(np.argmax(terms))
            if new_trigger != trigger:  # another term: aim at its band from lo
                trigger, kept = new_trigger, 0
                target = band_target(lo_terms[trigger], model.tol)
                lo_value = lo_terms[trigger] - target
            elif kept == 1:
                lo_value *= 0.5
            hi, hi_value, kept = mid, terms[trigger] - target, 1
        elif (terms[trigger] if trigger >= 0 else terms.max()) >= -model.tol:
            return q_mid, True, True
        else:
            lo, q_lo, lo_terms, moved = mid, q_mid, terms, True
            if trigger >= 0:
                lo_value = terms[trigger] - target
                if kept == -1:
                    hi_value *= 0.5
                kept = -1
    return q_lo, True, moved


@njit(cache=CACHE)
def _terms(model, q: np.ndarray, h: np.ndarray, E: np.ndarray) -> np.ndarray:
    """:func:`grasp_env.sim.consistency.geometry_terms` at ``(q, h)``."""
    return consistency.geometry_terms(place(model, q, h), model.n_object, model.n_vertices, E)


@njit(cache=CACHE)
def cradle(model, q: np.ndarray, h: np.ndarray, keys: np.ndarray, solves):
    """The rest pose of a fall that has nearly come to rest on one or two contacts: their
    equilibrium pose by Newton, if it lies within one fall step, no higher, with nothing
    violated, the contacts there hold the object, and it is a minimum of the potential
    energy along their poses (:func:`grasp_env.sim.curvature.unstable`): ``(q_rest,
    found)``. Newton finds a maximum as readily, the very one a fall released next to it has
    just left, within the tolerance of its height and held there by a contact touching with
    zero force."""
    if not 0 < keys.shape[0] < 3:
        return q, False
    q_rest, ok = newton_held(model, q, h, keys, solves)
    if not ok or q_rest[1] > q[1] + model.tol:
        return q, False
    if np.abs((q_rest - q) / model.scale).max() > model.fall_step:
        return q, False
    if geometry_violation(model, q_rest, h, keys) > model.tol:
        return q, False
    if not held_here(model, q_rest, h, 1e-12 * model.weight):
        return q, False
    if unstable(model, place(model, q_rest, h), q_rest[:2], keys):
        return q, False
    return q_rest, True


@njit(cache=CACHE)
def at_edge_end(model, world: np.ndarray, key: np.ndarray) -> bool:
    """Whether contact ``key``'s point lies within two tolerances of an end of its edge."""
    _, _, _, T, L = contact_rows(world, model.n_object, model.n_vertices, key.reshape(1, 4))
    return min(T[0], 1.0 - T[0]) * L[0] <= 2.0 * model.tol


@njit(cache=CACHE)
def fall_options(model, world: np.ndarray, keys: np.ndarray) -> list:
    """Contact sets a fall step may keep: at a vertex-vertex touch any one candidate's
    half-plane suffices locally, or all candidates at once (always admissible). A contact
    at the very end of its edge (an object vertex at a hand edge's end, a hand vertex at an
    object edge's end) may slide off it: then its twins, which detection folds into it,
    carry the slide on (the vertex at that end on the other body's edge, or the same vertex
    on the next edge where the two edges are collinear)."""
    options = contact_sets.choices(model, world, keys)
    if len(options) > 1:
        options.append(keys)
    ends = contact_sets.empty()
    for i in range(keys.shape[0]):
        k = keys[i]
        if k[0] != SUPPORT and at_edge_end(model, world, k):
            ends = contact_sets.with_key(ends, k)
    if ends.shape[0] > 0:
        twins = touching(model, world, ends)
        if not contact_sets.equal(twins, keys):
            for choice in contact_sets.choices(model, world, twins):
                options.append(choice)
    return options


@njit(cache=CACHE)
def lowers(model, q: np.ndarray, q_new: np.ndarray, at_event: bool) -> bool:
    """Whether a fall step from ``q`` to ``q_new`` goes down: it lowers the object by more
    than rounding, or reaches a new contact along a nearly flat way down."""
    if q_new[1] < q[1] - 1e-12 * model.size:
        return True
    return at_event and q_new[1] <= q[1] and np.any(q_new != q)


@njit(cache=CACHE)
def backtrack(model, q: np.ndarray, h: np.ndarray, E: np.ndarray, d: np.ndarray, solves):
    """The fall step along ``d`` keeping ``E`` closed, halved until it goes down
    (:func:`lowers`; near a stable rest, a cradle, a full step overshoots): ``(q_new,
    at_event)``."""
    q_new, at_event = q, False
    for _ in range(HALVINGS):
        q_new, at_event, stepped = fall_step(model, q, h, E, d, solves)
        if lowers(model, q, q_new, at_event):
            break
        if at_event and not stepped:
            # No admissible point along d at all: the bisection already tried every step a
            # halved d would (d/2, d/4, ... down to rounding).
            break
        d = 0.5 * d
    return q_new, at_event


@njit(cache=CACHE)
def fall(model, q: np.ndarray, h: np.ndarray, s: float, events: list, solves):
    """Quasi-static fall from ``q`` at hand ``h`` (path parameter ``s``): ``(q, moved)``,
    the rest pose and whether the object moved at all. Logs the fall's start and end."""
    events.append((FALL_START, s, contact_sets.empty()))
    moved = False
    q0, last_y = q, np.inf
    for _ in range(model.max_iterations):
        world = place(model, q, h)
        keys = touching(model, world, contact_sets.empty())
        drop, last_y = last_y - q[1], q[1]
        # Held only to rounding: near the boundary of equilibrium a residual within the usual
        # tolerance still leaves a way down, which the descent below finds. A wedge is held
        # by large forces that balance it to their own rounding: every descent from there
        # would be that rounding.
        if held(model, world, q[:2], keys, 1e-12 * model.weight, ROUNDING):
            events.append((FALL_END, s, keys))
            return q, moved
        # Wedged at second order, the last round lowering the object by less than the
        # tolerance: it would only creep on, every way down from here cutting into the
        # contacts. A fall that got no lower than the tolerance did not move it.
        if drop < model.tol and held_or_wedged(
            model, world, q[:2], keys, 1e-12 * model.weight, ROUNDING
        ):
            if q0[1] - q[1] < model.tol:
                q, moved = q0, False
                keys = touching(model, place(model, q, h), contact_sets.empty())
            events.append((FALL_END, s, keys))
            return q, moved
        q_rest, found = cradle(model, q, h, keys, solves)
        if found:
            q, moved = q_rest, True  # held exactly there: the next pass ends the fall
            continue
        # Of the options, the step that lowers the potential energy most.
        best, best_event, have_best = q, False, False
        for choice in fall_options(model, world, keys):
            a, E = descent(model, world, q, choice)
            norm_a = math.sqrt(dense.dot(a, a))
            if norm_a < 1e-13:
                continue  # gravity is balanced to first order by this choice
            d = a * model.scale / norm_a * model.fall_step
            q_new, at_event = backtrack(model, q, h, E, d, solves)
            if E.shape[0] > 2 and not lowers(model, q, q_new, at_event):
                # Three or more contacts dependent to tolerance leave the descent free to
                # first order, but Newton, keeping them all closed, can only return to q:
                # the curvature opens one of them along the descent. Let each go in turn;
                # the step's geometric check keeps the one let go from cutting in.
                for i in range(E.shape[0]):
                    q_i, event_i = backtrack(model, q, h, contact_sets.without(E, E[i]), d, solves)
                    if q_i[1] < q_new[1]:
                        q_new, at_event = q_i, event_i
            if not have_best or q_new[1] < best[1]:
                best, best_event, have_best = q_new, at_event, True
        # A step that ends on an event (a new contact, an edge's end) changes the contacts
        # for the next step however short it is; otherwise a negligible drop means rest.
        if not have_best or (
            not (best_event and np.any(best != q)) and best[1] > q[1] - 1e-12 * model.size
        ):
            # No step lowers the object: a nearly level way down to a rest on the one or two
            # contacts it keeps closed (a flat side along a finger and a fingertip holding
            # the object to slightly more than the tolerance) ends in that rest.
            if keys.shape[0] > 2:
                q_rest, found = cradle(model, q, h, descent(model, world, q, keys)[1], solves)
                if found:
                    q, moved = q_rest, True
                    continue
            events.append((FALL_END, s, keys))  # no admissible descent lowers the object
            return q, moved
        q, moved = best, True
    raise WorkLimitError("fall did not come to rest")


@njit(cache=CACHE)
def fall_if_moved(model, q: np.ndarray, h: np.ndarray, s: float, events: list, solves):
    """:func:`fall`, ``(q, moved)``, logged only when the object moved: a fall that found no
    way down leaves no events."""
    q_fallen, moved = fall(model, q, h, s, events, solves)
    if not moved:
        events.pop()  # its start and end
        events.pop()
    return q_fallen, moved


@njit(cache=CACHE)
def fall_if_unheld(model, q: np.ndarray, h: np.ndarray, s: float, events: list, solves):
    """Fall to rest when the touching contacts cannot hold the object: ``(q, fell)``; a fall
    that found no way down leaves no events."""
    if held_here(model, q, h, model.ftol):
        return q, False
    return fall_if_moved(model, q, h, s, events, solves)


@njit(cache=CACHE)
def nudge(model, q, s, E, v, h0, dh, s_end, solves, wedge: bool):
    """Smallest step along ``E`` (geometrically consistent) after which the touching contacts
    can no longer hold the object (with ``wedge``, nor wedge it): ``(s, q, found)``, not
    found within one step."""
    ds = 1e-10
    while ds <= model.max_step and s + ds <= s_end:
        h = h0 + (s + ds) * dh
        q_new, ok = newton(model, q + v * ds, h, E, solves)
        if not ok or geometry_violation(model, q_new, h, E) > model.tol:
            return s, q, False
        if not held_here(model, q_new, h, model.ftol, wedge):
            return s + ds, q_new, True
        ds *= 4.0
    return s, q, False


@njit(cache=CACHE)
def nudge_and_fall(model, q, s, E, v, h0, dh, s_end, events, solves, wedge: bool = False):
    """Nudge the hand past the boundary of equilibrium (:func:`nudge`) and let the object
    fall to rest there: ``(s, q, found)``; not found where nothing falls there either (an
    object wedged at a fold, held by forces that balance it only to their rounding), or
    where the fall finds no way down to a rest the contacts hold (a pinch at a fold: past
    it the pinching contacts are dependent to tolerance, free to first order along their
    dependence but blocked there by their curvature, so the object neither stays held nor
    falls): the object does not get past the boundary, and the hand stops there. With
    ``wedge`` the boundary is that of the object held or wedged
    (:func:`grasp_env.sim.equilibrium.held_or_wedged`), past which the fall must end in such
    a rest too."""
    s_new, q_new, found = nudge(model, q, s, E, v, h0, dh, s_end, solves, wedge)
    if not found:
        return s, q, False
    h = h0 + s_new * dh
    logged = len(events)
    q_rest, moved = fall_if_moved(model, q_new, h, s_new, events, solves)
    if not moved:
        return s, q, False  # wedged at a fold just ahead: no way past it
    world = place(model, q_rest, h)
    keys = touching(model, world, contact_sets.empty())
    rest = held(model, world, q_rest[:2], keys, model.ftol, ROUNDING) or (
        wedge and held_or_wedged(model, world, q_rest[:2], keys, model.ftol, ROUNDING)
    )
    if not rest:
        while len(events) > logged:
            events.pop()  # the fall that found no rest
        return s, q, False
    return s_new, q_rest, True
