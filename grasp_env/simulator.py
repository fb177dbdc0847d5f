"""Quasi-static frictionless simulator: the paper's active-set method (section 3.1).

For a straight-line hand move ``h(s) = h0 + s (h1 - h0)``, ``s`` in [0, 1], the object moves so
as to minimise its potential energy without interpenetration (eqs. 19-24). Per increment:

1. **Active set.** The velocity LP (eqs. 19-21) and the force LP (eqs. 22-24) at the current
   configuration give the object velocity and the contact forces. The contacts with positive
   force, plus any touching contact the hand pushes on (tight at the least-motion optimal
   velocity), form the active set ``E``: by complementary slackness they stay closed.
2. **Newton.** The active contacts' gap equations ``phi_E(q, h(s)) = 0`` (edge and tip contacts
   of the appendix, eqs. A.8, A.10, A.12, A.15, written in vector form in
   :mod:`grasp_env.mechanics.contacts`) are solved for the object pose ``q`` with Newton's method
   and the exact Jacobian ``V_ob`` (the gap gradient; least-motion steps when ``E`` leaves freedom).
3. **Consistency.** The step is accepted if no other vertex penetrates a body, no active
   contact slides off the end of its edge, and the active contacts still hold the object with
   non-negative forces. Otherwise the first event is located on ``s`` to ``contact_tol``
   (false position on the violated check, bracketed as in bisection); the motion stops
   there, the contacts are updated and the move continues.

Infeasible velocity LP: the hand cannot move on (a jam); the hand stops there. Unbounded
velocity LP: the object falls along the steepest admissible descent of its potential energy
(gravity projected onto the admissible cone in the mass metric) until contacts hold it.
"""

from __future__ import annotations

import math

import numpy as np

from grasp_env.arguments import integer, number, real_vector
from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.scene import MAX_ANGLE, MAX_COORDINATE, Scene
from grasp_env.core.scene_loading import load_scene
from grasp_env.core.scene_validation import coordinate_problem
from grasp_env.core.state import (
    ContactKey,
    Event,
    State,
    contacts_from_arrays,
    keep_contact_arrays,
    new_state,
    require_state,
)
from grasp_env.errors import ComputationError, SimulationError, WorkLimitError
from grasp_env.mechanics import closure as mech
from grasp_env.mechanics import contacts as ct
from grasp_env.mechanics.width import object_width
from grasp_env.sim import events as ev
from grasp_env.sim import move
from grasp_env.sim.model import Model, pack

#: Accepted ``contact_tol`` (relative to the palm width), ``[lo, hi)``: below ``lo`` the
#: contacts' own rounding (located events, Newton's residual, flush edges) is no longer small
#: against the tolerance.
CONTACT_TOL_RANGE = (1e-11, 1e-2)
#: Largest ``max_iterations`` and ``max_solves``: the compiled core counts in 64-bit ints.
MAX_WORK = 10**9
#: Largest coordinate of the object's and the palm's position at a start, in palm widths:
#: twice the scene schema's bound, so that every start about a scene's own is accepted (the
#: env's palm workspace reaches 2 palm widths past the object's scene position), while the
#: rounding of a position (2e4 w x 2.2e-16) stays 200 times below the default contact
#: tolerance.
MAX_POSITION = 2 * MAX_COORDINATE

_NO_KEYS = np.zeros((0, 4), dtype=np.int64)
#: The spacing of doubles at 1.
EPS = float(np.finfo(float).eps)


