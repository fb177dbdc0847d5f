"""The increment loop of a move: plan -> solve -> check -> locate -> update, as small compiled
functions around one record of the move's state (:class:`MoveState`).

Each increment

1. **plans** the active set ``E`` and the least-motion object twist ``v``
   (:func:`grasp_env.sim.motion.plan`), or finds a jam or a fall (:func:`_plan`);
2. **solves** for the object pose at the step's end on ``E`` and **checks** it: no
   penetration, overlap, contact past an edge's end or negative force (:func:`_solve`);
3. **locates** otherwise the first event to ``tol`` (:func:`grasp_env.sim.increment.locate`);
4. **updates** the state: the step is accepted (:func:`_accept`), the move goes on from the
   event (:func:`_moved`), or an event right at the current point changes the plan there
   (:func:`_event_here`); where nothing consistent lies ahead the object falls or the hand
   jams.

The record carries the pose ``q`` and path parameter ``s``; a plan :class:`Kept` for the
next increment (``carry``: ``E`` fixes the pose and holds it, so it stays valid;
``override``: a plan with a touching contact forced in or a lost one released); and what is
known about the current point (:class:`Here`), cleared whenever ``s`` moves on. Events that
recur within a hair of each other more than :data:`CHATTER` times are treated as happening
here (chatter, :class:`Run`).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.errors import SimulationError, WorkLimitError
from grasp_env.sim import contact_sets, motion
from grasp_env.sim.equilibrium import ROUNDING, determined, held, held_or_wedged
from grasp_env.sim.events import (
    EDGE_TO_TIP,
    JAM,
    LOST_CONTACT,
    NEW_CONTACT,
    NO_CHECK,
    TIP_TO_EDGE,
)  # fmt: skip
from grasp_env.sim.fall import fall_if_moved, fall_if_unheld, nudge_and_fall, touching
from grasp_env.sim.increment import locate, sweep_limit, try_step
from grasp_env.sim.placement import place

#: Chatter guard: an event (a contact lost, a jam) located more than CHATTER times in a row,
#: each time less than CHATTER_DS of the move after the last, is treated as happening at the
#: current point (a lost contact is dropped from the active set, a jam stops the hand)
#: instead of creeping on.
CHATTER = 3
CHATTER_DS = 1e-4
#: A move whose path parameter stays within CHATTER_DS for more than STALL increments (events
#: cycling at one point, e.g. a contact lost and found again and again) cannot be followed.
STALL = 200

#: A plan kept for the next increment: none, ``carry`` (an accepted step's active set, which
#: fixes the pose and holds it) or ``override`` (a contact forced in or released here).
KEEP_NONE, KEEP_CARRY, KEEP_OVERRIDE = 0, 1, 2

Kept = namedtuple("Kept", "kind E v")
Kept.__doc__ = "A plan kept for the next increment: ``KEEP_*``, active set and twist."
Here = namedtuple("Here", "banned forced losing losing_E losing_v")
Here.__doc__ = """What is known about the current point: contacts ``banned`` from the
active set (events that recur at once), contacts ``forced`` in, and (when ``losing``) the plan
dropped for a lost contact."""
Run = namedtuple("Run", "kind keys count mark_s mark_it")
Run.__doc__ = """The chatter and stall guards: the event located last, how many times in a
row it came within CHATTER_DS of the last, and where (``mark_s``, at increment ``mark_it``)
``s`` last moved on by more than CHATTER_DS."""
MoveState = namedtuple("MoveState", "q s keys use_known kept here stuck_fall run")
MoveState.__doc__ = """The state of a move between increments: pose ``q``, path parameter
``s``, the touching contacts ``keys`` (the caller's while ``use_known``, for the first plan),
the :class:`Kept` plan, :class:`Here`, whether a fall just found no way down
(``stuck_fall``: plan without falling) and the :class:`Run` guards."""


@njit(cache=CACHE)
def _nothing_kept() -> Kept:
    return Kept(KEEP_NONE, contact_sets.empty(), np.zeros(3))


@njit(cache=CACHE)
def _nothing_here() -> Here:
    none = contact_sets.empty()
    return Here(none, none, False, none, np.zeros(3))


@njit(cache=CACHE)
def _at(ms: MoveState, q: np.ndarray) -> MoveState:
    """``ms`` with the object at ``q`` (a fall), the same point of the path."""
    return MoveState(q, ms.s, ms.keys, ms.use_known, ms.kept, ms.here, ms.stuck_fall, ms.run)


@njit(cache=CACHE)
def _moved(ms: MoveState, q: np.ndarray, s: float) -> MoveState:
    """``ms`` at a new point of the path: what was known about the old one is cleared."""
    return MoveState(q, s, ms.keys, ms.use_known, ms.kept, _nothing_here(), ms.stuck_fall, ms.run)


@njit(cache=CACHE)
def advance(model, q, h0, dh, s_end, known, use_known, events, solves):
    """Follow the move ``h0 + s dh`` from ``s = 0`` to ``s_end``, logging to ``events``:
    ``(q, s, jammed, events)``. ``known`` are the contacts touching at the start when
    ``use_known`` (else they are detected)."""
    # Events closer than tol along the hand's path count as here (no progress).
    reach = np.abs(dh[:2]).sum() + np.abs(dh[2:]).sum() * 2.0 * model.half
    s_eps = max(1e-13, model.tol / reach)
    none = contact_sets.empty()
    run = Run(NO_CHECK, none, 0, 0.0, 0)
    ms = MoveState(q, 0.0, known, use_known, _nothing_kept(), _nothing_here(), False, run)
    for it in range(model.max_iterations):
        ms = _progress(ms, it)
        h = h0 + ms.s * dh
        # 1. plan
        outcome, E, v, kept, ms = _plan(model, ms, h, dh)
        if outcome == motion.JAM:
            ms, jammed = _cannot_move(model, ms, h, h0, dh, s_end, events, solves)
            if jammed:
                return ms.q, ms.s, True, events
            continue
        if outcome == motion.FALL:
            q_new, moved = fall_if_moved(model, ms.q, h, ms.s, events, solves)
            ms = MoveState(q_new, ms.s, ms.keys, ms.use_known, ms.kept, ms.here, not moved, ms.run)
            continue
        if ms.s >= s_end - 1e-15:
            return ms.q, s_end, False, events
        # 2-3. solve and check
        ok, q_new, ds, kind, key, value = _solve(
            model, ms, E, v, kept == KEEP_CARRY, h, h0, dh, s_end, solves
        )
        if ok:
            # 5. update: the step is accepted
            ms = _accept(model, ms, q_new, ds, E, h0, dh)
            continue
        # 4. locate the first event
        s_star, q_star, event, event_keys = locate(
            model, ms.q, ms.s, ms.s + ds, E, v, h0, dh, kind, key, value, solves
        )
        ms = _count(ms, s_star, event, event_keys)
        if s_star - ms.s >= s_eps and ms.run.count <= CHATTER:
            # 5. update: the move goes on from the event. A fold located ahead is logged as
            # a jam only where the hand stops at it (below, or in _cannot_move): the move
            # may still go on from there.
            if event != JAM:
                events.append((event, s_star, event_keys))
            ms = _moved(ms, q_star, s_star)
            continue
        # The event sits right here.
        ms, replanned, E = _event_here(
            model, ms, event, event_keys, E, v, kept == KEEP_OVERRIDE, h0, dh, s_end, events,
            solves,
        )  # fmt: skip
        if replanned:
            continue
        # Nothing consistent lies just ahead: the active contacts' equations fold (their
        # normals turn concurrent and the forces needed grow without bound) or no contact can
        # be released. The hand cannot move on: a jam -- unless the contacts left cannot hold
        # the object, which then falls first.
        h = h0 + ms.s * dh
        q_new, fell = fall_if_unheld(model, ms.q, h, ms.s, events, solves)
        if fell:
            ms = _moved(ms, q_new, ms.s)
            continue
        events.append((JAM, ms.s, E))
        stop_at_jam(model, ms.q, h, ms.s)
        return ms.q, ms.s, True, events
    raise WorkLimitError("no progress after", model.max_iterations, "increments, at s =", ms.s)


@njit(cache=CACHE)
def _progress(ms: MoveState, it: int) -> MoveState:
    """The stall guard: marks where ``s`` moved on; raises after STALL increments without."""
    run = ms.run
    if ms.s > run.mark_s + CHATTER_DS:
        run = Run(run.kind, run.keys, run.count, ms.s, it)
        return MoveState(ms.q, ms.s, ms.keys, ms.use_known, ms.kept, ms.here, ms.stuck_fall, run)
    if it - run.mark_it > STALL:
        raise WorkLimitError("no progress after", STALL, "increments near s =", ms.s)
    return ms


@njit(cache=CACHE)
def _plan(model, ms: MoveState, h: np.ndarray, dh: np.ndarray):
    """Step 1: the kept plan if there is one, else the plan of the contacts touching here
    (none of the banned ones): ``(outcome, E, v, kept kind, ms)``, the kept plan used up."""
    kept = ms.kept
    keys, use_known = ms.keys, ms.use_known
    if kept.kind != KEEP_NONE:
        outcome, E, v = motion.MOVE, kept.E, kept.v
    else:
        world = place(model, ms.q, h)
        if use_known:
            use_known = False
        else:
            keys = touching(model, world, ms.here.banned)
        outcome, E, v = motion.plan(model, world, ms.q, h, dh, keys, not ms.stuck_fall)
    ms = MoveState(ms.q, ms.s, keys, use_known, _nothing_kept(), ms.here, False, ms.run)
    return outcome, E, v, kept.kind, ms


@njit(cache=CACHE)
def _cannot_move(model, ms: MoveState, h, h0, dh, s_end, events, solves):
    """A plan found no motion (an infeasible velocity LP): ``(ms, jammed)``. Past a boundary
    of equilibrium the object falls; an object the touching contacts cannot hold falls;
    otherwise the hand jams here."""
    here = ms.here
    if here.losing:
        # Contacts dropped for a negative force leave the object unheld just ahead: past
        # the boundary of equilibrium it falls.
        s_new, q_new, found = nudge_and_fall(
            model, ms.q, ms.s, here.losing_E, here.losing_v, h0, dh, s_end, events, solves
        )
        if found:
            return _moved(ms, q_new, s_new), False
    world = place(model, ms.q, h)
    keys = touching(model, world, contact_sets.empty())
    if not held(model, world, ms.q[:2], keys, model.ftol, ROUNDING) and held_or_wedged(
        model, world, ms.q[:2], keys, model.ftol, ROUNDING
    ):
        # Wedged at second order: the hand may still move on where it leaves the object
        # where it is, and release it (a fall) past where the contacts stop holding it.
        s_new, q_new, found = nudge_and_fall(
            model, ms.q, ms.s, contact_sets.empty(), np.zeros(3), h0, dh, s_end, events, solves,
            True,
        )  # fmt: skip
        if found:
            return _moved(ms, q_new, s_new), False
    q_new, fell = fall_if_unheld(model, ms.q, h, ms.s, events, solves)
    if fell:
        return _at(ms, q_new), False
    events.append((JAM, ms.s, ms.keys))
    stop_at_jam(model, ms.q, h, ms.s)
    return ms, True


@njit(cache=CACHE)
def _solve(model, ms: MoveState, E, v, carried: bool, h, h0, dh, s_end: float, solves):
    """Steps 2-3: the pose at the step's end, checked: ``(ok, q, ds, kind, key, value)``
    (:func:`grasp_env.sim.increment.try_step`). The step is at most ``max_step`` and the sweep
    limit; where ``E`` fixes the pose as a function of ``s`` and holds it with positive forces
    (carried, or :func:`grasp_env.sim.equilibrium.determined`), it stays the active set until
    an event and the pose needs no integration, so one step may go to the sweep limit (the
    check locates any event in it)."""
    rest = sweep_limit(model, ms.q, h, dh, v, E, s_end - ms.s)
    ds = min(model.max_step, rest)
    if ds < rest and (carried or determined(model, place(model, ms.q, h), ms.q, E)):
        ok, q_new, kind, key, value = try_step(model, ms.q, ms.s, rest, E, v, h0, dh, True, solves)
        if ok or kind != JAM:
            return ok, q_new, rest, kind, key, value
    ok, q_new, kind, key, value = try_step(model, ms.q, ms.s, ds, E, v, h0, dh, False, solves)
    return ok, q_new, ds, kind, key, value


@njit(cache=CACHE)
def _accept(model, ms: MoveState, q_new: np.ndarray, ds: float, E, h0, dh) -> MoveState:
    """Step 5 after an accepted step: the move goes on from its end, carrying ``E`` where it
    fixes the pose there."""
    s_new = ms.s + ds
    kept = _nothing_kept()
    if determined(model, place(model, q_new, h0 + s_new * dh), q_new, E):
        kept = Kept(KEEP_CARRY, E, (q_new - ms.q) / ds)
    return MoveState(
        q_new, s_new, ms.keys, ms.use_known, kept, _nothing_here(), ms.stuck_fall, ms.run
    )


@njit(cache=CACHE)
def _count(ms: MoveState, s_star: float, event: int, event_keys: np.ndarray) -> MoveState:
    """The chatter count after locating ``event`` at ``s_star``."""
    run = ms.run
    near = s_star - ms.s < CHATTER_DS
    if near and event == run.kind and contact_sets.equal(event_keys, run.keys):
        count = run.count + 1
    else:
        count = 1 if near else 0
    run = Run(event, event_keys, count, run.mark_s, run.mark_it)
    return MoveState(ms.q, ms.s, ms.keys, ms.use_known, ms.kept, ms.here, ms.stuck_fall, run)


@njit(cache=CACHE)
def _event_here(model, ms, event, event_keys, E, v, overridden, h0, dh, s_end, events, solves):
    """An event at the current point changes the plan here: ``(ms, replanned, E)``;
    ``replanned`` False when nothing consistent lies ahead, with ``E`` the plan that could
    not go on."""
    here = ms.here
    has_key = event_keys.shape[0] > 0
    key = event_keys[0] if has_key else contact_sets.NONE
    if has_key and (event == EDGE_TO_TIP or event == TIP_TO_EDGE or event == LOST_CONTACT):
        if contact_sets.index(here.banned, key) < 0:
            # The offending contact cannot stay active here: plan without it.
            banned = contact_sets.with_key(here.banned, key)
            kept = ms.kept
            here = Here(banned, here.forced, here.losing, here.losing_E, here.losing_v)
            if event == LOST_CONTACT:
                # Its force reached zero: the others hold the object right there, so the
                # motion goes on with them (the old plan's velocity as Newton's predictor);
                # the old plan is kept in case releasing fails too.
                here = Here(banned, here.forced, True, E, v)
                released = contact_sets.without(E, key)
                if released.shape[0] > 0:
                    kept = Kept(KEEP_OVERRIDE, released, v)
            ms = MoveState(ms.q, ms.s, ms.keys, ms.use_known, kept, here, ms.stuck_fall, ms.run)
            return ms, True, E
    if overridden:
        return ms, True, E  # the forced plan could not go on: plan afresh
    reverted = False
    if event == NEW_CONTACT and has_key and contact_sets.index(E, key) < 0:
        is_banned = contact_sets.index(here.banned, key) >= 0
        if is_banned and here.losing:
            # Keeping the contact makes its force negative, dropping it lets the object into
            # it: the object sits at an equilibrium that the hand's motion destroys (a
            # potential maximum along the other contacts' family).
            E, v, reverted = here.losing_E, here.losing_v, True
        elif not is_banned and contact_sets.index(here.forced, key) < 0:
            # A touching contact the plan left open (zero force, not tight at the least-norm
            # velocity) closes at once: the object held by the others is pushed into it, so
            # it joins the active set. The plan's velocity keeps every touching contact
            # closed (V v >= xi).
            now = touching(model, place(model, ms.q, h0 + ms.s * dh), contact_sets.empty())
            if contact_sets.index(now, key) >= 0:
                forced = contact_sets.with_key(here.forced, key)
                here = Here(here.banned, forced, here.losing, here.losing_E, here.losing_v)
                kept = Kept(KEEP_OVERRIDE, contact_sets.with_key(E, key), v)
                ms = MoveState(ms.q, ms.s, ms.keys, ms.use_known, kept, here, ms.stuck_fall, ms.run)
                return ms, True, E
    if event == LOST_CONTACT or reverted:
        # The object sits on the boundary of equilibrium: just ahead, no contact set holds
        # it. Nudge the hand past the boundary and let the object fall.
        s_new, q_new, found = nudge_and_fall(model, ms.q, ms.s, E, v, h0, dh, s_end, events, solves)
        if found:
            return _moved(ms, q_new, s_new), True, E
    return ms, False, E


@njit(cache=CACHE)
def stop_at_jam(model, q: np.ndarray, h: np.ndarray, s: float) -> None:
    """The hand stops at a jam; the object must be held there (at a fold by forces without
    bound, balanced to their rounding, or wedged at second order). A jam whose object is
    neither held nor able to fall is a failure, not a state."""
    world = place(model, q, h)
    keys = touching(model, world, contact_sets.empty())
    if not held_or_wedged(model, world, q[:2], keys, model.ftol, ROUNDING):
        raise SimulationError("jam at s =", s, "with the object neither held nor falling")
