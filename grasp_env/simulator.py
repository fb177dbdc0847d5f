"""Quasi-static frictionless simulator: the paper's active-set method (section 3.1).

For a straight-line hand move ``h(s) = h0 + s (h1 - h0)``, ``s`` in [0, 1], the object moves so
as to minimise its potential energy without interpenetration (eqs. 19-24). Per increment:

1. **Active set.** The velocity LP (eqs. 19-21) and the force LP (eqs. 22-24) at the current
   configuration give the object velocity and the contact forces. The contacts with positive
   force, plus any touching contact the hand pushes on (tight at the least-motion optimal
   velocity), form the active set ``E``: by complementary slackness they stay closed.
2. **Newton.** The active contacts' gap equations ``phi_E(q, h(s)) = 0`` (edge and tip contacts
   of the appendix, eqs. A.8, A.10, A.12, A.15, written in vector form in
   :mod:`grasp_env.contacts`) are solved for the object pose ``q`` with Newton's method and the
   exact Jacobian ``V_ob`` (the gap gradient; least-motion steps when ``E`` leaves freedom).
3. **Consistency.** The step is accepted if no other vertex penetrates a body, no active
   contact slides off the end of its edge, and the active contacts still hold the object with
   non-negative forces. Otherwise the first event is located by bisection on ``s`` to
   ``contact_tol``; the motion stops there, the contacts are updated and the move continues.

Infeasible velocity LP: the hand cannot move on (a jam); the hand stops there. Unbounded
velocity LP: the object falls along the steepest admissible descent of its potential energy
(gravity projected onto the admissible cone in the mass metric) until contacts hold it.
"""

from __future__ import annotations

import copy
import itertools
import math

import numpy as np

from grasp_env import contacts as ct
from grasp_env import geometry as geo
from grasp_env import kinematics as kin
from grasp_env import mechanics as mech
from grasp_env import qp
from grasp_env.errors import SolverError
from grasp_env.scene import Scene, load_scene
from grasp_env.sim import consistency, dense, placement, pose
from grasp_env.state import Event, State
from grasp_env.width import object_width

#: Accepted ``contact_tol`` (relative to the palm width), ``[lo, hi)``: below ``lo`` the
#: contacts' own rounding (located events, Newton's residual, flush edges) is no longer small
#: against the tolerance.
CONTACT_TOL_RANGE = (1e-11, 1e-2)
#: Largest contact force, in object weights, that counts as holding the object.
MAX_FORCE = 1e6
#: Chatter guard: an event (a contact lost, a jam) located more than CHATTER times in a row,
#: each time less than CHATTER_DS of the move after the last, is treated as happening at the
#: current point (a lost contact is dropped from the active set, a jam stops the hand)
#: instead of creeping on.
CHATTER = 3
CHATTER_DS = 1e-4
#: A move whose path parameter stays within CHATTER_DS for more than STALL increments (events
#: cycling at one point, e.g. a contact lost and found again and again) cannot be followed:
#: it raises SimulationError at once, as it would after ``max_iterations``.
STALL = 200


class SimulationError(RuntimeError):
    """The simulator could not continue (a solve failed even on the fallbacks)."""


class WorkLimitError(SimulationError):
    """A move needed more work than its budget (``max_solves`` pose solves, ``max_iterations``
    increments, or ``STALL`` increments without progress): it cannot be followed in bounded
    time. Deterministic, so it is not retried."""


