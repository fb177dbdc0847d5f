"""The whole plan: pre-liftoff placements in turn (the paper's, then the pivot-ranked ones of
a dense grid), lifting from each until one reaches form closure, exploratory lifting with
palm motion as the last resort (:mod:`grasp_env.planning.regrasp`), then grip adjustment."""

from __future__ import annotations

import itertools
import logging
import time
from collections import Counter
from collections.abc import Sequence

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core.state import State
from grasp_env.errors import ComputationError
from grasp_env.mechanics.tippability import support_contacts, tippability_regions
from grasp_env.planning import regrasp
from grasp_env.planning.grip import adjust_grip
from grasp_env.planning.lifting import lift, stuck_condition
from grasp_env.planning.plan import (
    PhaseResult,
    Plan,
    PlanStep,
    event_note,
    grasped,
    grip_if_closed,
    try_move,
)
from grasp_env.planning.preliftoff import (
    PALM_ANGLES,
    centred_placement,
    pivot_placements,
    scoop_placement,
    squeeze_tips,
    tipping_placement,
)
from grasp_env.simulator import Simulator

#: Progress of a plan (placements tried, exploration, grip adjustment) at INFO level.
log = logging.getLogger(__name__)

#: Budget (simulated hand moves) of the exploratory lifting with palm motion
#: (:func:`explore`), the planner's last resort.
EXPLORE_MOVES = 20000

#: What a stuck plan's message says of an object whose faces all turn up or sideways but its
#: supporting edge (:func:`has_face_turned_down`): the class of object the planner fails on.
NO_FACE_DOWN = "no face but the supporting edge faces down"


def plan_grasp(
    scene,
    sim: Simulator | None = None,
    dq: float = 0.02,
    adjust: bool = True,
    explore_moves: int = EXPLORE_MOVES,
) -> Plan:
    """Run the three phases on a scene (a Scene, bundled name, path or dict).

    When lifting fails from every placement, :func:`explore` searches for a lift with palm
    motion from the states of the attempts at the paper's placements and from the centred
    placement, within ``explore_moves`` simulated moves (0: not at all)."""
    t0 = time.process_time()
    sim = sim or Simulator(scene)
    plan = Plan()
    try:
        _plan(sim, plan, dq, adjust, explore_moves)
    except ComputationError as exc:
        plan.status, plan.message = "error", f"simulation failed: {exc}"
    plan.cpu_time = time.process_time() - t0
    return plan


def _placements(sim: Simulator, centred: State):
    """Pre-liftoff placements in the order lifting tries them, for each palm angle of
    ``PALM_ANGLES`` (parallel to the support first): the tipping placements (Fig. 4), the
    scoop (both fingertips low at the support), and with the palm parallel the centred one
    (the paper's fallback) if squeezing tips the object."""
    for th in PALM_ANGLES:
        for side in ("right", "left"):
            found = tipping_placement(sim, palm_angles=(th,), sides=(side,))
            if found is not None:
                yield found[0], f"tippability ({side} region, palm angle {th:+.1f})"
        scoop = scoop_placement(sim, th)
        if scoop is not None:
            yield scoop, f"scoop (palm angle {th:+.1f})"
        if th == 0.0 and squeeze_tips(sim, centred)[0]:
            yield centred, "centred"


def _pivot_placements(sim: Simulator):
    """The placements lifting tries when every one of :func:`_placements` gets stuck: the
    best tipping placements of a dense grid, ranked by how readily they tip the object about
    the pivot their holding finger makes (:func:`~grasp_env.planning.pivot_placements`)."""
    for state, side, th in pivot_placements(sim):
        yield state, f"tippability ({side} region, palm angle {th:+.1f}, pivot-ranked)"


def _lift_from(sim: Simulator, placements, dq: float, tried: list) -> bool:
    """Lifting from each placement in turn until one reaches form closure (the hand is
    re-placed when stuck); every attempt is appended to ``tried`` as (placement, its state,
    lifting from it). Returns whether one reached form closure."""
    for start, placement in placements:
        log.info("lifting from the %s placement", placement)
        tried.append((placement, start, lift(sim, start, dq)))
        log.info("  %s", tried[-1][2].message)
        if tried[-1][2].status == "form_closure":
            return True
    return False


def first_placement(sim: Simulator) -> tuple[State, str]:
    """The first pre-liftoff placement :func:`plan_grasp` tries, and its name: a hand set-up
    fitted to the object (palm pose and finger closing) from which squeezing tips it toward
    the palm, or the centred placement where the object has none. What a policy starting
    there still has to do is lift and hold the object."""
    centred = centred_placement(sim)
    return next(_placements(sim, centred), (centred, "centred"))


def _plan(sim: Simulator, plan: Plan, dq: float, adjust: bool, explore_moves: int) -> None:
    left, right = tippability_regions(sim.scene)
    if left.is_empty and right.is_empty:
        plan.status = "not_tippable"
        plan.message = (
            "both tippability regions are empty: the object cannot be lifted without friction"
        )
        return
    centred = centred_placement(sim)
    tried: list[tuple[str, State, PhaseResult]] = []  # placement, its state, lifting from it
    lifted = _lift_from(sim, _placements(sim, centred), dq, tried)
    # Exploration starts from these attempts only: more starts would change its seeded
    # search wherever it runs, losing grasps as well as finding others.
    seeds = tried[:]
    lifted = lifted or _lift_from(sim, _pivot_placements(sim), dq, tried)
    why = _stuck_reason(sim, tried, (left, right))
    if not lifted and explore_moves > 0:
        log.info("exploratory lifting with palm motion (up to %d moves)", explore_moves)
        leads = [_lead(start, phase) for _, start, phase in seeds] + [([centred], [])]
        names = [name for name, _, _ in seeds] + ["centred"]
        phase, _, k = explore(sim, leads, explore_moves)
        if phase.status == "form_closure":
            tried.append((f"{names[k]}, exploratory lifting", leads[k][0][0], phase))
        why += f"; {phase.message}"
    placement, start, phase = tried[-1] if tried else ("centred", centred, None)
    plan.steps = [PlanStep("pre-liftoff", start, grip_if_closed(start), placement)]
    plan.placement = placement
    state = plan.add(phase) if phase is not None else start
    if not plan.success:
        plan.status, plan.message = "stuck", why
        return
    if adjust:
        log.info("form closure at step %d; grip adjustment", len(plan.steps) - 1)
        plan.add(adjust_grip(sim, state))