class Simulator:
    """Quasi-static frictionless grasp simulator for one scene.

    The whole of a move runs as compiled code (:mod:`grasp_env.sim.move`) on the scene's
    arrays (:class:`grasp_env.sim.model.Model`), built once here; this class checks the
    arguments and turns the result into a :class:`~grasp_env.core.state.State`.

    Args:
        scene: a :class:`~grasp_env.core.scene.Scene`, bundled name, path or dict.
        contact_tol: gap below which bodies touch, relative to the palm width (default 1e-9,
            at least 1e-11).
            No returned state penetrates deeper; events are located to within it.
        max_step: largest increment of the path parameter ``s`` between consistency checks
            along a move, as a fraction of the move (default 0.25). Smaller steps cost time;
            they matter for moves whose active set leaves the object free directions.
        fall_step: largest object displacement of one step of a fall, relative to the object's
            size (default 0.02).
        max_iterations: safety cap on increments per move (default 10000; at most 1e9).
        max_solves: cap on pose solves (Newton runs) per call of :meth:`move_hand` or
            :meth:`settle`, the retry included (default 5000; at most 1e9). A move that needs more
            raises :class:`WorkLimitError`; it bounds the time of any one call.
        lp_solver: ``"fast"`` (exact basis enumeration, :mod:`grasp_env.solvers.fastlp`) or
            ``"highs"`` (the reference path through scipy's HiGHS) for the motion LP.
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
        # a str first: an array would compare element-wise
        if not isinstance(lp_solver, str) or lp_solver not in ("fast", "highs"):
            raise ValueError(f"lp_solver must be 'fast' or 'highs', got {lp_solver!r}")
        contact_tol = number(contact_tol, "contact_tol", *CONTACT_TOL_RANGE, False, True)
        self.lp_solver = str(lp_solver)
        self.max_step = number(max_step, "max_step", 0.0, 1.0)
        fall_step = number(fall_step, "fall_step", 0.0, 1.0)
        self.max_iterations = integer(max_iterations, "max_iterations", 1, most=MAX_WORK)
        self.max_solves = integer(max_solves, "max_solves", 1, most=MAX_WORK)
        L = self.scene.palm.width
        self.tol = contact_tol * L
        size = float(geo.norms(self.scene.object.vertices_B).max())
        self.size = size  # the object's size: its farthest vertex from the centre of mass
        self.fall_step = float(fall_step) * size
        self._solves = np.zeros(1, dtype=np.int64)  # pose solves of the current call
        self.model = self._build_model(size)
        self._joint_low, self._joint_high = self.scene.joint_limits.T.tolist()
        self._last: tuple = (None, _NO_KEYS)  # the last state made, and its contact keys

    @property
    def model(self) -> Model:
        """The scene and this simulator's settings as the compiled core's arrays."""
        return self._model

    @model.setter
    def model(self, model: Model) -> None:
        self._model = model
        self._packed = pack(model)  # the form in which it crosses into compiled code
        self._compiled_model = model._replace(python_lp=False)

    @property
    def compiled_model(self) -> Model:
        """:attr:`model` for compiled callers that catch the core's errors (the env's
        kernel, :mod:`grasp_env.kernel`): an LP its basis enumeration cannot decide raises
        ``SolverError`` there, and the caller moves again with :meth:`move_arrays`."""
        return self._compiled_model

    def _build_model(self, size: float) -> Model:
        """The scene and this simulator's settings as the compiled core's arrays."""
        scene = self.scene
        L = scene.palm.width
        local = ct.local_geometry(scene)
        rho = mech.gyration_radius(scene)
        weight = scene.object_weight
        polys = kin.hand_polygons_local(scene)
        return Model(
            points=local.points,
            body=local.body,
            n_object=local.n_object,
            n_vertices=local.n_vertices,
            half=local.half,
            tol=self.tol,
            # Newton stops well inside the tolerance, but not below what doubles resolve
            newton_tol=max(1e-3 * self.tol, 64 * np.finfo(float).eps * L),
            ftol=1e-9 * weight,
            size=size,
            rho=rho,
            weight=weight,
            length=float(L),
            scale=np.array([1.0, 1.0, 1.0 / rho]),
            # moments per palm width: equilibrium rows and LP tolerances are unit-free
            per_length=np.array([1.0, 1.0, 1.0 / L]),
            gravity=mech.gravity_wrench(scene),
            max_step=self.max_step,
            fall_step=self.fall_step,
            max_iterations=self.max_iterations,
            max_solves=self.max_solves,
            # sweep bounds: how far any hand vertex lies from its body's frame origin (palm,
            # joints), and the thinnest of the bodies, which a step may not jump across
            reach=np.array([float(geo.norms(p).max()) for p in polys]),
            thinnest=float(
                min(
                    object_width(scene),
                    scene.palm.thickness,
                    *(f.thickness for f in scene.fingers),
                )
            ),
            reference_lp=self.lp_solver == "highs",
            python_lp=True,
        )

    @property
    def solves(self) -> int:
        """Pose solves (Newton runs) of the last call of :meth:`move_hand` or :meth:`settle`,
        its retry included: the work it took, in the unit of ``max_solves``."""
        return int(self._solves[0])

    # ------------------------------------------------------------------ public API
    def reset(self) -> State:
        """The scene's initial state; an object not held at its placement first falls to rest."""
        scene = self.scene
        return self.settle(scene.object.start_pose.copy(), scene.initial_hand)

    def settle(self, object_pose: np.ndarray, hand: np.ndarray) -> State:
        """State for a given object pose and hand configuration, after any fall to rest.

        Raises:
            ValueError: a start :meth:`check_start` refuses.
        """
        q = real_vector(object_pose, "object_pose", 3)
        h = real_vector(hand, "hand", 5)
        self.check_start(q, h)
        self._solves[0] = 0
        q, log = _compiled(move.settle, self.model, q, h, self._solves)
        return self._make_state(q, h, _events(log))

    def check_start(
        self, object_pose: np.ndarray, hand: np.ndarray, names: tuple = ("object_pose", "hand")
    ) -> None:
        """Refuse (``ValueError`` naming ``names``) a start the simulator does not move from:
        the object's or the palm's position beyond ``MAX_POSITION`` palm widths or angle
        beyond 2 pi in magnitude (the scene schema's bound), the fingers outside their joint
        limits, or the object or the hand entering the support or each other by more than the
        contact tolerance (the simulator moves bodies that touch; it does not separate
        overlapping ones)."""
        q_name, h_name = names
        w = self.scene.palm.width
        for name, position in ((q_name, object_pose[:2]), (h_name, hand[:2])):
            problem = coordinate_problem(position, name, w, MAX_POSITION)
            if problem:
                raise ValueError(problem)
        _check_angle(f"{q_name}[2]", object_pose[2])
        _check_angle(f"{h_name}[2]", hand[2])
        low, high = self.scene.joint_limits.T
        if np.any(hand[3:] < low) or np.any(hand[3:] > high):
            raise ValueError(
                f"{h_name}: finger angles {hand[3:].tolist()} outside the joint limits "
                f"{self.scene.joint_limits.tolist()}"
            )
        problem = kin.hand_placement_problem(self.scene, object_pose, hand, self.tol)
        if problem:
            raise ValueError(
                f"{q_name} {object_pose.tolist()} with {h_name} {hand.tolist()}: {problem}"
            )

    def check_state(self, state: State) -> None:
        """Refuse (``ValueError``) a state built by hand that the simulator does not move
        from: a start :meth:`check_start` refuses, or contacts other than those the
        simulator finds at its object pose and hand (the move takes a state's contacts as
        known: a mislabelled one would stop the hand with a false jam)."""
        q, h = state.object_pose.copy(), state.hand.copy()  # the compiled core's own arrays
        self.check_start(q, h, ("state.object_pose", "state.hand"))
        given = sorted(map(tuple, self._keys_of(state).tolist()))
        found = sorted(map(tuple, move.at_rest(self.model, q, h)[0].tolist()))
        if given != found:
            raise ValueError(
                f"state.contacts {given} (keys: body, kind, object_feature, hand_feature) are "
                f"not the contacts at the state's object pose and hand, {found}"
            )

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

        Raises:
            TypeError: ``state`` is not a :class:`~grasp_env.core.state.State`.
            ValueError: ``state`` is of another scene (a scene loaded again is another one);
                a state built by hand that :meth:`check_state` refuses; a palm angle beyond
                2 pi in magnitude; a palm target farther from the palm than
                :attr:`max_travel`.
            WorkLimitError: the move needs more than ``max_solves`` pose solves (or
                ``max_iterations`` increments, or stalls).
            SimulationError: a solve failed, and again on the reference LP path with smaller
                increments.
        """
        own_state(state, self.scene)
        if state._by_hand:  # a state this simulator made needs no check
            self.check_state(state)
        target = state.hand.tolist()
        if palm is not None:
            target[:3] = _finite_floats(palm, 3, "palm")
            _check_angle("palm[2]", target[2])
            self._check_travel(state.hand, target)
        joint_limit = False
        if fingers is not None:  # clipped to the joint limits
            f1, f2 = _finite_floats(fingers, 2, "fingers")
            (low1, low2), (high1, high2) = self._joint_low, self._joint_high
            target[3], target[4] = min(max(f1, low1), high1), min(max(f2, low2), high2)
            joint_limit = target[3] != f1 or target[4] != f2
        known = self._keys_of(state)
        out, log, keys, rows = self.move_arrays(  # the compiled core takes writeable arrays
            state.object_pose.copy(), state.hand.copy(), np.array(target), known
        )
        return self.state_from_move(state, out, log, keys, rows, joint_limit)

    @property
    def max_travel(self) -> float:
        """How far a move may take the palm, in palm widths (its position) or radians (its
        angle): the contact tolerance over 16 double-precision roundings. A move is followed
        along a path parameter in [0, 1], whose rounding moves the hand by the move's length
        times 2.2e-16; beyond this length that exceeds the contact tolerance, and the move's
        events could not be located (1e-9 / 3.6e-15, about 2.8e5 palm widths, at the default
        tolerance)."""
        return self.tol / self.scene.palm.width / (16 * EPS)

    def _check_travel(self, hand: np.ndarray, target: list) -> None:
        """Refuse (``ValueError`` naming ``palm``) a palm target beyond :attr:`max_travel`."""
        w = self.scene.palm.width
        travel = max(abs(target[0] - hand[0]) / w, abs(target[1] - hand[1]) / w,
                     abs(target[2] - hand[2]))  # fmt: skip
        if travel > self.max_travel:
            raise ValueError(
                f"palm target {target[:3]} lies {travel:.3g} palm widths (or radians) from the "
                f"palm {hand[:3].tolist()}, farther than a move can resolve at the contact "
                f"tolerance ({self.max_travel:.3g})"
            )

    def _keys_of(self, state: State) -> np.ndarray:
        """The contact keys of ``state`` as the compiled core takes them."""
        if state is self._last[0]:
            return self._last[1]  # a state this simulator made: its keys are at hand
        return np.array([c.key for c in state.contacts], dtype=np.int64).reshape(-1, 4)

    def state_from_move(
        self, state: State, out: np.ndarray, log: list, keys: np.ndarray, rows: np.ndarray,
        joint_limit: bool = False,
    ) -> State:  # fmt: skip
        """The :class:`State` a compiled move from ``state`` ended in:
        :func:`grasp_env.sim.move.run`'s ``out``, event ``log``, contact ``keys`` and
        ``rows``, with a ``"joint_limit"`` event first where the target's fingers were
        clipped. Where the move left the object untouched, the state keeps ``state``'s
        contacts."""
        s_reached, s_end, blocked, jammed, untouched = out[move.OUT_S :].tolist()
        events = [Event("joint_limit", 0.0)] if joint_limit else []  # clipped before it moves
        if log:
            events.extend(_events(log))
        # The hand is blocked by the support only if it got there (a jam may stop it first).
        blocked = bool(blocked) and not (jammed and s_reached < s_end)
        if blocked:
            events.append(Event("hand_blocked", s_end))
        q, h = out[move.OUT_Q], out[move.OUT_H]
        if untouched:  # the object and its contacts are as they were
            known = self._keys_of(state)
            new = self._new_state(q, h, state.contacts, known, events, False, blocked)
            if state._arrays is not None:
                keep_contact_arrays(new, *state._arrays)
            return new
        return self.make_state(q, h, keys, rows, events, bool(jammed), blocked)

    def move_arrays(self, q0: np.ndarray, h0: np.ndarray, h1: np.ndarray, known: np.ndarray):
        """A straight-line move from object pose ``q0`` and hand ``h0`` (touching the
        contacts ``known``, rows of keys) to the hand ``h1``, as the compiled core's arrays:
        :func:`grasp_env.sim.move.run`'s ``(out, log, keys, rows)``
        (:meth:`state_from_move` makes the state). Retried once on the reference LP path
        with a quarter of the increment and fall step if a solve fails (nothing of the failed
        attempt is kept); a second failure is reported."""
        self._solves[0] = 0
        try:
            return _compiled(move.run_packed, *self._packed, q0, h0, h1, known, True, self._solves)
        except WorkLimitError:
            raise  # the retry would do the same work again, and more
        except ComputationError as first:
            model = self.model
            careful = model._replace(
                reference_lp=True, max_step=model.max_step / 4, fall_step=model.fall_step / 4
            )
            try:
                return _compiled(
                    move.run_packed, *pack(careful), q0, h0, h1, _NO_KEYS, False,
                    self._solves,
                )  # fmt: skip
            except WorkLimitError:
                raise
            except ComputationError as second:
                raise SimulationError(
                    f"move failed ({first}) and again on the reference path with smaller "
                    f"increments ({second})"
                ) from second

    # ------------------------------------------------------------------ output
    def _make_state(self, q: np.ndarray, h: np.ndarray, events: list[Event]) -> State:
        return self.make_state(q, h, *move.at_rest(self.model, q, h), events)

    def make_state(
        self, q: np.ndarray, h: np.ndarray, keys: np.ndarray, rows: np.ndarray,
        events: list | tuple = (), jammed: bool = False, blocked: bool = False,
    ) -> State:  # fmt: skip
        """The :class:`State` of object pose ``q`` and hand ``h`` with the contacts the
        compiled core gives (:func:`grasp_env.sim.move.at_rest`: ``keys`` and ``rows`` of
        point, normal, gap and force), ``events`` and the flags of the move that led
        there."""
        points, normals = rows[:, move.ROW_POINT], rows[:, move.ROW_NORMAL]
        contacts = contacts_from_arrays(
            keys.tolist(), points, normals, rows[:, move.ROW_FORCE].tolist(),
            rows[:, move.ROW_GAP].tolist(),
        )  # fmt: skip
        state = self._new_state(q, h, contacts, keys, events, jammed, blocked)
        # the contacts' points and normals are views of these rows: kept as they are
        # (contact_arrays() hands out copies)
        return keep_contact_arrays(state, points, normals, keys[:, 0])

    def _new_state(self, q, h, contacts, keys, events, jammed, blocked) -> State:
        """The State, remembered with its contact keys for the next move from it."""
        state = new_state(self.scene, q, h, contacts, jammed, blocked, tuple(events))
        self._last = (state, keys)
        return state


def _compiled(kernel, *args):
    """Call a compiled kernel; its errors carry their message in pieces (compiled code
    cannot format strings), which are joined here."""
    try:
        return kernel(*args)
    except SimulationError as exc:
        if len(exc.args) > 1:
            raise type(exc)(" ".join(_piece(a) for a in exc.args)) from None
        raise


def _piece(value) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _events(log: list) -> list[Event]:
    """A compiled event log as :class:`~grasp_env.core.state.Event` objects."""
    return [
        Event(ev.NAMES[kind], s, tuple(ContactKey(*k) for k in keys.tolist()))
        for kind, s, keys in log
    ]


def own_state(state: State, scene: Scene) -> None:
    """Refuse anything but a state of ``scene`` (the very object: scenes compare by identity),
    naming both scenes."""
    require_state(state)
    if state.scene is not scene:
        raise ValueError(
            f"state is of scene {state.scene.name!r}, not of {scene.name!r}, the scene it is "
            "to move in (a scene loaded again is another scene)"
        )


def _check_angle(name: str, angle: float) -> None:
    """Refuse (``ValueError`` naming ``name``) an angle beyond 2 pi in magnitude, the scene
    schema's bound: a state the simulator makes is one it moves from again."""
    if not abs(angle) <= MAX_ANGLE:
        raise ValueError(f"{name} must be an angle within [-2 pi, 2 pi], got {float(angle)!r}")


def _finite_floats(value, size: int, name: str) -> tuple | list:
    """``value`` as ``size`` finite Python floats, or ``ValueError`` naming ``name``."""
    if type(value) is tuple and len(value) == size and all(type(x) is float for x in value):
        if all(map(math.isfinite, value)):  # the common case: a tuple of Python floats
            return value
    return real_vector(value, name, size).tolist()


__all__ = [
    "CONTACT_TOL_RANGE",
    "SimulationError",
    "Simulator",
    "WorkLimitError",
]
