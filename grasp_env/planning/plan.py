"""A grasp plan's record (:class:`Plan`, :class:`PlanStep`, :class:`BranchProbe`) and the
small questions every phase asks of a state: which bodies touch, whether a move is
admissible, whether the object is grasped."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.state import State
from grasp_env.errors import ComputationError
from grasp_env.mechanics import closure as mech
from grasp_env.simulator import Simulator

PHASES = ("pre-liftoff", "lifting", "grip adjustment")


@dataclass(frozen=True)
class PlanStep:
    """One step of a plan: the phase, the state reached and its grip objective ``y*``."""

    phase: str
    state: State
    grip: float
    note: str = ""


@dataclass
class BranchProbe:
    """One grip-adjustment step's evaluation of one four-contact branch (a record only).

    Attributes:
        step: index in ``Plan.steps`` of the state the step started from (in a
            :class:`PhaseResult`, counted from the phase's starting state).
        kept: indices into that state's contacts of the four contacts the branch keeps.
        q1: finger 1 angles at which :func:`adjust_grip` evaluated ``y*`` on the branch (the
            ``eps`` probes either way, then the trial steps), in evaluation order; only where
            the branch is valid.
        grip: ``y*`` at those angles.
        start: ``(q1, y*)`` of the state the step started from.
        chosen: ``q1`` the hand moved to along this branch; None if it did not.
    """

    step: int
    kept: tuple[int, ...]
    q1: list[float] = field(default_factory=list)
    grip: list[float] = field(default_factory=list)
    start: tuple[float, float] = (math.nan, math.nan)
    chosen: float | None = None


#: How a plan ended (:attr:`Plan.status`).
PlanStatus = Literal["form_closure", "not_tippable", "stuck", "error"]


@dataclass(frozen=True)
class PhaseResult:
    """What one phase did: the steps it went through, the state it ended in, and how it
    ended (``status`` None: the phase leaves the plan's status as it was, as grip adjustment
    does, which starts and ends in form closure).

    Attributes:
        steps: the phase's steps, in order (not its starting state).
        state: the state it ended in.
        status: how it ended, or None.
        message: a sentence on how it ended.
        grip_probes: what grip adjustment evaluated (:class:`BranchProbe`).
    """

    steps: tuple[PlanStep, ...]
    state: State
    status: PlanStatus | None
    message: str
    grip_probes: tuple[BranchProbe, ...] = ()


@dataclass
class Plan:
    """A grasp plan: its steps, how it ended, and the phase boundaries.

    Attributes:
        steps: every state the plan passed through, in order.
        status: ``"form_closure"`` (success), ``"not_tippable"`` (both tippability regions
            empty: no frictionless grasp can lift the object), ``"stuck"`` (the object is
            tippable but no placement, lifting or exploration found a grasp; ``message`` says
            why) or ``"error"``.
        message: a sentence on how the plan ended.
        placement: the pre-liftoff placement the plan starts from: ``"tippability (...)"``
            (a fingertip at a support contact, Fig. 4; ``"pivot-ranked"`` from the dense grid
            of :func:`grasp_env.planning.pivot_placements`), ``"scoop (...)"`` (both fingertips
            low at the support, :func:`grasp_env.planning.scoop_placement`) or ``"centred"``
            (the paper's fallback), followed by ``", exploratory lifting"`` where lifting
            needed palm motion.
        cpu_time: process time spent planning, seconds.
        grip_probes: what the grip adjustment evaluated (:class:`BranchProbe`, one per branch
            and step, in order); a record for plots (Fig. 14), not used by the planner.
    """

    steps: list[PlanStep] = field(default_factory=list)
    status: PlanStatus = "error"
    message: str = ""
    placement: str = ""
    cpu_time: float = 0.0
    grip_probes: list[BranchProbe] = field(default_factory=list)

    @property
    def success(self) -> bool:
        return self.status == "form_closure"

    def add(self, phase: PhaseResult) -> State:
        """Append a phase's steps and take its outcome; returns the state it ended in. The
        phase started from the plan's last step."""
        start = len(self.steps) - 1
        self.grip_probes.extend(replace(p, step=start + p.step) for p in phase.grip_probes)
        self.steps.extend(phase.steps)
        if phase.status is not None:
            self.status = phase.status
        self.message = phase.message
        return phase.state

    def phase_bounds(self) -> dict[str, tuple[int, int]]:
        """First and last step index of each phase present."""
        out: dict[str, tuple[int, int]] = {}
        for i, st in enumerate(self.steps):
            a, _ = out.get(st.phase, (i, i))
            out[st.phase] = (a, i)
        return out

    def form_closure_step(self) -> int | None:
        """Index of the first step in form closure, or None."""
        for i, st in enumerate(self.steps):
            if st.phase != "pre-liftoff" and mech.is_form_closure(st.state):
                return i
        return None


def touching_bodies(state: State) -> set[str]:
    """Names of the bodies touching the object (``"support"``, ``"palm"``, ``"finger1"``...)."""
    return {c.body for c in state.contacts}


def both_fingers_touch(state: State) -> bool:
    """Whether both fingers touch the object."""
    return {"finger1", "finger2"} <= touching_bodies(state)


def palm_distance(state: State) -> float:
    """Height of the object's centre of mass below the palmar edge, in the palm frame."""
    r = geo.rotate(state.object_pose[:2] - state.hand[:2], -state.hand[2])
    return float(-r[1])


def finger_gap(state: State) -> float:
    """Width of the opening between the fingers: the least distance between their axes (joint
    to tip), zero where they cross. Generalises the paper's fingertip distance to fingers that
    have closed past each other (the object then rests above the crossing and cannot drop)."""
    scene = state.scene
    tips = kin.fingertips_W(scene, state.hand)
    joints = kin.body_poses_W(scene, state.hand)[1:3, :2]
    return geo.segment_distance(joints[0], tips[0], joints[1], tips[1])


def try_fingers(sim: Simulator, state: State, dq: np.ndarray) -> State | None:
    """The state after finger increment ``dq`` (see :func:`try_move`)."""
    return try_move(sim, state, fingers=state.finger_angles + dq)


def try_move(sim: Simulator, state: State, **targets) -> State | None:
    """``sim.move_hand(state, **targets)``; None where the simulator cannot follow the motion
    (a jam with the object neither held nor falling): the planner refuses that increment and
    tries another instead of giving up the whole plan."""
    try:
        return sim.move_hand(state, **targets)
    except ComputationError:
        return None


def grasped(state: State) -> bool:
    """Form closure with the object off the support: the goal of lifting."""
    return not state.on_support and len(state.contacts) >= 4 and mech.is_form_closure(state)


def event_note(state: State) -> str:
    kinds = [e.kind for e in state.events if e.kind not in ("joint_limit",)]
    return ", ".join(dict.fromkeys(kinds))


def grip_if_closed(state: State) -> float:
    return mech.grip_objective(state) if mech.is_form_closure(state) else math.nan
