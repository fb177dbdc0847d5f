"""Lifting: finger increments with the palm fixed, simulated after each, until form
closure with the object off the support (the equal-rate squeeze while it makes progress,
else the best of a few alternatives)."""

from __future__ import annotations

import math

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.state import State
from grasp_env.mechanics.width import object_width
from grasp_env.planning.plan import (
    PhaseResult,
    PlanStep,
    event_note,
    finger_gap,
    grasped,
    grip_if_closed,
    palm_distance,
    try_fingers,
)
from grasp_env.simulator import Simulator

#: Lifting alternatives to the equal-rate squeeze, as multiples of the finger step
#: ``(dq1, dq2)`` (finger 1 closes as q1 grows, finger 2 as q2 falls).
ALTERNATIVES = (
    (1.0, -0.5),
    (0.5, -1.0),
    (1.0, 0.0),
    (0.0, -1.0),
    (1.0, 1.0),
    (-1.0, -1.0),
    (0.5, 0.5),
    (-0.5, -0.5),
    (-0.5, 0.0),
    (0.0, 0.5),
)

#: Squeezes in a row allowed without bringing the object closer to the palm than before.
PATIENCE = 5

#: Least decrease of the object's distance to the palm that counts as lifting progress,
#: relative to the object's size.
PROGRESS_TOL = 5e-3


def lift(sim: Simulator, state: State, dq: float = 0.02, max_steps: int = 300) -> PhaseResult:
    """Lifting phase: finger increments that move the object toward the palm, until form
    closure with the object off the support (status ``"form_closure"``, else ``"stuck"``).
    The palm stays fixed, as in the paper.

    Every step first tries the paper's squeeze, both fingers closing at equal rates by ``dq``.
    It is taken unless it jams the hand or has not brought the object closer to the palm than
    ever before (:func:`palm_distance`) for ``PATIENCE`` steps. Then the alternatives are
    simulated: one finger leading or alone, both fingers turning the same way (rolling the
    object past a fold where the squeeze wedges it), half-size increments, and a finger
    letting go a little followed by a squeeze (out of a wedge); the best is taken; after
    ``PATIENCE`` steps without a new record only a record is, so the phase cannot cycle. An
    increment is refused if it drops the object (back onto the support after it left) or,
    with the object off the support, opens the gap between the fingers (:func:`finger_gap`,
    the fingertip distance ``d`` of section 3.2 while the fingers have not crossed) from
    narrower than the object's width to wider (Toussaint's no-drop condition: while ``d < w``
    it cannot drop), or if the simulator cannot follow it.
    """
    steps: list[PlanStep] = []
    width = object_width(sim.scene)
    squeeze = np.array([dq, -dq])
    moves = [np.array(m) * dq for m in ALTERNATIVES]
    record, since_record = palm_distance(state), 0
    lifted = not state.on_support
    for _ in range(max_steps):
        if grasped(state):
            return PhaseResult(tuple(steps), state, "form_closure", "form closure reached")

        chosen = None
        nxt = try_fingers(sim, state, squeeze)
        if _admissible(nxt, state, lifted, width) and (
            _score(nxt) < record - PROGRESS_TOL * sim.size
            or (not nxt.jammed and since_record < PATIENCE)
        ):
            chosen = [nxt]
        else:
            best = None
            for m in moves:
                a = try_fingers(sim, state, m)
                if not _admissible(a, state, lifted, width):
                    continue
                seq = [a]
                if min(m[0], -m[1]) < 0 and not grasped(a):  # a release: squeeze after
                    b = try_fingers(sim, a, squeeze)
                    if _admissible(b, a, lifted, width) and _score(b) < _score(a):
                        seq.append(b)
                s = _score(seq[-1])
                if best is None or s < best[0]:
                    best = (s, seq)
                    if s == -math.inf:
                        break
            if best is not None and (
                best[0] < record - PROGRESS_TOL * sim.size or since_record < PATIENCE
            ):
                chosen = best[1]
        if chosen is None:
            message = (
                "no lifting increment brings the object closer to the palm: "
                f"{stuck_condition(sim, state)}"
            )
            return PhaseResult(tuple(steps), state, "stuck", message)
        for state in chosen:
            lifted = lifted or not state.on_support
            steps.append(PlanStep("lifting", state, grip_if_closed(state), event_note(state)))
        if palm_distance(state) < record - PROGRESS_TOL * sim.size:
            record, since_record = palm_distance(state), 0
        else:
            since_record += 1
    message = f"no form closure after {max_steps} lifting steps"
    return PhaseResult(tuple(steps), state, "stuck", message)


def stuck_condition(sim: Simulator, state: State) -> str:
    """How a stuck lifting attempt left the object: off the support without form closure,
    tipped over onto another face, wedged (the hand jams), tilted on one support vertex, or
    resting on its face."""
    if not state.on_support:
        return "the object is off the support, not in form closure"
    low = geo.transform(state.object_pose, sim.scene.object.vertices_B)[:, 1] <= sim.tol
    start = sim.scene.object.vertices_W0[:, 1] <= sim.tol
    if np.any(low & ~start):
        return "the object has tipped over onto another face"
    if state.jammed:
        return "the hand wedges the object"
    if np.count_nonzero(low) == 1:
        return "the object leans on one support vertex"
    return "the object rests on its face"


def _admissible(nxt: State | None, prev: State, lifted: bool, width: float) -> bool:
    """The simulator followed the increment, the hand moved, the object was not dropped, and
    once the finger gap is narrower than the object's width with the object off the support it
    stays so (unless the grasp closed)."""
    if nxt is None or np.abs((nxt.hand - prev.hand) / kin.hand_units(prev.scene)).max() <= 1e-12:
        return False
    if (lifted or not prev.on_support) and nxt.on_support:
        return False
    opened = finger_gap(prev) < width <= finger_gap(nxt)
    return grasped(nxt) or nxt.on_support or not opened


def _score(state: State) -> float:
    """Lifting progress measure (lower is better): the object's distance below the palm."""
    return -math.inf if grasped(state) else palm_distance(state)