class Simulator:
    """Quasi-static frictionless grasp simulator for one scene.

    Args:
        scene: a :class:`~grasp_env.scene.Scene`, bundled name, path or dict.
        contact_tol: gap below which bodies touch, relative to the palm width (default 1e-9,
            at least 1e-11).
            No returned state penetrates deeper; events are located to within it.
        max_step: largest increment of the path parameter ``s`` between consistency checks
            along a move, as a fraction of the move (default 0.25). Smaller steps cost time;
            they matter for moves whose active set leaves the object free directions.
        fall_step: largest object displacement of one step of a fall, relative to the object's
            size (default 0.02).
        max_iterations: safety cap on increments per move (default 10000).
        max_solves: cap on pose solves (Newton runs) per call of :meth:`move_hand` or
            :meth:`settle`, the retry included (default 5000). A move that needs more
            raises :class:`WorkLimitError`; it bounds the time of any one call.
        lp_solver: ``"fast"`` (exact basis enumeration, :mod:`grasp_env.fastlp`) or ``"highs"``
            (the reference path through scipy's HiGHS) for the motion LP.
    """

    def __init__(
        self,
        scene: Scene | str | dict,
        contact_tol: float = 1e-9,
        max_step: float = 0.25,
        fall_step: float = 0.02,
        max_iterations: int = 10000,
        max_solves: int = 5000,
        lp_solver: str = "fast",
    ) -> None:
        self.scene = load_scene(scene)
        if lp_solver not in ("fast", "highs"):
            raise ValueError(f"lp_solver must be 'fast' or 'highs', got {lp_solver!r}")
        self.lp_solver = lp_solver
        lo, hi = CONTACT_TOL_RANGE
        if isinstance(contact_tol, bool) or not (
            isinstance(contact_tol, float | int) and lo <= contact_tol < hi
        ):
            raise ValueError(f"contact_tol must be in [{lo:g}, {hi:g}), got {contact_tol!r}")
        if not (isinstance(max_step, float | int) and 0 < max_step <= 1):
            raise ValueError(f"max_step must be in (0, 1], got {max_step!r}")
        if not (isinstance(fall_step, float | int) and 0 < fall_step <= 1):
            raise ValueError(f"fall_step must be in (0, 1], got {fall_step!r}")
        L = self.scene.palm.width
        self.tol = float(contact_tol) * L
        self.max_step = float(max_step)
        self.max_iterations = int(max_iterations)
        if isinstance(max_solves, bool) or not (isinstance(max_solves, int) and max_solves > 0):
            raise ValueError(f"max_solves must be a positive int, got {max_solves!r}")
        self.max_solves = max_solves
        self._solves = [0]  # pose solves of the current call, shared with a retry's copy
        verts = self.scene.object.vertices_B
        self.size = float(geo.norms(verts).max())
        self.fall_step = float(fall_step) * self.size
        self.rho = mech.gyration_radius(self.scene)
        self.weight = self.scene.object_weight
        self._gravity = mech.gravity_wrench(self.scene)  # the wrench the contacts must supply
        self.ftol = 1e-9 * self.weight
        # Newton stops well inside the tolerance, but not below what doubles can resolve
        self.newton_tol = max(1e-3 * self.tol, 64 * np.finfo(float).eps * L)
        self._scale = np.array([1.0, 1.0, 1.0 / self.rho])  # twist -> scaled twist rows
        # Moments in units of the palm width, so that the equilibrium rows (forces in weights,
        # moments in weight x palm width) and the motion LP's tolerances are unit-free.
        self._length = L
        self._per_length = np.array([1.0, 1.0, 1.0 / L])
        self._placements: dict[tuple[bytes, bytes], ct.Placement] = {}
        self._local = ct.local_geometry(self.scene)
        # Sweep bounds: how far any hand vertex lies from its body's frame origin (palm,
        # joints), and the thinnest of the bodies, which a step may not jump across.
        polys = kin.hand_polygons_local(self.scene)
        self._reach = np.array([float(geo.norms(p).max()) for p in polys])
        self._thinnest = min(
            object_width(self.scene),
            self.scene.palm.thickness,
            *(f.thickness for f in self.scene.fingers),
        )

    def _place(self, q: np.ndarray, h: np.ndarray) -> ct.Placement:
        """The world geometry at ``(q, h)``, memoised over the last few configurations: the
        plan, the step's checks, the determinacy test and the output of one increment
        look at the same ones."""
        key = (q.tobytes(), h.tobytes())
        pl = self._placements.get(key)
        if pl is None:
            if len(self._placements) >= 8:
                del self._placements[next(iter(self._placements))]
            pl = self._placements[key] = ct.Placement(self.scene, q.copy(), h.copy())
        return pl

    # ------------------------------------------------------------------ public API
    def reset(self) -> State:
        """The scene's initial state; an object not held at its placement first falls to rest."""
        scene = self.scene
        return self.settle(scene.object.start_pose.copy(), scene.initial_hand)

    def settle(self, object_pose: np.ndarray, hand: np.ndarray) -> State:
        """State for a given object pose and hand configuration, after any fall to rest."""
        q = np.asarray(object_pose, dtype=float).copy()
        h = np.asarray(hand, dtype=float).copy()
        events: list[Event] = []
        self._solves[0] = 0
        q = self._fall_if_needed(q, h, 0.0, events)
        return self._make_state(q, h, events)

    def move_hand(
        self,
        state: State,
        palm: np.ndarray | tuple | None = None,
        fingers: np.ndarray | tuple | None = None,
    ) -> State:
        """Move the hand in a straight line in ``(x_p, y_p, theta_p, q1, q2)`` to the target.

        Args:
            state: the current state (its scene must be this simulator's).
            palm: target palm pose ``(x, y, theta)``; None keeps the current one.
            fingers: target finger angles ``(q1, q2)``; clipped to the joint limits (reported
                as a ``"joint_limit"`` event). None keeps the current ones.

        Returns:
            The new state. It never raises for a jam, a fall or a blocked hand: ``jammed`` /
            ``hand_blocked`` say the hand stopped short, and ``events`` say what happened.
        """
        h0 = state.hand.copy()
        h1 = h0.copy()
        events: list[Event] = []
        if palm is not None:
            h1[:3] = _finite_vector(palm, 3, "palm")
        if fingers is not None:
            target = _finite_vector(fingers, 2, "fingers")
            lim = self.scene.joint_limits
            clipped = np.clip(target, lim[:, 0], lim[:, 1])
            if np.any(clipped != target):
                events.append(Event("joint_limit", 1.0))
            h1[3:] = clipped
        s_end, blocked = self._support_limit(h0, h1)
        touching = [c.key for c in state.contacts]  # detected at (q, h0) by _make_state
        start = events.copy()
        self._solves[0] = 0
        try:
            q, s_reached, jammed = self._advance(
                state.object_pose.copy(), h0, h1, s_end, events, touching
            )
            return self._finish(q, h0, h1, s_reached, s_end, events, jammed, blocked)
        except WorkLimitError:
            raise  # the retry would do the same work again, and more
        except (SimulationError, SolverError) as first:
            # A failed solve: once more on the reference LP path with smaller increments
            # (nothing of the failed attempt is kept); a second failure is reported.
            careful, events = self._careful(), start
            try:
                q, s_reached, jammed = careful._advance(
                    state.object_pose.copy(), h0, h1, s_end, events, None
                )
                return careful._finish(q, h0, h1, s_reached, s_end, events, jammed, blocked)
            except WorkLimitError:
                raise
            except (SimulationError, SolverError) as second:
                raise SimulationError(
                    f"move failed ({first}) and again on the reference path with smaller "
                    f"increments ({second})"
                ) from second

    def _finish(self, q, h0, h1, s_reached, s_end, events, jammed, blocked) -> State:
        """The state at the end of a move: the hand is blocked by the support only if it got
        there (a jam may stop it first)."""
        if blocked and not (jammed and s_reached < s_end):
            events.append(Event("hand_blocked", s_end))
        else:
            blocked = False
        h = h0 + s_reached * (h1 - h0)
        return self._make_state(q, h, events, jammed=jammed, blocked=blocked)

    def _careful(self) -> Simulator:
        """A copy of this simulator on the reference LP path (HiGHS) with a quarter of the
        increment and fall step, for retrying a move whose solves failed."""
        careful = copy.copy(self)
        careful.lp_solver = "highs"
        careful.max_step = self.max_step / 4.0
        careful.fall_step = self.fall_step / 4.0
        return careful

    # ------------------------------------------------------------------ hand path
    def _support_limit(self, h0: np.ndarray, h1: np.ndarray) -> tuple[float, bool]:
        """Largest ``s`` in [0, 1] before a hand vertex enters the support, and whether the
        move is cut short. Hand vertex heights are smooth in ``s``: a dense scan brackets the
        first crossing, and bisection locates it to ``contact_tol``."""
        dh = h1 - h0

        def lowest(s: float) -> float:
            return float(kin.lowest_hand_points(self.scene, h0 + s * dh)[0])

        grid = np.linspace(0.0, 1.0, 65)
        low = kin.lowest_hand_points(self.scene, h0 + grid[:, None] * dh)
        below = np.nonzero(low[1:] < -self.tol)[0]
        if len(below) == 0:
            return 1.0, False
        lo, hi = grid[below[0]], grid[below[0] + 1]
        while hi - lo > 1e-16 and lowest(lo) > self.tol:  # stop touching, not above
            mid = 0.5 * (lo + hi)
            if lowest(mid) < 0.0:
                hi = mid
            else:
                lo = mid
        return lo, True

    # ------------------------------------------------------------------ core loop
    def _advance(
        self,
        q: np.ndarray,
        h0: np.ndarray,
        h1: np.ndarray,
        s_end: float,
        events: list[Event],
        touching: list | None = None,
    ) -> tuple[np.ndarray, float, bool]:
        """Follow the move from ``s = 0`` to ``s_end``; ``touching`` are the contacts already
        known at the start. Returns the object pose, the ``s`` reached and whether it jammed."""
        dh = h1 - h0
        s = 0.0
        banned: set = set()
        if not np.any(dh) or s_end <= 0.0:
            return self._fall_if_needed(q, h0, 0.0, events), 0.0, False
        # Events closer than contact_tol along the hand's path count as here (no progress).
        reach = np.abs(dh[:2]).sum() + np.abs(dh[2:]).sum() * self.scene.palm.width
        s_eps = max(1e-13, self.tol / reach)
        stuck_fall = False
        losing = None  # (E, v) of a plan dropped for a negative force at this s
        override, forced = None, set()  # a plan with a touching contact forced active
        carry = None  # (E, v) kept from an accepted step whose active set stays valid
        run: tuple = (None, 0)  # the event located last, and how often in a row (chatter)
        mark = (0.0, 0)  # (s, iteration) where s last moved on by more than CHATTER_DS
        for it in range(self.max_iterations):
            if s > mark[0] + CHATTER_DS:
                mark = (s, it)
            elif it - mark[1] > STALL:
                raise WorkLimitError(
                    f"no progress after {STALL} increments within {CHATTER_DS:g} of s = {s}"
                )
            h = h0 + s * dh
            determined = carry is not None
            overridden = override is not None
            if determined:
                plan, carry = carry, None
            elif overridden:
                plan, override = override, None
            else:
                pl = self._place(q, h)
                if touching is not None:
                    keys, touching = touching, None
                else:
                    keys = ct.detect(pl, self.tol, exclude=banned)
                plan = self._plan(pl, keys, h, dh, allow_fall=not stuck_fall)
            stuck_fall = False
            if plan == "jam":
                if losing is not None:
                    # Contacts dropped for a negative force leave the object unheld just
                    # ahead: past the boundary of equilibrium it falls.
                    fallen = self._nudge_and_fall(q, s, *losing, h0, dh, s_end, events)
                    if fallen is not None:
                        s, q = fallen
                        banned, losing, forced = set(), None, set()
                        continue
                q_fallen = self._fall_if_unheld(q, h, s, events)
                if q_fallen is not None:
                    q = q_fallen
                    continue
                events.append(Event("jam", s, tuple(keys)))
                return self._jam(q, h, s)
            if plan == "fall":
                q_fallen = self._fall(q, h, s, events)
                stuck_fall = q_fallen is q  # no way down after all: plan without falling
                if stuck_fall:
                    del events[-2:]  # the fall that did not happen
                q = q_fallen
                continue
            E, v = plan
            if s >= s_end - 1e-15:
                return q, s_end, False
            rest = self._sweep_limit(q, h, dh, v, E, s_end - s)
            ds = min(self.max_step, rest)
            tried = False
            if ds < rest and (determined or self._determined(q, h, E)):
                # E fixes the pose as a function of s and holds it with positive forces: it
                # stays the active set until an event and the pose needs no integration, so
                # one step may go to the end of the move (the check locates any event in it).
                ok, q_new, trigger = self._try_step(q, s, rest, E, v, h0, dh, guard=True)
                tried = ok or trigger[0] != "jam"
                if tried:
                    ds = rest
            if not tried:
                ok, q_new, trigger = self._try_step(q, s, ds, E, v, h0, dh)
            if ok:
                if self._determined(q_new, h0 + (s + ds) * dh, E):
                    carry = (E, (q_new - q) / ds)
                q, s = q_new, s + ds
                banned, losing, forced = set(), None, set()
                continue
            s_star, q_star, event = self._locate(q, s, s + ds, E, v, h0, dh, trigger)
            # Chatter: the same event again and again, each within a hair's breadth of the
            # last (a contact whose force falls to zero again as soon as the re-planned
            # active set takes it back; an infeasible LP just ahead at a wedge). Treat it as
            # happening here, at s.
            near = s_star - s < CHATTER_DS
            seen = (event.kind, event.contacts)
            run = (seen, run[1] + 1) if near and seen == run[0] else (seen, 1 if near else 0)
            if s_star - s < s_eps or run[1] > CHATTER:
                key = event.contacts[0] if event.contacts else None
                if event.kind in ("edge_to_tip", "tip_to_edge", "lost_contact") and key is not None:
                    if key not in banned:
                        # The offending contact cannot stay active here: plan without it.
                        banned.add(key)
                        if event.kind == "lost_contact":
                            losing, override = self._release(E, v, key)
                        continue
                if overridden:
                    continue  # the forced plan could not go on: plan afresh
                reverted = False
                if event.kind == "new_contact" and key is not None and key not in E:
                    if key in banned and losing is not None:
                        # Keeping the contact makes its force negative, dropping it lets the
                        # object into it: the object sits at an equilibrium that the hand's
                        # motion destroys (a potential maximum along the other contacts'
                        # family).
                        (E, v), reverted = losing, True
                    elif key not in banned and key not in forced:
                        # A touching contact the plan left open (zero force, not tight at
                        # the least-norm velocity) closes at once: the object held by the
                        # others is pushed into it, so it joins the active set. The plan's
                        # velocity keeps every touching contact closed (V v >= xi).
                        pl = self._place(q, h0 + s * dh)
                        if key in ct.detect(pl, self.tol):
                            forced.add(key)
                            override = ([*E, key], v)
                            continue
                if event.kind == "lost_contact" or reverted:
                    # The object sits on the boundary of equilibrium: just ahead, no contact
                    # set holds it. Nudge the hand past the boundary and let the object fall.
                    fallen = self._nudge_and_fall(q, s, E, v, h0, dh, s_end, events)
                    if fallen is not None:
                        s, q = fallen
                        banned, losing, forced = set(), None, set()
                        continue
                # Nothing consistent lies just ahead: the active contacts' equations fold
                # (their normals turn concurrent and the forces needed grow without bound) or
                # no contact can be released. The hand cannot move on: a jam -- unless the
                # contacts left cannot hold the object, which then falls first.
                q_fallen = self._fall_if_unheld(q, h0 + s * dh, s, events)
                if q_fallen is not None:
                    q, banned, losing, forced = q_fallen, set(), None, set()
                    continue
                events.append(Event("jam", s, tuple(E)))
                return self._jam(q, h0 + s * dh, s)
            events.append(Event(event.kind, s_star, event.contacts))
            q, s = q_star, s_star
            banned, losing, forced = set(), None, set()
        raise WorkLimitError(f"no progress after {self.max_iterations} increments (s = {s})")

    def _jam(self, q: np.ndarray, h: np.ndarray, s: float) -> tuple[np.ndarray, float, bool]:
        """The hand stops at a jam; the object must be held there (at a fold by forces
        without bound). A jam whose object is neither held nor able to fall (a fall that
        cannot find its way down) is a failure, not a state to return."""
        pl = self._place(q, h)
        if not self._held(pl, ct.detect(pl, self.tol), max_force=np.inf):
            raise SimulationError(f"jam at s = {s:.6g} with the object neither held nor falling")
        return q, s, True

    @staticmethod
    def _release(E: list, v: np.ndarray, key) -> tuple:
        """A contact's force reached zero: the others hold the object right there, so the
        motion goes on with them (the old plan's velocity as Newton's predictor). Returns
        ``(losing, override)``: the old plan, kept in case releasing fails too, and the new."""
        rest = [k for k in E if k != key]
        return (E, v), ((rest, v) if rest else None)

    def _plan(self, pl: ct.Placement, keys: list, h: np.ndarray, dh: np.ndarray, allow_fall=True):
        """Active set and least-motion velocity for hand velocity ``dh`` at a placement.

        Vertex-vertex touches give several candidate contacts at one point whose admissible
        half-planes form a union; each choice is tried and the one with the lowest potential
        energy rate (the object's choice, eq. 19) is kept. All candidates at once (always
        admissible) is the last choice. With ``allow_fall=False`` (a fall just found no way
        down) choices that would fall are skipped.
        """
        best = None
        choices = list(_choices(pl, keys, self.tol))
        if len(choices) > 1:
            choices.append(keys)
        for choice in choices:
            res = self._solve_lp(pl, choice, h, dh)
            if res == "fall":
                if allow_fall:
                    return "fall"
                continue
            if res == "jam":
                continue
            if best is None or res[0] < best[0] - 1e-12 * self.weight * self._length:
                best = res
        if best is None:
            return "jam"
        return best[1], best[2]

    def _solve_lp(self, pl: ct.Placement, keys: list, h: np.ndarray, dh: np.ndarray):
        p, n, bodies = _arrays(pl, keys)
        V = mech.V_ob(p, n, pl.com_W)
        xi = mech.xi(self.scene, h, dh, bodies, p, n)
        if keys and not np.any(xi):
            # The hand moves no contact (the object on the support, the fingers in free
            # space): v = 0 is optimal, with every contact tight, whenever the contacts hold
            # the object exactly; only the borderline cases need the LP.
            if _nnls((V * self._per_length).T, self._gravity)[1] <= 1e-12 * self.weight:
                return 0.0, list(keys), np.zeros(3)
        L = self._length
        res = mech.motion_lp(V * self._per_length, xi / L, self.weight, self.lp_solver)
        if res.status == "infeasible":
            return "jam"
        if res.status == "unbounded":
            return "fall"
        lam = res.forces
        pos = lam > self.ftol
        Vs = V * self._scale
        try:
            w = qp.least_norm(Vs[pos], xi[pos] / L, Vs[~pos], xi[~pos] / L, tol=1e-9) * L
        except SolverError:
            w = res.velocity * L * self._per_length / self._scale
        v = w * self._scale
        slack = dense.matvec(V, v) - xi
        tight = pos | (slack <= 1e-9 * max(L, float(np.abs(xi).max(initial=0.0))))
        E = [k for k, t in zip(keys, tight, strict=True) if t]
        return res.value * L, E, v

    def _sweep_limit(self, q, h, dh, v, E, rest: float) -> float:
        """Largest ``ds`` (up to ``rest``) after which no hand body out of contact can have
        passed through the object: its separating distance plus the thinnest body's width,
        over a bound on how fast its vertices approach the object's (conservative
        advancement). Only the step's end is checked for penetration, so this keeps thin
        fingers from tunnelling; short moves (most env steps) need no distances at all."""
        half = 0.5 * self.scene.palm.width
        turn = abs(dh[2])
        base = float(np.hypot(dh[0], dh[1])) + turn * half  # palm origin / joints
        speed = {
            geo.PALM: float(np.hypot(dh[0], dh[1])) + turn * self._reach[0],
            geo.FINGER1: base + abs(dh[2] + dh[3]) * self._reach[1],
            geo.FINGER2: base + abs(dh[2] + dh[4]) * self._reach[2],
        }
        # the object moves too: twice its predicted speed, for the path's curvature
        obj = 2.0 * (float(np.hypot(v[0], v[1])) + abs(v[2]) * self.size)
        if (max(speed.values()) + obj) * rest <= self._thinnest:
            return rest
        touching = {k[0] for k in E}
        seps = ct.separations(self._place(q, h), [b for b in speed if b not in touching])
        limit = rest
        for b, d in seps.items():
            rate = speed[b] + obj
            if rate > 0.0:
                limit = min(limit, (max(d, 0.0) + self._thinnest) / rate)
        return limit

    # ------------------------------------------------------------------ Newton
    def _newton(self, q0: np.ndarray, h: np.ndarray, E: list) -> np.ndarray | None:
        """Solve ``phi_E(q, h) = 0`` from ``q0`` (least-motion steps); None if it fails.

        Three or more object vertices on one straight edge (a flat side on the support or on
        a finger, whose middle vertices may bulge by less than the tolerance) are one
        supporting edge: their equations are dependent and, off the line by rounding or a
        bulge, inconsistent. Newton then solves for the edge's two outermost contacts, and
        the pose is accepted when the middle ones lie within tolerance as well.
        """
        if not E:
            return q0.copy()
        core = self._supporting_pairs(q0, h, E)
        q = self._newton_on(q0, h, core)
        if q is None or core is E:
            return q
        return q if np.abs(self._gaps(q, h, E)[2]).max() <= self.tol else None

    def _supporting_pairs(self, q: np.ndarray, h: np.ndarray, E: list) -> list:
        """``E`` with the contacts of each straight edge that holds three or more object
        vertices reduced to its outermost two (``E`` itself when there are none)."""
        groups: dict[tuple[int, int], list[int]] = {}
        for i, k in enumerate(E):
            if k[1] == ct.EDGE:
                groups.setdefault((k[0], k[3]), []).append(i)
        if all(len(g) < 3 for g in groups.values()):
            return E
        P = self._gaps(q, h, E)[0]
        drop: set[int] = set()
        for g in groups.values():
            if len(g) >= 3:
                far = max(
                    itertools.combinations(g, 2),
                    key=lambda ij: float(np.abs(P[ij[0]] - P[ij[1]]).sum()),
                )
                drop.update(i for i in g if i not in far)
        return [k for i, k in enumerate(E) if i not in drop]

    def _count_solve(self) -> None:
        """Charge one pose solve to the current call's budget (``max_solves``)."""
        self._solves[0] += 1
        if self._solves[0] > self.max_solves:
            raise WorkLimitError(f"the move needs more than {self.max_solves} pose solves")

    def _newton_on(self, q0: np.ndarray, h: np.ndarray, E: list) -> np.ndarray | None:
        """Newton's method on the gap equations of ``E`` (:func:`grasp_env.sim.pose.newton`)."""
        self._count_solve()
        g = self._local
        q, ok = pose.newton(
            g.points, g.body, g.n_object, g.n_vertices, g.half, q0, h, _key_array(E),
            self._scale, self.newton_tol, self.tol, self.size,
        )  # fmt: skip
        return q if ok else None

    def _solve_pose(self, q0: np.ndarray, h: np.ndarray, E: list) -> np.ndarray | None:
        """The object pose on the path with active set ``E``: held by ``E`` in equilibrium."""
        if E and all(k[0] == geo.SUPPORT for k in E):
            # Resting on the support alone, the object does not move while the hand moves
            # (the plan's velocity is zero): the pose that met the contacts still does.
            if np.abs(self._gaps(q0, h, E)[2]).max() <= self.tol:
                return q0
        if 0 < len(E) < 3:
            q = self._newton_held(q0, h, E)
            if q is not None:
                return q
        return self._newton(q0, h, E)

    def _newton_held(self, q0: np.ndarray, h: np.ndarray, E: list) -> np.ndarray | None:
        """Pose held by fewer than three contacts: their gap equations together with the
        object's equilibrium (:func:`grasp_env.sim.pose.newton_held`); None if Newton fails.

        With ``|E| < 3`` the gap equations leave the object ``3 - |E|`` free directions, and
        quasi-static motion keeps it at the potential's minimum along them; the equilibrium
        equations close the system.
        """
        self._count_solve()
        g = self._local
        q, ok = pose.newton_held(
            g.points, g.body, g.n_object, g.n_vertices, g.half, q0, h, _key_array(E),
            self._scale, self.rho, self._gravity / self.weight, self.newton_tol, self.size,
        )  # fmt: skip
        return q if ok else None

    def _gaps(self, q: np.ndarray, h: np.ndarray, E: list):
        """Points, normals and gaps of the contacts ``E`` at ``(q, h)``."""
        g = self._local
        P, N, F, _, _ = placement.contact_rows(
            self._place(q, h).world, g.n_object, g.n_vertices, _key_array(E)
        )
        return P, N, F

    # ------------------------------------------------------------------ consistency
    def _check(self, q: np.ndarray, h: np.ndarray, E: list) -> dict:
        """Signed violations of the active set ``E`` at ``(q, h)``, in length units.

        Returns ``{(kind, key): value}``: ``value > tol`` is a violation, ``|value| <= tol``
        an event sitting exactly here. Kinds: ``"new_contact"`` (minus the smallest gap of a
        vertex not pinned by ``E``), ``"edge_to_tip"``/``"tip_to_edge"`` (how far an active
        contact's point lies beyond its edge's end), ``"lost_contact"`` (minus the smallest
        active force, scaled by size / weight) and ``"equilibrium"`` (the residual of the
        object's equilibrium with ``E``'s forces, which only flags violations).
        """
        g = self._local
        gap, gap_key, depth, body, ends, lost, force, residual = consistency.violations(
            self._place(q, h).world, g.n_object, g.n_vertices, _key_array(E),
            0.05 * self.size + self.tol, q[:2], self._gravity, self._length,
        )  # fmt: skip
        out = {}
        if gap_key[0] >= 0:
            out[("new_contact", tuple(int(x) for x in gap_key))] = -gap
        if body >= 0:
            out[("overlap", int(body))] = depth
        for k, end in zip(E, ends, strict=True):
            if end > -np.inf:
                out[("edge_to_tip" if k[1] == ct.EDGE else "tip_to_edge", k)] = end
        if E:
            scale = self.size / self.weight
            if lost >= 0:
                out[("lost_contact", E[lost])] = -force * scale
            out[("equilibrium", None)] = residual * scale - self.tol
        return out

    def _worst(self, checks: dict) -> tuple[float, tuple]:
        if not checks:
            return -np.inf, ("none", None)
        ident = max(checks, key=checks.get)
        return checks[ident], ident

    def _try_step(self, q, s, ds, E, v, h0, dh, guard=False):
        """Newton step to ``s + ds`` and its consistency check: ``(ok, q_new, trigger)``.

        With ``guard``, a Newton correction larger than half the predicted motion counts as a
        failure (over a long step it may have found another root of the equations).
        """
        h = h0 + (s + ds) * dh
        q_pred = q + v * ds
        q_new = self._solve_pose(q_pred, h, E)
        if q_new is not None and guard:
            move = np.abs((q_pred - q) / self._scale).max()
            if np.abs((q_new - q_pred) / self._scale).max() > 0.5 * move + self.tol:
                q_new = None
        if q_new is None:
            return False, None, ("jam", None)
        worst, ident = self._worst(self._check(q_new, h, E))
        return worst <= self.tol, q_new, ident

    def _locate(self, q, s_lo, s_hi, E, v, h0, dh, trigger):
        """Find the first point in ``(s_lo, s_hi]`` where the active set ``E`` stops being
        consistent, to within ``contact_tol`` (bisection on ``s``).

        Returns ``(s, q, Event)`` at the event: the triggering quantity sits within tolerance
        of its limit there, and nothing is violated beyond tolerance.
        """
        q_lo = q
        for _ in range(200):
            mid = 0.5 * (s_lo + s_hi)
            if mid <= s_lo or mid >= s_hi:
                break
            h = h0 + mid * dh
            q_mid = self._solve_pose(q_lo + v * (mid - s_lo), h, E)
            if q_mid is None:
                s_hi, trigger = mid, ("jam", None)
                continue
            checks = self._check(q_mid, h, E)
            worst, ident = self._worst(checks)
            if worst > self.tol:
                s_hi, trigger = mid, ident
            elif (
                trigger[0] not in ("equilibrium", "jam")
                and checks.get(trigger, -np.inf) >= -self.tol
            ):
                if trigger[0] == "overlap":  # first touch: the vertex that touches
                    trigger = next((c for c in checks if c[0] == "new_contact"), trigger)
                return mid, q_mid, _event(trigger, mid)
            else:
                s_lo, q_lo = mid, q_mid
        return s_lo, q_lo, _event(trigger, s_lo)

    def _determined(self, q: np.ndarray, h: np.ndarray, E: list) -> bool:
        """True when ``E`` cannot change before an event: three independent contacts holding
        the object with forces all clearly positive, or the object resting on the support."""
        if E and all(k[0] == geo.SUPPORT for k in E):
            return True  # resting on the support: only a new contact changes that
        if len(E) != 3:
            return False
        pl = self._place(q, h)
        P, N, _ = _arrays(pl, E)
        W = mech.V_ob(P, N, q[:2]).T
        if abs(dense.det(W * self._scale[:, None])) < 1e-8:
            return False
        lam, ok = dense.solve(W, self._gravity)
        return ok and bool(lam.min() > 1e-6 * self.weight)

    def _nudge_and_fall(self, q, s, E, v, h0, dh, s_end, events):
        """Nudge the hand past the boundary of equilibrium (:meth:`_nudge`) and let the
        object fall to rest there: ``(s, q)``, or None if there is no such boundary ahead."""
        nudged = self._nudge(q, s, E, v, h0, dh, s_end)
        if nudged is None:
            return None
        s, q = nudged
        return s, self._fall(q, h0 + s * dh, s, events)

    def _nudge(self, q, s, E, v, h0, dh, s_end):
        """Smallest step along ``E`` (geometrically consistent) after which the touching
        contacts can no longer hold the object; None if there is none within one step."""
        ds = 1e-10
        while ds <= self.max_step and s + ds <= s_end:
            h = h0 + (s + ds) * dh
            q_new = self._newton(q + v * ds, h, E)
            if q_new is None or self._geometry_violation(q_new, h, E) > self.tol:
                return None
            pl = self._place(q_new, h)
            if not self._held(pl, ct.detect(pl, self.tol)):
                return s + ds, q_new
            ds *= 4.0
        return None

    # ------------------------------------------------------------------ falls
    def _fall_if_needed(
        self, q: np.ndarray, h: np.ndarray, s: float, events: list[Event]
    ) -> np.ndarray:
        pl = self._place(q, h)
        keys = ct.detect(pl, self.tol)
        if self._held(pl, keys):
            return q
        return self._fall(q, h, s, events)

    def _fall_if_unheld(self, q, h, s, events) -> np.ndarray | None:
        """Fall to rest when the touching contacts cannot hold the object; the new pose, or
        None when they hold it (or no way down exists)."""
        pl = self._place(q, h)
        if self._held(pl, ct.detect(pl, self.tol)):
            return None
        q_fallen = self._fall(q, h, s, events)
        if q_fallen is q:
            del events[-2:]
            return None
        return q_fallen

    def _held(
        self, pl: ct.Placement, keys: list, ftol: float | None = None, max_force: float = MAX_FORCE
    ) -> bool:
        """True when the touching contacts ``keys`` hold the object against gravity (to the
        force tolerance ``ftol``, default the simulator's). At a vertex-vertex touch the
        object may move along either candidate's edge (a union of half-planes): it is held
        only if every choice of candidates holds it. Forces beyond :data:`MAX_FORCE` object
        weights do not count: a wedge between faces parallel to rounding would need them, and
        in double precision they no longer balance (the object slides out instead)."""
        ftol = self.ftol if ftol is None else ftol
        if not keys:
            return False
        g = self._gravity
        for choice in _choices(pl, keys, self.tol):
            p, n, _ = _arrays(pl, choice)
            lam, res = _nnls((mech.V_ob(p, n, pl.com_W) * self._per_length).T, g)
            if res > ftol or lam.max() > max_force * self.weight:
                return False
        return True

    def _fall(self, q: np.ndarray, h: np.ndarray, s: float, events: list[Event]) -> np.ndarray:
        """Quasi-static fall: follow the steepest admissible descent of the potential energy
        (gravity projected on the admissible cone, mass metric) until contacts hold the object."""
        events.append(Event("fall_start", s))
        for _ in range(self.max_iterations):
            pl = self._place(q, h)
            keys = ct.detect(pl, self.tol)
            # Held only to rounding: near the boundary of equilibrium a residual within the
            # usual tolerance still leaves a way down, which the descent below finds.
            if self._held(pl, keys, ftol=1e-12 * self.weight):
                events.append(Event("fall_end", s, tuple(keys)))
                return q
            q_rest = self._cradle(q, h, keys)
            if q_rest is not None:
                q = q_rest  # held exactly there: the next pass ends the fall
                continue
            # At a vertex-vertex touch any one candidate's half-plane suffices locally; take
            # the choice (or all candidates at once, always admissible) whose step lowers the
            # potential energy most.
            choices = list(_choices(pl, keys, self.tol))
            if len(choices) > 1:
                choices.append(keys)
            # An edge contact at the very end of its hand edge may slide off it: then its twin
            # (the hand vertex there, on the object's edge), which detection folds into it,
            # carries the slide on.
            ends = {
                k for k in keys if k[0] != geo.SUPPORT and k[1] == ct.EDGE and self._at_end(pl, k)
            }
            if ends:
                twins = ct.detect(pl, self.tol, exclude=ends)
                if twins != keys:
                    choices.extend(_choices(pl, twins, self.tol))
            best, best_event = None, False
            for choice in choices:
                a, E = self._descent(pl, choice)
                norm_a = math.sqrt(dense.dot(a, a))
                if norm_a < 1e-13:
                    continue  # gravity is balanced to first order by this choice
                # backtracking: near a stable rest (a cradle) a full step overshoots
                d = a * self._scale / norm_a * self.fall_step
                for _ in range(50):
                    q_new, at_event = self._fall_step(q, h, E, d)
                    if q_new[1] < q[1] - 1e-12 * self.size:
                        break
                    if at_event and q_new[1] <= q[1] and np.any(q_new != q):
                        break  # a nearly flat way down that reaches a new contact
                    if at_event and q_new is q:
                        # No admissible point along d at all: the bisection already tried
                        # every step a halved d would (d/2, d/4, ... down to rounding).
                        break
                    d = 0.5 * d
                if best is None or q_new[1] < best[1]:
                    best, best_event = q_new, at_event
            # A step that ends on an event (a new contact, an edge's end) changes the contacts
            # for the next step however short it is; otherwise a negligible drop means rest.
            if best is None or (
                not (best_event and np.any(best != q)) and best[1] > q[1] - 1e-12 * self.size
            ):
                # no admissible descent lowers the object: it is held
                events.append(Event("fall_end", s, tuple(keys)))
                return q
            q = best
        raise WorkLimitError("fall did not come to rest")

    def _at_end(self, pl: ct.Placement, key) -> bool:
        """Whether contact ``key``'s point lies within two tolerances of an end of its edge."""
        _, _, _, t, L = pl.evaluate(key)
        return min(t, 1.0 - t) * L <= 2.0 * self.tol

    def _cradle(self, q: np.ndarray, h: np.ndarray, keys: list) -> np.ndarray | None:
        """The rest pose of a fall that has nearly come to rest on fewer than three contacts
        (a cradle, where descent steps converge only linearly): their equilibrium pose by
        Newton, if it lies within one fall step, no higher, with nothing violated, and the
        contacts there hold the object; else None."""
        if not 0 < len(keys) < 3:
            return None
        q_rest = self._newton_held(q, h, keys)
        if q_rest is None or q_rest[1] > q[1] + self.tol:
            return None
        if np.abs((q_rest - q) / self._scale).max() > self.fall_step:
            return None
        if self._geometry_violation(q_rest, h, keys) > self.tol:
            return None
        pl = self._place(q_rest, h)
        return q_rest if self._held(pl, ct.detect(pl, self.tol), 1e-12 * self.weight) else None

    def _descent(self, pl: ct.Placement, keys: list) -> tuple[np.ndarray, list]:
        """Steepest admissible descent (scaled twist) for contacts ``keys``, and the contacts it
        keeps closed: ``a = argmin |a - g|^2 s.t. C a >= 0`` (gravity projected on the cone)."""
        g_scaled = np.array([0.0, -1.0, 0.0])
        p, n, _ = _arrays(pl, keys)
        Cs = mech.V_ob(p, n, pl.com_W) * self._scale
        try:
            w = qp.least_norm(np.zeros((0, 3)), np.zeros(0), Cs, -dense.matvec(Cs, g_scaled))
        except SolverError as exc:
            raise SimulationError("fall direction infeasible") from exc
        a = w + g_scaled
        tight = dense.matvec(Cs, a) <= 1e-10
        return a, [k for k, t in zip(keys, tight, strict=True) if t]

    def _fall_step(self, q: np.ndarray, h: np.ndarray, E: list, d: np.ndarray):
        """One fall step of at most ``d``, shortened to the first new contact or edge end.

        Returns ``(q_new, at_event)``: ``at_event`` when the step was shortened to an event.
        """

        def at(frac: float) -> np.ndarray | None:
            return self._newton(q + frac * d, h, E)

        q1 = at(1.0)
        if q1 is not None:
            if self._geometry_violation(q1, h, E) <= self.tol:
                return q1, False
        lo, hi, q_lo = 0.0, 1.0, q
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if hi - lo < 1e-16 or not lo < mid < hi:
                break  # located to rounding (near 1 doubles are 1.1e-16 apart)
            q_mid = at(mid)
            if q_mid is None:
                hi = mid
                continue
            worst = self._geometry_violation(q_mid, h, E)
            if worst > self.tol:
                hi = mid
            elif worst >= -self.tol:
                return q_mid, True
            else:
                lo, q_lo = mid, q_mid
        return q_lo, True

    def _geometry_violation(self, q, h, E) -> float:
        """Penetration, overlap or a contact past its edge's end, at worst, for ``E``."""
        g = self._local
        return float(
            consistency.geometry_violation(
                self._place(q, h).world, g.n_object, g.n_vertices, _key_array(E)
            )
        )

    # ------------------------------------------------------------------ output
    def _make_state(self, q, h, events, jammed=False, blocked=False) -> State:
        pl = self._place(q, h)
        keys = ct.detect(pl, self.tol)
        forces = self._rest_forces(pl, keys)
        contacts = []
        for key, f in zip(keys, forces, strict=True):
            p, n, gap, _, _ = pl.evaluate(key)
            contacts.append(
                ct.Contact(
                    body=geo.BODY_NAMES[key[0]],
                    kind=ct.KIND_NAMES[key[1]],
                    point=p.copy(),
                    normal=n.copy(),
                    force=float(f),
                    object_feature=key[2],
                    hand_feature=key[3],
                    gap=float(gap),
                )
            )
        return State(
            self.scene, q.copy(), h.copy(), tuple(contacts), jammed, blocked, tuple(events)
        )

    def _rest_forces(self, pl: ct.Placement, keys: list) -> np.ndarray:
        """Contact forces holding the object once the hand stops: the least total force in
        equilibrium (a position-controlled hand adds no preload, section 3.2)."""
        if not keys:
            return np.zeros(0)
        p, n, _ = _arrays(pl, keys)
        V = mech.V_ob(p, n, pl.com_W) * self._per_length
        g = self._gravity
        if len(keys) <= 3:
            # independent wrenches: the only forces in equilibrium, if non-negative
            lam = _independent_forces(V.T, g)
            if (
                lam is not None
                and lam.min() >= 0.0
                and np.abs(dense.rmatvec(V, lam) - g).max() <= self.ftol
            ):
                return lam
        # min 1^T lam s.t. V^T lam = (0, W, 0), lam >= 0: the force LP with xi = -1, solved
        # through its primal (min W v_y s.t. V v >= -1) by the same motion LP as the steps.
        res = mech.motion_lp(V, -np.ones(len(keys)), self.weight, self.lp_solver)
        if res.status != "optimal":
            # held only to within the fall's tolerance: the closest non-negative forces
            lam, _ = _nnls(V.T, g)
            return lam
        return np.maximum(res.forces, 0.0)


