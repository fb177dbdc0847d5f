"""A whole hand move, compiled: the paper's active-set method (section 3.1) from ``s = 0`` to
the end of a straight-line hand path ``h(s) = h0 + s (h1 - h0)``.

Each increment runs

1. **plan**: the active set ``E`` and the least-motion object twist ``v``
   (:func:`grasp_env.sim.motion.plan`), or a jam, or a fall;
2. **solve**: the object pose at the step's end on ``E`` (:func:`grasp_env.sim.step.try_step`);
3. **check**: no penetration, overlap, contact past an edge's end or negative force;
4. **locate**: otherwise the first event, by bisection to ``tol``
   (:func:`grasp_env.sim.step.locate`);
5. **update**: the move goes on from the step's end or the event.

The move state carried from one increment to the next is: the pose ``q`` and path
parameter ``s``; a plan kept for the next increment (``carry``: ``E`` fixes the pose and
holds it, so it stays valid; ``override``: a plan with a touching contact forced in or a lost
one released); and what is known about the current point, cleared whenever ``s`` moves on:
contacts ``banned`` from the active set (events that recur at once), contacts ``forced`` in,
and the plan dropped for a lost contact (``losing``). Events that recur within a hair of
each other more than :data:`CHATTER` times are treated as happening here (chatter).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from grasp_env.errors import SimulationError, WorkLimitError
from grasp_env.sim import CACHE, contact_sets, motion
from grasp_env.sim.clearance import separation
from grasp_env.sim.equilibrium import determined, held, rest_forces
from grasp_env.sim.events import (
    EDGE_TO_TIP,
    JAM,
    LOST_CONTACT,
    NEW_CONTACT,
    NO_CHECK,
    TIP_TO_EDGE,
)  # fmt: skip
from grasp_env.sim.fall import fall, fall_if_unheld, held_here, nudge_and_fall, touching
from grasp_env.sim.hand import support_limit, vertex_speeds
from grasp_env.sim.model import unpack
from grasp_env.sim.placement import contact_rows, place
from grasp_env.sim.step import locate, sweep_limit, try_step

#: Chatter guard: an event (a contact lost, a jam) located more than CHATTER times in a row,
#: each time less than CHATTER_DS of the move after the last, is treated as happening at the
#: current point (a lost contact is dropped from the active set, a jam stops the hand)
#: instead of creeping on.
CHATTER = 3
CHATTER_DS = 1e-4
#: A move whose path parameter stays within CHATTER_DS for more than STALL increments (events
#: cycling at one point, e.g. a contact lost and found again and again) cannot be followed.
STALL = 200


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


@njit(cache=CACHE)
def stop_at_jam(model, q: np.ndarray, h: np.ndarray, s: float) -> None:
    """The hand stops at a jam; the object must be held there (at a fold by forces without
    bound). A jam whose object is neither held nor able to fall is a failure, not a state."""
    world = place(model, q, h)
    keys = touching(model, world, contact_sets.empty())
    if not held(model, world, q[:2], keys, model.ftol, np.inf):
        raise SimulationError("jam at s =", s, "with the object neither held nor falling")


@njit(cache=CACHE)
def hand_stays_clear(model, q: np.ndarray, h0: np.ndarray, dh: np.ndarray, known: np.ndarray):
    """Whether a move ``dh`` from ``h0`` leaves alone an object resting on the support
    alone: every hand body stays farther from it than contact detection looks (``10 tol``)
    all along, so no contact is made or lost and the object stays at rest. A body's
    separating distance along its best axis changes by at most how far its vertices move
    (:func:`grasp_env.sim.hand.vertex_speeds`)."""
    if not contact_sets.all_on_support(known):
        return False
    world = place(model, q, h0)
    travel = vertex_speeds(model, dh)
    margin = 10.0 * model.tol
    for b in range(1, 4):
        if separation(world, model.n_object, model.n_vertices, b) <= travel[b - 1] + margin:
            return False
    return True


#: Layout of the float array :func:`move_hand` returns: the object pose, the hand, the ``s``
#: reached, the support limit ``s_end``, and the flags ``blocked``, ``jammed`` and
#: ``untouched`` as 0.0 or 1.0 (one array crosses back into Python at once).
OUT_Q, OUT_H = slice(0, 3), slice(3, 8)
OUT_S, OUT_S_END, OUT_BLOCKED, OUT_JAMMED, OUT_UNTOUCHED = 8, 9, 10, 11, 12
OUT_SIZE = 13
#: Columns of the contact rows :func:`at_rest` returns, one row per contact.
ROW_POINT, ROW_NORMAL, ROW_GAP, ROW_FORCE = slice(0, 2), slice(2, 4), 4, 5


@njit(cache=CACHE)
def move_hand(
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
    move loop and ``at_rest`` are skipped (its keys and rows are then empty). A non-finite end
    state raises ``SimulationError``.
    """
    s_end, blocked = support_limit(model, h0, h1)
    dh = h1 - h0
    if use_known and hand_stays_clear(model, q, h0, s_end * dh, known):
        out = _out(q, h0 + s_end * dh, s_end, s_end, blocked, False, True)
        return out, new_log(), contact_sets.empty(), np.zeros((0, 6))
    q, s, jammed, events = move(model, q, h0, h1, s_end, known, use_known, solves)
    h = h0 + s * dh
    if not (np.isfinite(q).all() and np.isfinite(h).all()):
        raise SimulationError("the move ended in a non-finite state")
    keys, rows = at_rest(model, q, h)
    return _out(q, h, s, s_end, blocked, jammed, False), events, keys, rows


