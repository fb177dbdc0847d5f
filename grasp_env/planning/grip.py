"""Grip adjustment: descend the grip objective ``y*`` along the four-contact branches of
the grasp (eqs. 28 and 37), and the branch curves for plots (Fig. 14)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.state import KIND_NAMES, Contact, ContactKey, State
from grasp_env.mechanics import closure as mech
from grasp_env.mechanics import contacts as ct
from grasp_env.planning.plan import (
    BranchProbe,
    PhaseResult,
    PlanStep,
    event_note,
    grasped,
    grip_if_closed,
    try_move,
)
from grasp_env.simulator import Simulator


class FourContactBranch:
    """The one-parameter family of configurations keeping four contacts (eq. 28).

    With the palm fixed and ``q1`` given, the unknowns ``z = (x, y, theta, q2)`` solve the four
    contacts' gap equations by Newton's method. The Jacobian is exact: the object columns are
    ``V_ob``'s rows, and ``d gap / d q2 = -(r x n)`` for a contact on finger 2 (``r`` from its
    joint), zero otherwise.
    """

    def __init__(
        self, sim: Simulator, keys: list[ContactKey], hand: np.ndarray, kept: tuple[int, ...] = ()
    ) -> None:
        self.sim, self.hand = sim, hand.copy()
        self.keys = [ContactKey(*k) for k in keys]
        self.kept = tuple(kept)  # indices of the keys among the contacts it was built from

    def solve(self, q1: float, z0: np.ndarray) -> np.ndarray | None:
        sim, z = self.sim, z0.copy()
        scale = np.array([1.0, 1.0, 1.0 / sim.model.rho, 1.0 / sim.size])
        unit = kin.hand_units(sim.scene)[[0, 1, 2, 4]]  # (x, y) in palm widths, angles in rad
        for _ in range(40):
            h = self.config(q1, z)
            pl = ct.Placement(sim.scene, z[:3], h)
            F = np.empty(4)
            J = np.zeros((4, 4))
            joint2 = kin.body_poses_W(sim.scene, h)[2, :2]
            for i, key in enumerate(self.keys):
                p, n, F[i], _, _ = pl.evaluate(key)
                J[i, :3] = mech.V_ob(p[None], n[None], z[:2])[0]
                if key.body == geo.FINGER2:
                    J[i, 3] = -float(geo.cross2(p - joint2, n))
            if np.abs(F).max() <= sim.model.newton_tol:
                return z
            try:
                dz = np.linalg.solve(J * scale, -F) * scale
            except np.linalg.LinAlgError:
                return None
            z = z + dz
            if not np.all(np.isfinite(z)) or np.abs(dz / unit).max() > 1.0:
                return None  # diverging: a step over a palm width or a radian
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
                Contact(
                    geo.BODY_NAMES[key.body],
                    KIND_NAMES[key.kind],
                    p.copy(),
                    n.copy(),
                    0.0,
                    key.object_feature,
                    key.hand_feature,
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
    eps: float = 1e-4,
    alpha: float = 1.0,
    max_dq: float = 0.02,
    max_steps: int = 200,
) -> PhaseResult:
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
    which). Every ``y*`` it evaluates on a branch is recorded in the result's
    ``grip_probes`` (for plots; the decisions do not read it), each with ``step`` counted
    from the phase's starting state (:meth:`Plan.add` makes it an index into the plan).
    """
    steps: list[PlanStep] = []
    all_probes: list[BranchProbe] = []
    y = mech.grip_objective(state)
    z = np.array([*state.object_pose, state.hand[4]])
    q1 = float(state.hand[3])
    weight = sim.scene.object_weight
    for _ in range(max_steps):
        candidates = []
        probes = {}
        for br in _branches(sim, state):
            probe = probes[id(br)] = BranchProbe(len(steps), br.kept, start=(q1, y))
            all_probes.append(probe)
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
            message = (
                "form closure reached; y* falls along a four-contact branch, but the hand "
                "cannot follow it"
                if candidates
                else "form closure reached; y* at a local minimum"
            )
            return PhaseResult(tuple(steps), state, None, message, tuple(all_probes))
        for via in moves[:-1]:
            steps.append(PlanStep("grip adjustment", via, grip_if_closed(via), "via"))
        state, y = moves[-1], y_moved
        z, q1 = np.array([*state.object_pose, state.hand[4]]), float(state.hand[3])
        steps.append(PlanStep("grip adjustment", state, y, event_note(state)))
    message = f"grip adjustment stopped after {max_steps} steps"
    return PhaseResult(tuple(steps), state, None, message, tuple(all_probes))


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
    direct = try_move(sim, state, palm=target[:3], fingers=target[3:])
    if (y_new := _closed_grip(direct)) < y:
        return [direct], y_new
    step = abs(float(target[3] - state.hand[3]))
    for opening in ((-step, 0.0), (0.0, step)):  # finger 1 opens as q1 falls, 2 as q2 rises
        mid = 0.5 * (state.hand + target)
        mid[3:] += opening
        via = try_move(sim, state, palm=mid[:3], fingers=mid[3:])
        if via is None or via.on_support:
            continue
        end = try_move(sim, via, palm=target[:3], fingers=target[3:])
        if (y_new := _closed_grip(end)) < y:
            return [via, end], y_new
    return [], math.inf


def _closed_grip(state: State | None) -> float:
    """``y*`` of a grasp closed off the support; inf for anything else."""
    return mech.grip_objective(state) if state is not None and grasped(state) else math.inf


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