def _event(trigger: tuple, s: float) -> Event:
    kind, key = trigger
    if kind == "equilibrium":
        kind = "lost_contact"
    if kind == "overlap":  # edges about to cross: a new contact (vertex-vertex)
        kind, key = "new_contact", None
    return Event(kind, s, (key,) if key is not None else ())


def _independent_forces(W: np.ndarray, g: np.ndarray) -> np.ndarray | None:
    """Forces of up to three independent contact wrenches (the columns of ``W``) balancing
    ``g`` in least squares, or None when the wrenches are dependent
    (:func:`grasp_env.sim.pose.independent_forces`)."""
    lam, ok = pose.independent_forces(np.ascontiguousarray(W), g)
    return lam if ok else None


def _nnls(W: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, float]:
    """Non-negative least squares ``min |W lam - g|, lam >= 0`` and its residual norm."""
    return dense.nnls(np.ascontiguousarray(W), g)


def _key_array(keys: list) -> np.ndarray:
    """Contact keys as the int rows the compiled kernels take, shape (m, 4)."""
    return np.array(keys, dtype=np.int64).reshape(-1, 4)


def _arrays(pl: ct.Placement, keys: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, normals and bodies of the contacts ``keys`` at placement ``pl``."""
    rows = _key_array(keys)
    P, N, *_ = placement.contact_rows(pl.world, pl.local.n_object, pl.local.n_vertices, rows)
    return P, N, rows[:, 0].copy()


def _choices(pl: ct.Placement, keys: list, tol: float):
    """Contact sets to try: one candidate per vertex-vertex touch (same body, same point)."""
    groups: list[list] = []
    for k in keys:
        p = pl.evaluate(k)[0]
        for g in groups:
            k0 = g[0]
            if (
                k0[0] == k[0]
                and np.abs(pl.evaluate(k0)[0] - p).max() <= 4 * tol
                and k0[0] != geo.SUPPORT
            ):
                g.append(k)
                break
        else:
            groups.append([k])
    multi = [g for g in groups if len(g) > 1]
    single = [g[0] for g in groups if len(g) == 1]
    if not multi:
        yield keys
        return
    for combo in itertools.product(*multi):
        yield single + list(combo)


def _finite_vector(value, size: int, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {size} numbers, got {value!r}") from None
    if arr.shape != (size,):
        raise ValueError(f"{name} must be {size} numbers, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return arr


__all__ = ["SimulationError", "Simulator", "WorkLimitError"]