@njit(cache=CACHE)
def _out(q, h, s, s_end, blocked, jammed, untouched) -> np.ndarray:
    """The ``OUT_*`` array of a move's end."""
    out = np.empty(OUT_SIZE)
    out[OUT_Q] = q
    out[OUT_H] = h
    out[OUT_S], out[OUT_S_END] = s, s_end
    out[OUT_BLOCKED], out[OUT_JAMMED], out[OUT_UNTOUCHED] = blocked, jammed, untouched
    return out


@njit(cache=CACHE)
def move(
    model, q: np.ndarray, h0: np.ndarray, h1: np.ndarray, s_end: float, known: np.ndarray,
    use_known: bool, solves: np.ndarray,
):  # fmt: skip
    """Follow the move from ``s = 0`` to ``s_end``; ``known`` are the contacts touching at the
    start when ``use_known`` (else they are detected). Returns ``(q, s, jammed, events)``."""
    dh = h1 - h0
    if not np.any(dh) or s_end <= 0.0:
        q, events = settle(model, q, h0, solves)
        return q, 0.0, False, events
    return _advance(model, q, h0, dh, s_end, known, use_known, new_log(), solves)


@njit(cache=CACHE)
def _advance(model, q, h0, dh, s_end, known, use_known, events, solves):
    """The increment loop of :func:`move` (see the module docstring)."""
    none = contact_sets.empty()
    zero = np.zeros(3)
    s = 0.0
    # Events closer than tol along the hand's path count as here (no progress).
    reach = np.abs(dh[:2]).sum() + np.abs(dh[2:]).sum() * 2.0 * model.half
    s_eps = max(1e-13, model.tol / reach)
    keys = known
    stuck_fall = False
    has_carry, carry_E, carry_v = False, none, zero
    has_override, override_E, override_v = False, none, zero
    # what is known about the current point, cleared when s moves on
    banned, forced = none, none
    has_losing, losing_E, losing_v = False, none, zero
    run_kind, run_keys, run_count = NO_CHECK, none, 0  # the event located last (chatter)
    mark_s, mark_it = 0.0, 0  # where s last moved on by more than CHATTER_DS
    for it in range(model.max_iterations):
        if s > mark_s + CHATTER_DS:
            mark_s, mark_it = s, it
        elif it - mark_it > STALL:
            raise WorkLimitError("no progress after", STALL, "increments near s =", s)
        h = h0 + s * dh
        # 1. plan
        carried, overridden = has_carry, has_override
        if carried:
            outcome, E, v = motion.MOVE, carry_E, carry_v
            has_carry = False
        elif overridden:
            outcome, E, v = motion.MOVE, override_E, override_v
            has_override = False
        else:
            world = place(model, q, h)
            if use_known:
                use_known = False
            else:
                keys = touching(model, world, banned)
            outcome, E, v = motion.plan(model, world, q, h, dh, keys, not stuck_fall)
        stuck_fall = False
        if outcome == motion.JAM:
            if has_losing:
                # Contacts dropped for a negative force leave the object unheld just ahead:
                # past the boundary of equilibrium it falls.
                s_new, q_new, found = nudge_and_fall(
                    model, q, s, losing_E, losing_v, h0, dh, s_end, events, solves
                )
                if found:
                    s, q = s_new, q_new
                    banned, forced, has_losing = none, none, False
                    continue
            q_new, fell = fall_if_unheld(model, q, h, s, events, solves)
            if fell:
                q = q_new
                continue
            events.append((JAM, s, keys))
            stop_at_jam(model, q, h, s)
            return q, s, True, events
        if outcome == motion.FALL:
            q_new, moved = fall(model, q, h, s, events, solves)
            stuck_fall = not moved  # no way down after all: plan without falling
            if stuck_fall:
                events.pop()  # the fall that did not happen
                events.pop()
            q = q_new
            continue
        if s >= s_end - 1e-15:
            return q, s_end, False, events
        # 2-3. solve and check
        rest = sweep_limit(model, q, h, dh, v, E, s_end - s)
        ds = min(model.max_step, rest)
        tried = False
        if ds < rest and (carried or determined(model, place(model, q, h), q, E)):
            # E fixes the pose as a function of s and holds it with positive forces: it stays
            # the active set until an event and the pose needs no integration, so one step may
            # go to the end of the move (the check locates any event in it).
            ok, q_new, kind, key, value = try_step(model, q, s, rest, E, v, h0, dh, True, solves)
            tried = ok or kind != JAM
            if tried:
                ds = rest
        if not tried:
            ok, q_new, kind, key, value = try_step(model, q, s, ds, E, v, h0, dh, False, solves)
        if ok:
            # 5. update: the step is accepted
            h_new = h0 + (s + ds) * dh
            if determined(model, place(model, q_new, h_new), q_new, E):
                has_carry, carry_E, carry_v = True, E, (q_new - q) / ds
            q, s = q_new, s + ds
            banned, forced, has_losing = none, none, False
            continue
        # 4. locate the first event
        s_star, q_star, event, event_keys = locate(
            model, q, s, s + ds, E, v, h0, dh, kind, key, value, solves
        )
        # Chatter: the same event again and again, each within a hair's breadth of the last
        # (a contact whose force falls to zero again as soon as the re-planned active set
        # takes it back; an infeasible LP just ahead at a wedge). Treat it as happening here.
        near = s_star - s < CHATTER_DS
        if near and event == run_kind and contact_sets.equal(event_keys, run_keys):
            run_count += 1
        else:
            run_count = 1 if near else 0
        run_kind, run_keys = event, event_keys
        if s_star - s >= s_eps and run_count <= CHATTER:
            # 5. update: the move goes on from the event
            events.append((event, s_star, event_keys))
            q, s = q_star, s_star
            banned, forced, has_losing = none, none, False
            continue
        # The event sits right here.
        has_key = event_keys.shape[0] > 0
        key = event_keys[0] if has_key else contact_sets.NONE
        if has_key and (event == EDGE_TO_TIP or event == TIP_TO_EDGE or event == LOST_CONTACT):
            if contact_sets.index(banned, key) < 0:
                # The offending contact cannot stay active here: plan without it.
                banned = contact_sets.with_key(banned, key)
                if event == LOST_CONTACT:
                    # Its force reached zero: the others hold the object right there, so the
                    # motion goes on with them (the old plan's velocity as Newton's
                    # predictor); the old plan is kept in case releasing fails too.
                    has_losing, losing_E, losing_v = True, E, v
                    override_E = contact_sets.without(E, key)
                    has_override, override_v = override_E.shape[0] > 0, v
                continue
        if overridden:
            continue  # the forced plan could not go on: plan afresh
        reverted = False
        if event == NEW_CONTACT and has_key and contact_sets.index(E, key) < 0:
            is_banned = contact_sets.index(banned, key) >= 0
            if is_banned and has_losing:
                # Keeping the contact makes its force negative, dropping it lets the object
                # into it: the object sits at an equilibrium that the hand's motion destroys
                # (a potential maximum along the other contacts' family).
                E, v, reverted = losing_E, losing_v, True
            elif not is_banned and contact_sets.index(forced, key) < 0:
                # A touching contact the plan left open (zero force, not tight at the
                # least-norm velocity) closes at once: the object held by the others is
                # pushed into it, so it joins the active set. The plan's velocity keeps
                # every touching contact closed (V v >= xi).
                here = touching(model, place(model, q, h0 + s * dh), none)
                if contact_sets.index(here, key) >= 0:
                    forced = contact_sets.with_key(forced, key)
                    has_override, override_E, override_v = True, contact_sets.with_key(E, key), v
                    continue
        if event == LOST_CONTACT or reverted:
            # The object sits on the boundary of equilibrium: just ahead, no contact set
            # holds it. Nudge the hand past the boundary and let the object fall.
            s_new, q_new, found = nudge_and_fall(model, q, s, E, v, h0, dh, s_end, events, solves)
            if found:
                s, q = s_new, q_new
                banned, forced, has_losing = none, none, False
                continue
        # Nothing consistent lies just ahead: the active contacts' equations fold (their
        # normals turn concurrent and the forces needed grow without bound) or no contact can
        # be released. The hand cannot move on: a jam -- unless the contacts left cannot hold
        # the object, which then falls first.
        h = h0 + s * dh
        q_new, fell = fall_if_unheld(model, q, h, s, events, solves)
        if fell:
            q = q_new
            banned, forced, has_losing = none, none, False
            continue
        events.append((JAM, s, E))
        stop_at_jam(model, q, h, s)
        return q, s, True, events
    raise WorkLimitError("no progress after", model.max_iterations, "increments, at s =", s)