def _lead(start: State, phase: PhaseResult) -> tuple[list[State], list[np.ndarray]]:
    """A lifting attempt as a path: its states from the placement on, and the hand
    increments between them."""
    states = [start, *(step.state for step in phase.steps)]
    return states, [b.hand - a.hand for a, b in itertools.pairwise(states)]


def _stuck_reason(sim: Simulator, tried: list[tuple[str, State, PhaseResult]], regions) -> str:
    """Why lifting with the palm fixed failed: how it left the object
    (:func:`~grasp_env.planning.lifting.stuck_condition`), from how many placements; with no
    placement at all, also whether the regions lie lower than the fingers are thick; and
    whether the object has a face turned down besides its supporting edge."""
    why = _placement_reason(sim, tried, regions)
    if not has_face_turned_down(sim.scene):
        why += f" ({NO_FACE_DOWN}: only a fingertip under a raised corner can push the object up)"
    return why


def has_face_turned_down(scene) -> bool:
    """Whether a face of the object at rest other than its supporting edge faces down (its
    inward normal points up): one a finger can push up on without first tipping the object."""
    v = scene.object.vertices_W0
    support = set(support_contacts(v)[0])
    up = -geo.edge_normals(v)[:, 1] > 1e-9  # unit normals: an absolute tolerance
    return any(up[i] for i in range(len(v)) if not {i, (i + 1) % len(v)} <= support)


def _placement_reason(sim: Simulator, tried, regions) -> str:
    """How lifting from the placements ended (:func:`_stuck_reason`'s first part)."""
    if not tried:
        why = (
            "no tipping placement: no fingertip placement reaches a tippability region and "
            "squeezing the centred hand does not move the object"
        )
        top = _region_top(regions)
        thick = min(f.thickness for f in sim.scene.fingers)
        if top < thick:
            why += (
                f" (the regions lie at most {top:.3g} above the support, below the fingers' "
                f"thickness, {thick:.3g})"
            )
        return why
    counts = Counter(stuck_condition(sim, phase.state) for _, _, phase in tried)
    parts = ", ".join(f"{why} ({n} of {len(tried)})" for why, n in counts.items())
    return f"fixed-palm lifting stuck from every placement: {parts}"


def _region_top(regions) -> float:
    """Height above the support of the highest point of the tippability regions."""
    heights = [max(e.start_W[1], e.end_W[1]) for region in regions for e in region.edges] + [
        region.vertices_W[v.vertex, 1] for region in regions for v in region.vertices
    ]
    return float(max(heights, default=0.0))


def explore(
    sim: Simulator,
    leads: Sequence[tuple[list[State], list[np.ndarray]]],
    max_moves: int = EXPLORE_MOVES,
    move: regrasp.Move | None = None,
) -> tuple[PhaseResult, list[np.ndarray], int]:
    """Exploratory lifting with palm motion (:mod:`grasp_env.planning.regrasp`): a seeded
    search over finger increments, palm translations and palm turns for form closure with the
    object off the support, starting from every state of the ``leads`` (paths already
    simulated: states and the hand increments between them), the whole path then shortened.

    ``move`` simulates a hand increment (default: one straight simulator move; the scripted
    policy passes the env's own step). Returns the path after its lead's first state as
    lifting steps noted ``explore`` (status ``"form_closure"``, else ``"stuck"`` and no
    steps), the path's hand increments, and the index of its lead."""
    if move is None:

        def move(st: State, dh: np.ndarray) -> State | None:
            h = st.hand + dh
            return try_move(sim, st, palm=h[:3], fingers=h[3:])

    roots = [(i, k) for i, (states, _) in enumerate(leads) for k in range(len(states))]
    found = regrasp.explore_lift(
        [leads[i][0][k] for i, k in roots], move, grasped, max_moves=max_moves
    )
    if found.states is None:
        message = f"exploratory lifting found no grasp in {found.moves} moves"
        return PhaseResult((), leads[0][0][-1], "stuck", message), [], 0
    lead, k = roots[found.root]
    states, increments = leads[lead][0][: k + 1], leads[lead][1][:k]
    walk = len(states) - 1 + len(found.states) - 1
    states, increments = regrasp.shorten(
        states + found.states[1:], increments + found.increments, move, grasped
    )
    steps = tuple(
        PlanStep(
            "lifting", st, grip_if_closed(st), ", ".join(filter(None, ("explore", event_note(st))))
        )
        for st in states[1:]
    )
    message = (
        f"form closure reached by exploratory lifting with palm motion ({found.moves} moves "
        f"searched, path of {walk} shortened to {len(states) - 1})"
    )
    return PhaseResult(steps, states[-1], "form_closure", message), increments, lead
