"""One increment of a move with a fixed active set: the pose on the contacts, what the
step violates, and where the first event lies.

A check is a kind (:mod:`grasp_env.sim.events`), a signed value in length units (above
``tol`` a violation, within ``tol`` an event sitting right here) and the contact it concerns
(``NONE`` for none; a body's overlap names the body in the first entry):

* ``NEW_CONTACT``: minus the smallest gap of a vertex not pinned by ``E``;
* ``OVERLAP``: how deep a hand body overlaps the object;
* ``EDGE_TO_TIP`` / ``TIP_TO_EDGE``: how far an active contact lies beyond its edge's end;
* ``LOST_CONTACT``: minus the smallest active force, scaled by size / weight;
* ``EQUILIBRIUM``: the residual of the object's equilibrium with ``E``'s forces minus
  ``tol`` (it only flags violations).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.errors import WorkLimitError
from grasp_env.sim import clearance, consistency, contact_sets, pose
from grasp_env.sim.contact_sets import NONE
from grasp_env.sim.events import (
    EDGE_TO_TIP,
    EQUILIBRIUM,
    JAM,
    LOST_CONTACT,
    NEW_CONTACT,
    NO_CHECK,
    OVERLAP,
    TIP_TO_EDGE,
)  # fmt: skip
from grasp_env.sim.hand import vertex_speeds
from grasp_env.sim.placement import EDGE, contact_rows, place

# ---------------------------------------------------------------------------------------------
# The pose on a contact set


@njit(cache=CACHE)
def count_solve(model, solves: np.ndarray) -> None:
    """Charge one pose solve to the call's budget ``solves[0]`` (``model.max_solves``)."""
    solves[0] += 1
    if solves[0] > model.max_solves:
        raise WorkLimitError("the move needs more than", model.max_solves, "pose solves")