@njit(cache=CACHE)
def at_rest(model, q: np.ndarray, h: np.ndarray):
    """The contacts of a state at rest: ``(keys, rows)``, a row per contact with its point,
    normal, gap and force (``ROW_*``), the forces the least total force in equilibrium
    (:func:`grasp_env.sim.equilibrium.rest_forces`)."""
    world = place(model, q, h)
    keys = touching(model, world, contact_sets.empty())
    P, N, gaps, _, _ = contact_rows(world, model.n_object, model.n_vertices, keys)
    rows = np.empty((keys.shape[0], 6))
    rows[:, ROW_POINT] = P
    rows[:, ROW_NORMAL] = N
    rows[:, ROW_GAP] = gaps
    rows[:, ROW_FORCE] = rest_forces(model, world, q[:2], keys)
    return keys, rows


@njit(cache=CACHE)
def move_hand_packed(
    points, body, scale, per_length, gravity, reach, numbers, q, h0, h1, known, use_known,
    solves,
):  # fmt: skip
    """:func:`move_hand` of a model in its :func:`grasp_env.sim.model.pack` form: the entry
    point from Python, where a model crosses as arrays."""
    model = unpack(points, body, scale, per_length, gravity, reach, numbers)
    return move_hand(model, q, h0, h1, known, use_known, solves)
