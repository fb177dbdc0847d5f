"""The paper's three-phase grasp planner (section 3.2): pre-liftoff, lifting, grip adjustment.

The planner drives the :class:`~grasp_env.simulator.Simulator` with hand increments and
records every step (:class:`PlanStep`). It assumes exact knowledge of the scene, as the paper
does. Phases:

1. **Pre-liftoff.** From the tippability regions (section 2.4): no region, no plan. Else look
   for a hand placement, palm parallel to the support, with one fingertip at a support
   contact and the other finger touching the object inside the matching region (Fig. 4).
   Also centre the palm over the object, parallel to the support and just above the longer
   finger's reach of it, close the fingers until they touch, and decide by the velocity LP
   whether squeezing tips the object (and which support contact breaks). Lifting starts from
   the tipping placement if there is one, and starts again from the centred one (a
   re-placement) if it gets stuck.
2. **Lifting.** Finger increments with the palm fixed, simulated after every increment: the
   paper's equal-rate squeeze while it makes progress toward the palm, else the best of a few
   alternatives (one finger, rolling, letting go a little), until form closure with the
   object off the support. Once the gap between the fingers (:func:`finger_gap`) is narrower
   than the object with the object off the support it stays so (Toussaint's no-drop
   argument); an increment the simulator cannot follow is refused; a constrained fall is
   recovered by lifting on from where the object came to rest.
3. **Grip adjustment.** Keep four contacts, treat ``q1`` as the independent variable, solve
   ``q2`` and the object pose from the four contact equations (eq. 28), and step along the
   finite-difference gradient of ``y*`` (eq. 37). At a five-contact configuration every
   four-contact branch that keeps form closure is evaluated and the best continued; stop at a
   local minimum of ``y*``.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from grasp_env import contacts as ct
from grasp_env import geometry as geo
from grasp_env import kinematics as kin
from grasp_env import mechanics as mech
from grasp_env import regrasp
from grasp_env.errors import SolverError
from grasp_env.simulator import SimulationError, Simulator
from grasp_env.state import State
from grasp_env.tippability import tippability_regions
from grasp_env.width import object_width

#: Progress of a plan (placements tried, exploration, grip adjustment) at INFO level.
log = logging.getLogger(__name__)

PHASES = ("pre-liftoff", "lifting", "grip adjustment")

#: Gap between the hanging tip of the longer finger and the support in the centred
#: pre-liftoff placement, in palm widths (the paper's "just high enough so that the longer
#: finger could not touch the support").
PALM_CLEARANCE = 0.01
#: Finger step of the pre-liftoff closing motion (rad); the first touch is then located
#: exactly from the simulator's events, so the step only changes the cost.
PRELIFTOFF_STEP = 0.1
#: Palm angles (rad) of the tipping placements, in the order lifting tries them: the paper's
#: palm parallel to the support first, then tilted ever more (a tilted palm reaches further
#: under objects with parallel or undercut sides).
PALM_ANGLES = (0.0, -0.2, 0.2, -0.4, 0.4, -0.6, 0.6)
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
#: Budget (simulated hand moves) of the exploratory lifting with palm motion
#: (:func:`explore`), the planner's last resort.
EXPLORE_MOVES = 20000


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
        step: index in ``Plan.steps`` of the state the step started from.
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


@dataclass
class Plan:
    """A grasp plan: its steps, how it ended, and the phase boundaries.

    Attributes:
        steps: every state the plan passed through, in order.
        status: ``"form_closure"`` (success), ``"not_tippable"`` (empty tippability regions or
            no tipping placement), ``"stuck"`` (lifting found no useful increment) or
            ``"error"``.
        message: a sentence on how the plan ended.
        placement: ``"tippability"`` (a fingertip at a support contact, Fig. 4) or
            ``"centred"`` (the paper's fallback).
        cpu_time: process time spent planning, seconds.
        grip_probes: what the grip adjustment evaluated (:class:`BranchProbe`, one per branch
            and step, in order); a record for plots (Fig. 14), not used by the planner.
    """

    steps: list[PlanStep] = field(default_factory=list)
    status: str = "error"
    message: str = ""
    placement: str = ""
    cpu_time: float = 0.0
    grip_probes: list[BranchProbe] = field(default_factory=list)

    @property
    def success(self) -> bool:
        return self.status == "form_closure"

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


def _first_touch(scene, h: np.ndarray, finger: int, q_obj: np.ndarray, tol: float) -> float | None:
    """Angle at which finger ``finger`` (1 or 2), closing from its open limit with the rest of
    the hand fixed, first touches the object; None if it never does within its limits."""
    lo_lim, hi_lim = scene.fingers[finger - 1].limits
    obj = geo.transform(q_obj, scene.object.vertices_B)

    def depth(q: float) -> float:
        hh = h.copy()
        hh[2 + finger] = q
        return geo.penetration_depth(kin.hand_polygons_W(scene, hh)[finger], obj)

    # finger 1 closes as q1 increases, finger 2 as q2 decreases
    grid = np.linspace(lo_lim, hi_lim, 91) if finger == 1 else np.linspace(hi_lim, lo_lim, 91)
    if depth(grid[0]) > 0:
        return None
    for a, b in itertools.pairwise(grid):
        if depth(b) > 0:
            for _ in range(80):
                m = 0.5 * (a + b)
                if depth(m) > 0:
                    b = m
                else:
                    a = m
                if abs(b - a) < 1e-14:
                    break
            return a if depth(a) >= -tol else None
    return None


def tipping_placement(
    sim: Simulator, palm_angles=(0.0,), n_q: int = 24, sides=("right", "left")
) -> tuple[State, str] | None:
    """Pre-liftoff search for the paper's Fig. 4 placement.

    For each tippability region (right: finger 2's tip at the right support contact, finger 1
    in the right region; left: the mirror), each palm angle and each angle of the holding
    finger, the holding fingertip is put on the support contact, the other finger closes until
    it touches, and the placement is kept if that contact lies in the region, the hand is
    clear of the support and the object, and the joints are within limits. Among the valid
    placements the one whose contact has the largest moment arm about the support contact
    (the easiest to tip) is returned, with the side; None if there is none. ``sides``
    restricts the search to some regions.
    """
    scene = sim.scene
    q_obj = scene.object.start_pose.copy()
    left, right = tippability_regions(scene)
    tol = sim.tol
    best = None
    for side, region in (("right", right), ("left", left)):
        if region.is_empty or side not in sides:
            continue
        hold = 2 if side == "right" else 1  # finger whose tip sits on the support contact
        move = 3 - hold
        p_C = region.contact_W
        side_up = _side_direction(scene, p_C, hold)
        lim = scene.fingers[hold - 1].limits
        for th in palm_angles:
            for q_hold in np.linspace(lim[0], lim[1], n_q)[1:-1]:
                u = np.array([math.cos(th + q_hold), math.sin(th + q_hold)])
                J = p_C - scene.fingers[hold - 1].length * u
                jx = scene.palm.width / 2 if hold == 2 else -scene.palm.width / 2
                o = J - geo.rotate(np.array([jx, 0.0]), th)
                h = np.array([o[0], o[1], th, -math.pi / 2, -math.pi / 2])
                h[2 + hold] = q_hold
                h[2 + move] = scene.fingers[move - 1].limits[0 if move == 1 else 1]
                # The finger's body pokes below its tip: slide the hand up the object's side.
                low = min(p[:, 1].min() for p in kin.hand_polygons_W(scene, h))
                if low < 0.0:
                    h[:2] += (-low + tol) / side_up[1] * side_up
                q_move = _first_touch(scene, h, move, q_obj, tol)
                if q_move is None:
                    continue
                h[2 + move] = q_move
                if kin.hand_placement_problem(scene, q_obj, h, 10 * tol) is not None:
                    continue
                try:
                    state = sim.settle(q_obj, h)
                except (SimulationError, SolverError):
                    continue
                if np.abs(state.object_pose - q_obj).max() > 1e-9:
                    continue
                finger = f"finger{move}"
                touch = [c for c in state.contacts if c.body == finger]
                if not touch or not all(region.contains(c.point, c.normal, 1e-7) for c in touch):
                    continue
                arm = max(abs(float(geo.cross2(c.point - p_C, c.normal))) for c in touch)
                if best is None or arm > best[0]:
                    best = (arm, state, side)
    return None if best is None else (best[1], best[2])


def _side_direction(scene, p_C: np.ndarray, hold: int) -> np.ndarray:
    """Unit direction up the object's side from the support contact ``p_C``: along the edge
    that leaves ``p_C`` upwards on finger ``hold``'s side (finger 2: the right side)."""
    v = scene.object.vertices_W0
    k = int(np.argmin(np.linalg.norm(v - p_C, axis=1)))
    other = v[(k + 1) % len(v)] if hold == 2 else v[k - 1]
    d = other - v[k]
    return d / np.linalg.norm(d)


def centred_hand(scene, object_vertices_W: np.ndarray | None = None) -> np.ndarray:
    """The paper's centred pre-liftoff hand: palm over the object's centroid, parallel to the
    support, ``PALM_CLEARANCE`` palm widths above the longer finger's reach of the support
    (higher if the object is taller), fingers hanging straight down.

    Args:
        scene: the scene (its hand and, unless given, its object).
        object_vertices_W: the object's vertices ``(n, 2)`` in the world; default the scene's.

    Returns:
        Hand configuration ``(x_p, y_p, theta_p, q1, q2)``, shape (5,).
    """
    v = scene.object.vertices_W0 if object_vertices_W is None else object_vertices_W
    reach = max(max(f.length for f in scene.fingers), float(v[:, 1].max()))
    q = np.clip(np.full(2, -0.5 * math.pi), scene.joint_limits[:, 0], scene.joint_limits[:, 1])
    x = float(geo.polygon_centroid(v)[0])
    return np.array([x, reach + PALM_CLEARANCE * scene.palm.width, 0.0, q[0], q[1]])


def centred_placement(sim: Simulator, step: float = PRELIFTOFF_STEP) -> State:
    """The paper's fallback pre-liftoff placement: the palm at :func:`centred_hand`, the
    fingers closed at equal rates until each touches the object (:func:`close_until_touch`)."""
    scene = sim.scene
    state = sim.settle(scene.object.start_pose.copy(), centred_hand(scene))
    return close_until_touch(sim, state, step)


def both_fingers_touch(state: State) -> bool:
    """Whether both fingers touch the object."""
    return {"finger1", "finger2"} <= touching_bodies(state)


def close_until_touch(sim: Simulator, state: State, step: float = PRELIFTOFF_STEP) -> State:
    """Close both fingers at equal rates until each has touched the object or they jam.

    The fingers move in steps of ``step`` rad; a finger that touches stops there (its first
    touch located exactly from the simulator's ``new_contact`` event) while the other closes
    on. Stops too when both fingers are at their closing limits or the hand is blocked.
    """
    lim = sim.scene.joint_limits
    closing = np.array([1.0, -1.0])  # finger 1 closes as q1 grows, finger 2 as q2 falls
    for _ in range(int(4 * math.pi / step) + 4):
        done = [f"finger{i + 1}" in touching_bodies(state) for i in range(2)]
        if all(done) or state.jammed or state.hand_blocked:
            break
        q = state.finger_angles
        target = q.copy()
        for i in range(2):
            if not done[i]:
                target[i] = np.clip(q[i] + closing[i] * step, lim[i, 0], lim[i, 1])
        if np.array_equal(target, q):
            break
        new = sim.move_hand(state, fingers=target)
        touch = [
            e.s
            for e in new.events
            if e.kind == "new_contact"
            and any(k[0] in (geo.FINGER1, geo.FINGER2) for k in e.contacts)
        ]
        if touch and min(touch) < 1.0:
            new = sim.move_hand(state, fingers=q + min(touch) * (target - q))
        state = new
    return state


def squeeze_tips(sim: Simulator, state: State, dq: float = 1e-3) -> tuple[bool, list[int]]:
    """Whether squeezing the fingers at equal rates moves the object (the velocity LP, eqs.
    19-21, has a solution with nonzero velocity), and which support contacts break at the
    onset (zero dual value in the force LP), as indices into ``state.contacts``."""
    p, n, b = state.contact_arrays()
    dh = np.array([0.0, 0.0, 0.0, dq, -dq])
    V = mech.V_ob(p, n, state.object_pose[:2])
    xi = mech.xi(sim.scene, state.hand, dh, b, p, n)
    res = mech.motion_lp(V, xi, sim.scene.object_weight)
    if res.status != "optimal":
        return False, []
    moves = np.abs(res.velocity).max() > 1e-9 * sim.size
    weight = sim.scene.object_weight
    broken = [
        i
        for i, (c, f) in enumerate(zip(state.contacts, res.forces, strict=True))
        if c.body == "support" and f <= 1e-9 * weight
    ]
    return bool(moves), broken


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


def lift(sim: Simulator, state: State, plan: Plan, dq: float = 0.02, max_steps: int = 300) -> State:
    """Lifting phase: finger increments that move the object toward the palm, until form
    closure with the object off the support. The palm stays fixed, as in the paper.

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
    width = object_width(sim.scene)
    squeeze = np.array([dq, -dq])
    moves = [np.array(m) * dq for m in ALTERNATIVES]
    record, since_record = palm_distance(state), 0
    lifted = not state.on_support
    for _ in range(max_steps):
        if _grasped(state):
            plan.status, plan.message = "form_closure", "form closure reached"
            return state

        chosen = None
        nxt = _try_fingers(sim, state, squeeze)
        if _admissible(nxt, state, lifted, width) and (
            _score(nxt) < record - PROGRESS_TOL * sim.size
            or (not nxt.jammed and since_record < PATIENCE)
        ):
            chosen = [nxt]
        else:
            best = None
            for m in moves:
                a = _try_fingers(sim, state, m)
                if not _admissible(a, state, lifted, width):
                    continue
                seq = [a]
                if min(m[0], -m[1]) < 0 and not _grasped(a):  # a release: squeeze after
                    b = _try_fingers(sim, a, squeeze)
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
            plan.status = "stuck"
            plan.message = "no lifting increment brings the object closer to the palm"
            return state
        for state in chosen:
            lifted = lifted or not state.on_support
            plan.steps.append(
                PlanStep("lifting", state, _grip_if_closed(state), _event_note(state))
            )
        if palm_distance(state) < record - PROGRESS_TOL * sim.size:
            record, since_record = palm_distance(state), 0
        else:
            since_record += 1
    plan.status, plan.message = "stuck", f"no form closure after {max_steps} lifting steps"
    return state


def _try_fingers(sim: Simulator, state: State, dq: np.ndarray) -> State | None:
    """The state after finger increment ``dq`` (see :func:`_try_move`)."""
    return _try_move(sim, state, fingers=state.finger_angles + dq)


def _try_move(sim: Simulator, state: State, **targets) -> State | None:
    """``sim.move_hand(state, **targets)``; None where the simulator cannot follow the motion
    (a jam with the object neither held nor falling): the planner refuses that increment and
    tries another instead of giving up the whole plan."""
    try:
        return sim.move_hand(state, **targets)
    except (SimulationError, SolverError):
        return None


def _admissible(nxt: State | None, prev: State, lifted: bool, width: float) -> bool:
    """The simulator followed the increment, the hand moved, the object was not dropped, and
    once the finger gap is narrower than the object's width with the object off the support it
    stays so (unless the grasp closed)."""
    if nxt is None or np.abs(nxt.hand - prev.hand).max() <= 1e-12:
        return False
    if (lifted or not prev.on_support) and nxt.on_support:
        return False
    opened = finger_gap(prev) < width <= finger_gap(nxt)
    return _grasped(nxt) or nxt.on_support or not opened


def _score(state: State) -> float:
    """Lifting progress measure (lower is better): the object's distance below the palm."""
    return -math.inf if _grasped(state) else palm_distance(state)


def _grasped(state: State) -> bool:
    """Form closure with the object off the support: the goal of lifting."""
    return not state.on_support and len(state.contacts) >= 4 and mech.is_form_closure(state)


def _event_note(state: State) -> str:
    kinds = [e.kind for e in state.events if e.kind not in ("joint_limit",)]
    return ", ".join(dict.fromkeys(kinds))


def _grip_if_closed(state: State) -> float:
    return mech.grip_objective(state) if mech.is_form_closure(state) else math.nan


# ---------------------------------------------------------------------- grip adjustment
class FourContactBranch:
    """The one-parameter family of configurations keeping four contacts (eq. 28).

    With the palm fixed and ``q1`` given, the unknowns ``z = (x, y, theta, q2)`` solve the four
    contacts' gap equations by Newton's method. The Jacobian is exact: the object columns are
    ``V_ob``'s rows, and ``d gap / d q2 = -(r x n)`` for a contact on finger 2 (``r`` from its
    joint), zero otherwise.
    """

    def __init__(
        self, sim: Simulator, keys: list, hand: np.ndarray, kept: tuple[int, ...] = ()
    ) -> None:
        self.sim, self.keys, self.hand = sim, list(keys), hand.copy()
        self.kept = tuple(kept)  # indices of the keys among the contacts it was built from

    def solve(self, q1: float, z0: np.ndarray) -> np.ndarray | None:
        sim, z = self.sim, z0.copy()
        scale = np.array([1.0, 1.0, 1.0 / sim.rho, 1.0 / sim.size])
        for _ in range(40):
            h = self.config(q1, z)
            pl = ct.Placement(sim.scene, z[:3], h)
            F = np.empty(4)
            J = np.zeros((4, 4))
            joint2 = kin.body_poses_W(sim.scene, h)[2, :2]
            for i, key in enumerate(self.keys):
                p, n, F[i], _, _ = pl.evaluate(key)
                J[i, :3] = mech.V_ob(p[None], n[None], z[:2])[0]
                if key[0] == geo.FINGER2:
                    J[i, 3] = -float(geo.cross2(p - joint2, n))
            if np.abs(F).max() <= sim.newton_tol:
                return z
            try:
                dz = np.linalg.solve(J * scale, -F) * scale
            except np.linalg.LinAlgError:
                return None
            z = z + dz
            if not np.all(np.isfinite(z)) or np.abs(dz).max() > 1.0:
                return None
        return None

    def config(self, q1: float, z: np.ndarray) -> np.ndarray:
        h = self.hand.copy()
        h[3], h[4] = q1, z[3]
        return h

    def state(self, q1: float, z: np.ndarray) -> State | None:
        """The state at ``(q1, z)`` if it is valid: no penetration beyond the four contacts,
        every contact on its edge, joints within limits, form closure; else None."""
        sim = self.sim
        h = self.config(q1, z)
        lim = sim.scene.joint_limits
        if np.any(h[3:] < lim[:, 0] - 1e-12) or np.any(h[3:] > lim[:, 1] + 1e-12):
            return None
        if min(p[:, 1].min() for p in kin.hand_polygons_W(sim.scene, h)) < -sim.tol:
            return None
        pl = ct.Placement(sim.scene, z[:3], h)
        gap, _ = ct.min_gap(pl, {ct.vertex_of(k) for k in self.keys})
        if gap < -sim.tol:
            return None
        contacts = []
        for key in self.keys:
            p, n, g, t, L = pl.evaluate(key)
            if np.isfinite(L) and (t < -sim.tol / L or t > 1 + sim.tol / L):
                return None
            contacts.append(
                ct.Contact(
                    geo.BODY_NAMES[key[0]],
                    ct.KIND_NAMES[key[1]],
                    p.copy(),
                    n.copy(),
                    0.0,
                    key[2],
                    key[3],
                    float(g),
                )
            )
        st = State(sim.scene, z[:3].copy(), h, tuple(contacts))
        return st if mech.is_form_closure(st) else None

    def grip(self, q1: float, z0: np.ndarray) -> tuple[float, np.ndarray | None]:
        z = self.solve(q1, z0)
        if z is None:
            return math.inf, None
        st = self.state(q1, z)
        return (mech.grip_objective(st), z) if st is not None else (math.inf, None)


def _branches(sim: Simulator, state: State) -> list[FourContactBranch]:
    """Four-contact subsets of the state's contacts that keep form closure."""
    keys = [c.key for c in state.contacts]
    out = []
    for sub in itertools.combinations(range(len(keys)), 4):
        trial = State(
            state.scene, state.object_pose, state.hand, tuple(state.contacts[i] for i in sub)
        )
        if mech.is_form_closure(trial):
            out.append(FourContactBranch(sim, [keys[i] for i in sub], state.hand, sub))
    return out


def adjust_grip(
    sim: Simulator,
    state: State,
    plan: Plan,
    eps: float = 1e-4,
    alpha: float = 1.0,
    max_dq: float = 0.02,
    max_steps: int = 200,
) -> State:
    """Grip-adjustment phase: descend ``y*`` along the four-contact branches (eq. 37).

    Each step takes ``q1 <- q1 - alpha (dy*/dq1) / W`` (``W`` the object's weight; a
    difference over ``eps`` in each direction), its size clipped to ``[eps, max_dq]`` and
    halved until ``y*`` falls below its value at the ``eps`` step (which is taken otherwise).
    At a five-contact configuration every four-contact branch that keeps form closure is
    evaluated in both directions and the best one continues. The hand goes to the new
    configuration by one simulated straight-line move, or two through a via point where the
    branch curves away from the chord (:func:`_follow_branch`; the via step, noted ``"via"``,
    may leave form closure for a moment), kept if the grasp ends closed off the support and
    ``y*`` falls (the plan then replays exactly). Stops when no branch lowers ``y*`` at a
    step of ``eps`` either way, or no such move keeps the grasp (the plan's message says
    which). Every ``y*`` it evaluates on a branch is recorded in ``plan.grip_probes`` (for
    plots; the decisions do not read it).
    """
    y = mech.grip_objective(state)
    z = np.array([*state.object_pose, state.hand[4]])
    q1 = float(state.hand[3])
    weight = sim.scene.object_weight
    for _ in range(max_steps):
        candidates = []
        probes = {}
        for br in _branches(sim, state):
            probe = probes[id(br)] = BranchProbe(len(plan.steps) - 1, br.kept, start=(q1, y))
            plan.grip_probes.append(probe)
            # the branch is usable only in directions where it stays valid and y* falls
            for sign in (1.0, -1.0):
                y_nb, z_nb = br.grip(q1 + sign * eps, z)
                _record(probe, q1 + sign * eps, y_nb, z_nb)
                if z_nb is None or y_nb >= y:
                    continue
                grad = (y_nb - y) / (sign * eps)
                step = sign * float(np.clip(alpha * abs(grad) / weight, eps, max_dq))
                found = (y_nb, q1 + sign * eps, z_nb)  # the eps step is known to descend
                while abs(step) > eps:
                    y_new, z_new = br.grip(q1 + step, z)
                    _record(probe, q1 + step, y_new, z_new)
                    if z_new is not None and y_new < y_nb:
                        found = (y_new, q1 + step, z_new)
                        break
                    step *= 0.5
                candidates.append((*found, br))
        # The hand reaches the chosen configuration by simulated straight-line moves (so that
        # the plan replays through the simulator and the env); keep them only if the grasp
        # ends closed off the support with y* lower.
        for _, q1_new, z_new, br in sorted(candidates, key=lambda c: c[0]):
            moves, y_moved = _follow_branch(sim, state, br.config(q1_new, z_new), y)
            if moves:
                probes[id(br)].chosen = q1_new
                break
        else:
            plan.message = (
                "form closure reached; y* falls along a four-contact branch, but the hand "
                "cannot follow it"
                if candidates
                else "form closure reached; y* at a local minimum"
            )
            return state
        for via in moves[:-1]:
            plan.steps.append(PlanStep("grip adjustment", via, _grip_if_closed(via), "via"))
        state, y = moves[-1], y_moved
        z, q1 = np.array([*state.object_pose, state.hand[4]]), float(state.hand[3])
        plan.steps.append(PlanStep("grip adjustment", state, y, _event_note(state)))
    plan.message = f"grip adjustment stopped after {max_steps} steps"
    return state


def _record(probe: BranchProbe, q1: float, y: float, z: np.ndarray | None) -> None:
    """Add an evaluation of ``y*`` on a branch to ``probe`` if the branch was valid there."""
    if z is not None:
        probe.q1.append(float(q1))
        probe.grip.append(float(y))


def _follow_branch(
    sim: Simulator, state: State, target: np.ndarray, y: float
) -> tuple[list[State], float]:
    """States of simulated moves from ``state`` to ``target`` (a configuration on a
    four-contact branch) ending closed off the support with ``y*`` below ``y``, and that
    ``y*``; ``([], inf)`` if there are none.

    One straight-line move first. Where the branch curves away from that chord, the chord
    leaves the hand configurations in which the object fits (the first move jams at once):
    then through a via point, the chord's middle with one finger opened by the step of
    finger 1 (finger 1 first), from which the hand closes onto the branch again.
    """
    direct = _try_move(sim, state, palm=target[:3], fingers=target[3:])
    if (y_new := _closed_grip(direct)) < y:
        return [direct], y_new
    step = abs(float(target[3] - state.hand[3]))
    for opening in ((-step, 0.0), (0.0, step)):  # finger 1 opens as q1 falls, 2 as q2 rises
        mid = 0.5 * (state.hand + target)
        mid[3:] += opening
        via = _try_move(sim, state, palm=mid[:3], fingers=mid[3:])
        if via is None or via.on_support:
            continue
        end = _try_move(sim, via, palm=target[:3], fingers=target[3:])
        if (y_new := _closed_grip(end)) < y:
            return [via, end], y_new
    return [], math.inf


def _closed_grip(state: State | None) -> float:
    """``y*`` of a grasp closed off the support; inf for anything else."""
    return mech.grip_objective(state) if state is not None and _grasped(state) else math.inf


def grip_curves(sim: Simulator, state: State, half_width: float = 0.15, n: int = 61) -> list[dict]:
    """``y*`` against ``q1`` along every four-contact branch through ``state`` (like Fig. 14).

    Returns one dict per four-contact subset of the state's contacts: the contacts kept, the
    dropped ones, whether the subset is in form closure, and the ``(q1, y*)`` samples where the
    branch is valid (traced by continuation from the state in both directions).
    """
    out = []
    keys = [c.key for c in state.contacts]
    q1_0 = float(state.hand[3])
    for sub in itertools.combinations(range(len(keys)), min(4, len(keys))):
        br = FourContactBranch(sim, [keys[i] for i in sub], state.hand, sub)
        trial = State(
            state.scene, state.object_pose, state.hand, tuple(state.contacts[i] for i in sub)
        )
        closed = mech.is_form_closure(trial)
        pts = []
        for sign in (1.0, -1.0):
            z = np.array([*state.object_pose, state.hand[4]])
            for q1 in q1_0 + sign * np.linspace(0.0, half_width, n // 2 + 1):
                y, z_new = br.grip(q1, z)
                if z_new is None:
                    break
                z = z_new
                pts.append((float(q1), float(y)))
        pts = sorted(set(pts))
        out.append(
            {
                "kept": sub,
                "dropped": tuple(i for i in range(len(keys)) if i not in sub),
                "form_closure": closed,
                "q1": [p[0] for p in pts],
                "grip": [p[1] for p in pts],
            }
        )
    return out


# ---------------------------------------------------------------------- the whole plan
#: Finger openings (rad) from the placement's finger angles tried by :func:`approach_path`
#: for the final descent, and the margin (palm widths) it keeps from the object in transit.
#: A negative opening closes the finger further: the tip of a finger turned inward past the
#: vertical rises, where opening it would swing the tip down into the support.
APPROACH_OPENINGS = (0.3, 0.6, 0.15, 1.0, 0.0, -0.3, -0.6)
#: Which fingers are opened by those amounts for the descent: both, or one alone (a finger
#: whose tip rests on the support at the target, turned past the vertical, would swing its
#: tip into the support if opened).
APPROACH_OPEN_FINGERS = (np.array([1.0, 1.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]))
APPROACH_MARGIN = 0.02
#: Path resolution of the clearance check, in palm widths and radians.
APPROACH_RESOLUTION = 0.005


def _segment_clear(scene, a: np.ndarray, b: np.ndarray, q_obj: np.ndarray, tol: float) -> bool:
    """The hand moving in a straight line from ``a`` to ``b`` (hand configurations) keeps
    clear of the object and the support (up to ``tol``) at every checked sample."""
    d = b - a
    w = scene.palm.width
    span = max(float(np.abs(d[:2]).max()) / w, float(np.abs(d[2:]).max()) * 0.5)
    n = max(1, math.ceil(span / APPROACH_RESOLUTION))
    return all(
        kin.hand_placement_problem(scene, q_obj, a + (k / n) * d, tol) is None
        for k in range(1, n + 1)
    )


def approach_path(sim: Simulator, state: State, target: np.ndarray) -> list[np.ndarray] | None:
    """A collision-free hand path from ``state`` (object resting at its pose) to the
    pre-liftoff hand ``target``, as hand configurations reached by straight-line moves.

    The fingers open to their limits, the palm rises clear of the object, moves and turns to
    above the target with the fingers opened a little from the target's, descends to the
    target palm pose, and the fingers close to the target angles (:func:`_approach_paths`
    lists the variants, simplest first). The first path that the clearance check and then
    the simulator find free (the object does not move and the hand reaches ``target``) is
    returned, without the start configuration; None if there is none.
    """
    q_obj = state.object_pose
    tol = 1e-6 * sim.size
    tried = set()
    for path in _approach_paths(sim.scene, state.hand, target, q_obj, tol):
        path = [h for i, h in enumerate(path) if i == 0 or np.any(h != path[i - 1])]
        key = np.concatenate(path).tobytes()
        if key in tried:
            continue
        tried.add(key)
        if _path_clear(sim.scene, state.hand, path, q_obj, tol) and _path_moves_nothing(
            sim, state, path
        ):
            return path
    return None


def _approach_paths(scene, start: np.ndarray, target: np.ndarray, q_obj: np.ndarray, tol: float):
    """Candidate approach paths (possibly repeated). First the simple ones: both fingers
    opened by each of ``APPROACH_OPENINGS`` (>= 0), descending along the world vertical or the
    target palm's normal straight onto the target palm pose. Then the refined ones: one finger
    opened alone or closed further, the palm also descending along a finger's axis towards its
    tip (a fingertip slides into a corner under an overhang), opened fingers that would dip
    into the support or the object at the target palm pose opened a little higher up (closing
    as the palm comes down), and the fingers closed once the palm is above the target rather
    than on the way."""
    w = scene.palm.width
    lim = scene.joint_limits
    top = float(geo.transform(q_obj, scene.object.vertices_B)[:, 1].max()) + APPROACH_MARGIN * w
    opened = start.copy()
    opened[3] = lim[0, 0] + 0.05
    opened[4] = lim[1, 1] - 0.05
    th = float(target[2])
    both = APPROACH_OPEN_FINGERS[0]
    simple = [(d, both) for d in APPROACH_OPENINGS if d >= 0.0]
    refined = [
        (d, which)
        for d, which in itertools.product(APPROACH_OPENINGS, APPROACH_OPEN_FINGERS)
        if d != 0.0 or which is both  # nothing opened: one candidate
    ]
    for is_refined, combos in ((False, simple), (True, refined)):
        for delta, which in combos:
            low = target.copy()
            low[3:] = np.clip(target[3:] + delta * np.array([-1.0, 1.0]) * which, *lim.T)
            directions = [np.array([0.0, 1.0]), np.array([-math.sin(th), math.cos(th)])]
            if is_refined:
                axes = kin.body_poses_W(scene, low)[1:3, :2] - kin.fingertips_W(scene, low)
                directions += [a / np.linalg.norm(a) for a in axes if a[1] > 0.0]
            for direction in directions:
                near = low
                if is_refined:
                    near = _slide(low, direction, 0.5 * w, 0.01 * w, _clear_of(scene, q_obj, tol))
                above = _slide(low, direction, 3.0 * w, 0.02 * w, _above(scene, top))
                if near is None or above is None:
                    continue
                raised = opened.copy()
                raised[1] = max(above[1], opened[1])
                yield [opened, raised, above, near, target.copy()]
                if not is_refined:
                    continue
                # close the fingers above the target, raised until their sweep is clear
                sweep_clear = _sweep_clear(scene, opened[3:], q_obj, tol)
                closed = _slide(above, direction, 3.0 * w, 0.05 * w, sweep_clear)
                if closed is not None:
                    lifted = raised.copy()
                    lifted[1] = max(raised[1], closed[1])
                    still_open = np.r_[closed[:3], opened[3:]]
                    yield [opened, lifted, still_open, closed, near, target.copy()]


def _slide(h: np.ndarray, direction: np.ndarray, length: float, step: float, accept):
    """The first configuration ``h`` with the palm moved along ``direction`` by a multiple of
    ``step`` (0 first, below ``length``) that ``accept`` takes; None if there is none."""
    for s in np.arange(0.0, length, step):
        moved = h.copy()
        moved[:2] += s * direction
        if accept(moved):
            return moved
    return None


def _clear_of(scene, q_obj: np.ndarray, tol: float):
    return lambda h: kin.hand_placement_problem(scene, q_obj, h, tol) is None


def _sweep_clear(scene, opened_fingers: np.ndarray, q_obj: np.ndarray, tol: float):
    """Whether the fingers close clear from ``opened_fingers`` to ``h``'s angles, the palm
    at ``h``."""
    return lambda h: _segment_clear(scene, np.r_[h[:3], opened_fingers], h, q_obj, 10 * tol)


def _above(scene, height: float):
    return lambda h: min(p[:, 1].min() for p in kin.hand_polygons_W(scene, h)) > height


def _path_clear(scene, start: np.ndarray, path: list, q_obj: np.ndarray, tol: float) -> bool:
    """Every straight segment of ``path`` from ``start`` passes the clearance check (the
    last, onto the target, with the tight tolerance: the target touches the object)."""
    a = start
    for b in path:
        if not _segment_clear(scene, a, b, q_obj, tol if b is path[-1] else 10 * tol):
            return False
        a = b
    return True


def _path_moves_nothing(sim: Simulator, state: State, path: list[np.ndarray]) -> bool:
    start = state
    try:
        for h in path:
            state = sim.move_hand(state, palm=h[:3], fingers=h[3:])
    except (SimulationError, SolverError):
        return False
    return bool(
        np.abs(state.hand - path[-1]).max() < 1e-9 * sim.size
        and np.abs(state.object_pose - start.object_pose).max() < 1e-9 * sim.size
    )


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
    except (SimulationError, SolverError) as exc:
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
        plan.steps = [PlanStep("pre-liftoff", state, _grip_if_closed(state), placement)]
        plan.placement = placement
        state = lift(sim, state, plan, dq)
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
        plan.steps = [PlanStep("pre-liftoff", centred, _grip_if_closed(centred), "centred")]
        plan.placement = "centred, exploratory lifting"
        state, _ = explore(sim, plan, ([centred], []), explore_moves)
        if not plan.success:
            failed.append(plan.message)
    if not plan.success:
        plan.message = "; ".join(failed)
        return
    if failed:
        plan.message += f" (after re-placement; {'; '.join(failed)})"
    if adjust:
        log.info("form closure at step %d; grip adjustment", len(plan.steps) - 1)
        adjust_grip(sim, state, plan)


def explore(
    sim: Simulator,
    plan: Plan,
    lead: tuple[list[State], list[np.ndarray]],
    max_moves: int = EXPLORE_MOVES,
    move: regrasp.Move | None = None,
) -> tuple[State, list[np.ndarray]]:
    """Exploratory lifting with palm motion (:mod:`grasp_env.regrasp`): a seeded search over
    finger increments, palm translations and palm turns for form closure with the object off
    the support, from the last state of ``lead`` (states and the hand increments between
    them), the whole path then shortened.

    ``move`` simulates a hand increment (default: one straight simulator move; the scripted
    policy passes the env's own step). Appends the path after ``lead``'s first state to
    ``plan`` as lifting steps noted ``explore`` and sets its status; returns the last state
    and the path's hand increments."""
    if move is None:

        def move(st: State, dh: np.ndarray) -> State | None:
            h = st.hand + dh
            return _try_move(sim, st, palm=h[:3], fingers=h[3:])

    states, increments = lead
    found = regrasp.explore_lift(states[-1], move, _grasped, max_moves=max_moves)
    if found.states is None:
        plan.status = "stuck"
        plan.message = f"exploratory lifting found no grasp in {found.moves} moves"
        return states[-1], []
    walk = len(states) - 1 + len(found.states) - 1
    states, increments = regrasp.shorten(
        states + found.states[1:], increments + found.increments, move, _grasped
    )
    for st in states[1:]:
        note = ", ".join(filter(None, ("explore", _event_note(st))))
        plan.steps.append(PlanStep("lifting", st, _grip_if_closed(st), note))
    plan.status = "form_closure"
    plan.message = (
        f"form closure reached by exploratory lifting with palm motion ({found.moves} moves "
        f"searched, path of {walk} shortened to {len(states) - 1})"
    )
    return states[-1], increments