@njit(cache=CACHE)
def gaps(model, q: np.ndarray, h: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """Gaps of the contacts ``keys`` at ``(q, h)``."""
    return contact_rows(place(model, q, h), model.n_object, model.n_vertices, keys)[2]


@njit(cache=CACHE)
def newton(model, q0: np.ndarray, h: np.ndarray, E: np.ndarray, solves: np.ndarray):
    """Solve ``phi_E(q, h) = 0`` from ``q0`` (least-motion Newton steps): ``(q, ok)``.

    Three or more object vertices on one straight edge (a flat side on the support or on a
    finger, whose middle vertices may bulge by less than the tolerance) are one supporting
    edge: their equations are dependent and, off the line by rounding or a bulge,
    inconsistent. Newton then solves for the edge's two outermost contacts, and the pose is
    accepted when the middle ones lie within tolerance as well.
    """
    if E.shape[0] == 0:
        return q0.copy(), True
    core = contact_sets.supporting_pairs(model, q0, h, E)
    count_solve(model, solves)
    q, ok = pose.newton(
        model.points, model.body, model.n_object, model.n_vertices, model.half, q0, h, core,
        model.scale, model.newton_tol, model.tol, model.size,
    )  # fmt: skip
    if not ok or core.shape[0] == E.shape[0]:
        return q, ok
    return q, np.abs(gaps(model, q, h, E)).max() <= model.tol


@njit(cache=CACHE)
def newton_held(model, q0: np.ndarray, h: np.ndarray, E: np.ndarray, solves: np.ndarray):
    """Pose held by fewer than three contacts: their gap equations together with the
    object's equilibrium (:func:`grasp_env.sim.pose.newton_held`): ``(q, ok)``. With
    ``|E| < 3`` the gap equations leave the object free directions, along which quasi-static
    motion keeps it at the potential's minimum."""
    count_solve(model, solves)
    return pose.newton_held(
        model.points, model.body, model.n_object, model.n_vertices, model.half, q0, h, E,
        model.scale, model.rho, model.gravity / model.weight, model.newton_tol, model.size,
    )  # fmt: skip


@njit(cache=CACHE)
def solve_pose(model, q0: np.ndarray, h: np.ndarray, E: np.ndarray, solves: np.ndarray):
    """The object pose on the path with active set ``E``, held by ``E`` in equilibrium:
    ``(q, ok)``."""
    if contact_sets.all_on_support(E):
        # Resting on the support alone, the object does not move while the hand moves (the
        # plan's velocity is zero): the pose that met the contacts still does.
        if np.abs(gaps(model, q0, h, E)).max() <= model.tol:
            return q0, True
    if 0 < E.shape[0] < 3:
        q, ok = newton_held(model, q0, h, E, solves)
        if ok:
            return q, True
    return newton(model, q0, h, E, solves)


# ---------------------------------------------------------------------------------------------
# Checks


@njit(cache=CACHE)
def geometry_violation(model, q: np.ndarray, h: np.ndarray, E: np.ndarray) -> float:
    """Penetration, overlap or a contact past its edge's end, at worst, for ``E``."""
    return consistency.geometry_violation(place(model, q, h), model.n_object, model.n_vertices, E)


@njit(cache=CACHE)
def checks(model, q: np.ndarray, h: np.ndarray, E: np.ndarray):
    """The checks of the active set ``E`` at ``(q, h)`` (module docstring):
    ``(kinds, values, keys)``."""
    gap, gap_key, depth, body, ends, lost, force, residual = consistency.violations(
        place(model, q, h), model.n_object, model.n_vertices, E, 0.05 * model.size + model.tol,
        q[:2], model.gravity, model.length,
    )  # fmt: skip
    m = E.shape[0]
    kinds = np.empty(m + 4, dtype=np.int64)
    values = np.empty(m + 4)
    keys = np.empty((m + 4, 4), dtype=np.int64)
    n = 0
    if gap_key[0] >= 0:
        kinds[n], values[n], keys[n] = NEW_CONTACT, -gap, gap_key
        n += 1
    if body >= 0:
        kinds[n], values[n], keys[n] = OVERLAP, depth, NONE
        keys[n, 0] = body
        n += 1
    for i in range(m):
        if ends[i] > -np.inf:
            kinds[n] = EDGE_TO_TIP if E[i, 1] == EDGE else TIP_TO_EDGE
            values[n], keys[n] = ends[i], E[i]
            n += 1
    if m > 0:
        scale = model.size / model.weight
        if lost >= 0:
            kinds[n], values[n], keys[n] = LOST_CONTACT, -force * scale, E[lost]
            n += 1
        kinds[n], values[n], keys[n] = EQUILIBRIUM, residual * scale - model.tol, NONE
        n += 1
    return kinds[:n], values[:n], keys[:n]


@njit(cache=CACHE)
def worst(kinds: np.ndarray, values: np.ndarray, keys: np.ndarray):
    """The largest check (the first of equal ones): ``(value, kind, key)``."""
    if kinds.shape[0] == 0:
        return -np.inf, NO_CHECK, NONE
    i = np.argmax(values)
    return values[i], kinds[i], keys[i]


@njit(cache=CACHE)
def value_of(kinds, values, keys, kind: int, key: np.ndarray) -> float:
    """The value of the check ``(kind, key)``, or -inf when it is not among them."""
    for i in range(kinds.shape[0]):
        if kinds[i] == kind and contact_sets.same(keys[i], key):
            return values[i]
    return -np.inf


# ---------------------------------------------------------------------------------------------
# Steps and events


@njit(cache=CACHE)
def try_step(
    model, q: np.ndarray, s: float, ds: float, E: np.ndarray, v: np.ndarray, h0: np.ndarray,
    dh: np.ndarray, guard: bool, solves: np.ndarray,
):  # fmt: skip
    """Newton step to ``s + ds`` and its checks: ``(ok, q_new, kind, key, value)`` with the
    worst check as the trigger of an event and its value (``JAM`` and NaN when Newton
    fails).

    With ``guard``, a Newton correction larger than half the predicted motion counts as a
    failure (over a long step it may have found another root of the equations).
    """
    h = h0 + (s + ds) * dh
    q_pred = q + v * ds
    q_new, ok = solve_pose(model, q_pred, h, E, solves)
    if ok and guard:
        move = np.abs((q_pred - q) / model.scale).max()
        ok = np.abs((q_new - q_pred) / model.scale).max() <= 0.5 * move + model.tol
    if not ok:
        return False, q, JAM, NONE, np.nan
    value, kind, key = worst(*checks(model, q_new, h, E))
    return value <= model.tol, q_new, kind, key, value


@njit(cache=CACHE)
def event_of(kind: int, key: np.ndarray):
    """The event a trigger reports: ``(kind, keys)``. An overlap is a new contact (edges
    about to cross) and a failed equilibrium a lost contact, neither with a known key."""
    if kind == EQUILIBRIUM:
        return LOST_CONTACT, contact_sets.empty()
    if kind == OVERLAP:
        return NEW_CONTACT, contact_sets.empty()
    if key[0] < 0:
        return kind, contact_sets.empty()
    return kind, key.reshape(1, 4).copy()


@njit(cache=CACHE)
def trigger_value(model, q, h, E, kind: int, key: np.ndarray) -> float:
    """The value of the check ``(kind, key)`` at ``(q, h)``; NaN for a trigger without one
    (a failed solve, the equilibrium residual) or when the check is not reported there."""
    if kind == JAM or kind == EQUILIBRIUM:
        return np.nan
    value = value_of(*checks(model, q, h, E), kind, key)
    return value if value > -np.inf else np.nan


@njit(cache=CACHE)
def short_of_band(model, q, h, E, kind: int, key: np.ndarray) -> bool:
    """Whether the check ``(kind, key)`` lies clearly inside its limit at ``(q, h)``, below
    its band ``[-tol, tol]``. A lost contact's check is minus the least force, whichever
    contact bears it: all of ``E``'s forces are then clearly positive."""
    if kind == LOST_CONTACT:
        kinds, values, _ = checks(model, q, h, E)
        for i in range(kinds.shape[0]):
            if kinds[i] == LOST_CONTACT:
                return values[i] < -model.tol
        return False
    return trigger_value(model, q, h, E, kind, key) < -model.tol


@njit(cache=CACHE)
def band_target(start: float, tol: float) -> float:
    """The value an event search aims its check at, given the check's value ``start`` at the
    consistent end of the bracket: the middle of the band's consistent half, ``-tol / 2``
    (inside the band rather than at the limit, so a located contact force is clearly
    positive or a gap clearly closed, not at a degenerate zero); where ``start`` already
    lies above it (a contact touching at the start, the event right there), the middle
    between ``start`` and ``tol``, which the check reaches in one interpolation where it is
    linear (the midpoint would take one halving per bit)."""
    target = -0.5 * tol
    if start > target:
        target = 0.5 * (start + tol)
    return target


@njit(cache=CACHE)
def false_position(lo: float, hi: float, lo_value: float, hi_value: float) -> float:
    """The next point of a search between ``lo`` (consistent) and ``hi`` (violated) for
    where a check reaches its target: where the check, linear between the ends, does so
    (``lo_value < 0 < hi_value``, the values relative to the target), kept a thousandth of
    the bracket from either end; the midpoint where either value is not known (NaN) or they
    do not bracket the target."""
    width = hi - lo
    if lo_value < 0.0 < hi_value:
        t = lo_value / (lo_value - hi_value)
        return lo + min(max(t, 1e-3), 1.0 - 1e-3) * width
    return lo + 0.5 * width


@njit(cache=CACHE)
def locate(
    model, q: np.ndarray, s_lo: float, s_hi: float, E: np.ndarray, v: np.ndarray,
    h0: np.ndarray, dh: np.ndarray, kind: int, key: np.ndarray, value: float,
    solves: np.ndarray,
):  # fmt: skip
    """The first point in ``(s_lo, s_hi]`` where the active set ``E`` stops being consistent,
    to within ``tol``, from the trigger ``(kind, key)`` found at ``s_hi`` with ``value``:
    ``(s, q, event kind, event keys)``. There the trigger's check sits within tolerance of
    its limit and nothing is violated beyond it.

    The bracket keeps a consistent ``s_lo`` and a violated ``s_hi``, as bisection does; the
    next point is where the trigger's check, linear between the ends, reaches
    :func:`band_target` (regula falsi with the Illinois rule: an end kept twice in a row has
    its value halved), and the midpoint whenever the check is not known at both ends (a
    failed solve, the equilibrium residual, another check taking over).

    A bracket that closes to rounding with the trigger's check still short of its band at
    the consistent end is no event of that check: the check jumped, and so did the pose,
    from one root of ``E``'s equations to another -- the two roots that meet at a fold (the
    contact normals turning concurrent), where the forces pass through infinity, not
    through zero, and change sign. Nothing consistent lies beyond: a ``JAM``.
    """
    q_lo = q
    start = trigger_value(model, q, h0 + s_lo * dh, E, kind, key)
    target = band_target(start, model.tol)
    lo_value = start - target
    hi_value = value - target
    kept = 0  # +1: s_lo was kept by the last point, -1: s_hi was
    for _ in range(200):
        mid = false_position(s_lo, s_hi, lo_value, hi_value)
        if mid <= s_lo or mid >= s_hi:
            if short_of_band(model, q_lo, h0 + s_lo * dh, E, kind, key):
                kind, key = JAM, NONE  # the check jumped over its band: a fold
            break
        h = h0 + mid * dh
        q_mid, ok = solve_pose(model, q_lo + v * (mid - s_lo), h, E, solves)
        if not ok:
            s_hi, kind, key, hi_value, lo_value, kept = mid, JAM, NONE, np.nan, np.nan, 0
            continue
        kinds, values, keys = checks(model, q_mid, h, E)
        worst_value, worst_kind, worst_key = worst(kinds, values, keys)
        if worst_value > model.tol:
            same = worst_kind == kind and contact_sets.same(worst_key, key)
            s_hi, kind, key, hi_value = mid, worst_kind, worst_key, worst_value - target
            if not same:  # another check took over: its value at s_lo is not known
                lo_value, kept = np.nan, 0
            elif kept == 1:
                lo_value *= 0.5
            kept = 1
            continue
        mid_value = value_of(kinds, values, keys, kind, key)
        if kind != EQUILIBRIUM and kind != JAM and mid_value >= -model.tol:
            if kind == OVERLAP:  # first touch: the vertex that touches
                for i in range(kinds.shape[0]):
                    if kinds[i] == NEW_CONTACT:
                        kind, key = NEW_CONTACT, keys[i]
                        break
            event, event_keys = event_of(kind, key)
            return mid, q_mid, event, event_keys
        s_lo, q_lo = mid, q_mid
        lo_value = mid_value - target if mid_value > -np.inf else np.nan
        if kept == -1:
            hi_value *= 0.5
        kept = -1
    event, event_keys = event_of(kind, key)
    return s_lo, q_lo, event, event_keys


@njit(cache=CACHE)
def sweep_limit(
    model, q: np.ndarray, h: np.ndarray, dh: np.ndarray, v: np.ndarray, E: np.ndarray,
    rest: float,
) -> float:  # fmt: skip
    """Largest ``ds`` (up to ``rest``) after which no hand body out of contact can have passed
    through the object: its separating distance plus the thinnest body's width, over a bound
    on how fast its vertices approach the object's (conservative advancement). Only the
    step's end is checked for penetration, so this keeps thin fingers from tunnelling; short
    moves (most env steps) need no distances at all."""
    speed = vertex_speeds(model, dh)
    # the object moves too: twice its predicted speed, for the path's curvature
    obj = 2.0 * (np.hypot(v[0], v[1]) + abs(v[2]) * model.size)
    if (max(speed) + obj) * rest <= model.thinnest:
        return rest
    world = place(model, q, h)
    limit = rest
    for b in range(1, 4):
        touching = False
        for i in range(E.shape[0]):
            touching = touching or E[i, 0] == b
        if touching:
            continue
        d = clearance.separation(world, model.n_object, model.n_vertices, b)
        rate = speed[b - 1] + obj
        if rate > 0.0:
            limit = min(limit, (max(d, 0.0) + model.thinnest) / rate)
    return limit
