"""The whole plan: pre-liftoff placements in turn, lifting from each until one reaches
form closure, exploratory lifting with palm motion as the last resort
(:mod:`grasp_env.planning.regrasp`), then grip adjustment."""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from grasp_env.core.state import State
from grasp_env.errors import ComputationError
from grasp_env.mechanics.tippability import tippability_regions
from grasp_env.planning import regrasp
from grasp_env.planning.grip import adjust_grip
from grasp_env.planning.lifting import lift
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
    squeeze_tips,
    tipping_placement,
)
from grasp_env.simulator import Simulator

#: Progress of a plan (placements tried, exploration, grip adjustment) at INFO level.
log = logging.getLogger(__name__)

#: Budget (simulated hand moves) of the exploratory lifting with palm motion
#: (:func:`explore`), the planner's last resort.
EXPLORE_MOVES = 20000


def plan_grasp(
    scene,
    sim: Simulator | None = None,
    dq: float = 0.02,
    adjust: bool = True,
    explore_moves: int = EXPLORE_MOVES,
) -> Plan:
    """Run the three phases on a scene (a Scene, bundled name, path or dict).

    When lifting fails from every placement, :func:`explore` searches for a lift with palm
    motion from the centred placement, within ``explore_moves`` simulated moves (0: not at
    all)."""
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
    """Pre-liftoff placements in the order lifting tries them: the tipping placements (Fig. 4)
    with the palm parallel to the support, the centred one (the paper's fallback) if squeezing
    tips the object, then tipping placements with the palm tilted by ``PALM_ANGLES``."""
    for th in PALM_ANGLES:
        for side in ("right", "left"):
            found = tipping_placement(sim, palm_angles=(th,), sides=(side,))
            if found is not None:
                yield found[0], f"tippability ({side} region, palm angle {th:+.1f})"
        if th == 0.0 and squeeze_tips(sim, centred)[0]:
            yield centred, "centred"


def _plan(sim: Simulator, plan: Plan, dq: float, adjust: bool, explore_moves: int) -> None:
    left, right = tippability_regions(sim.scene)
    if left.is_empty and right.is_empty:
        plan.status = "not_tippable"
        plan.message = (
            "both tippability regions are empty: the object cannot be lifted without friction"
        )
        return
    centred = centred_placement(sim)
    tries = 0
    failed = []
    for state, placement in _placements(sim, centred):  # re-place the hand when stuck
        tries += 1
        log.info("lifting from the %s placement", placement)
        plan.steps = [PlanStep("pre-liftoff", state, grip_if_closed(state), placement)]
        plan.placement = placement
        state = plan.add(lift(sim, state, dq))
        if plan.success:
            break
        log.info("  %s", plan.message)
        failed.append(f"from the {placement} placement: {plan.message}")
    if tries == 0:
        plan.steps = [PlanStep("pre-liftoff", centred, math.nan, "not tippable")]
        plan.status = "not_tippable"
        plan.message = "no tipping placement: squeezing the centred hand does not move the object"
        return
    if not plan.success and explore_moves > 0:
        log.info("exploratory lifting with palm motion (up to %d moves)", explore_moves)
        plan.steps = [PlanStep("pre-liftoff", centred, grip_if_closed(centred), "centred")]
        plan.placement = "centred, exploratory lifting"
        phase, _ = explore(sim, ([centred], []), explore_moves)
        state = plan.add(phase)
        if not plan.success:
            failed.append(plan.message)
    if not plan.success:
        plan.message = "; ".join(failed)
        return
    if failed:
        plan.message += f" (after re-placement; {'; '.join(failed)})"
    if adjust:
        log.info("form closure at step %d; grip adjustment", len(plan.steps) - 1)
        plan.add(adjust_grip(sim, state))


def explore(
    sim: Simulator,
    lead: tuple[list[State], list[np.ndarray]],
    max_moves: int = EXPLORE_MOVES,
    move: regrasp.Move | None = None,
) -> tuple[PhaseResult, list[np.ndarray]]:
    """Exploratory lifting with palm motion (:mod:`grasp_env.regrasp`): a seeded search over
    finger increments, palm translations and palm turns for form closure with the object off
    the support, from the last state of ``lead`` (states and the hand increments between
    them), the whole path then shortened.

    ``move`` simulates a hand increment (default: one straight simulator move; the scripted
    policy passes the env's own step). Returns the path after ``lead``'s first state as
    lifting steps noted ``explore`` (status ``"form_closure"``, else ``"stuck"`` and no
    steps), and the path's hand increments."""
    if move is None:

        def move(st: State, dh: np.ndarray) -> State | None:
            h = st.hand + dh
            return try_move(sim, st, palm=h[:3], fingers=h[3:])

    states, increments = lead
    found = regrasp.explore_lift(states[-1], move, grasped, max_moves=max_moves)
    if found.states is None:
        message = f"exploratory lifting found no grasp in {found.moves} moves"
        return PhaseResult((), states[-1], "stuck", message), []
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
    return PhaseResult(steps, states[-1], "form_closure", message), increments
