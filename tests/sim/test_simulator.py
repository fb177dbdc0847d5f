"""Tests of :mod:`grasp_env.simulator` against independent computations.

Nothing here is checked against the simulator's own earlier output. Every returned state is
checked by :func:`assert_invariants` with :func:`grasp_env.testing.check_state`, which
rebuilds the world polygons of the object and of the hand from the conventions of
docs/conventions.md (not from :mod:`grasp_env.core.kinematics` or :mod:`grasp_env.core.geometry`),
measures penetration with its own separating-axis test, re-derives every contact's gap from
its point and normal, checks that every touching vertex-body pair is listed, sums the contact
forces for the object's equilibrium and solves the velocity LP ``min m g v_y s.t. V_ob v >=
0`` with :func:`scipy.optimize.linprog`; a jammed state must also make the hand's continued
motion impossible by an LP solved here (:func:`assert_jam_genuine`). The motions are
checked against closed forms (a block
tipping about a pivot, a square wedged between parallel fingertips, a hand lowered onto the
support), a finer run (tolerance and step convergence), the same move cut into pieces, and
the paper's section-4 experiment.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import itertools
import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.optimize import brentq, linprog

import grasp_env
from grasp_env import Simulator, State
from grasp_env.sim.events import FALL_END, FALL_START
from grasp_env.sim.increment import false_position
from grasp_env.simulator import WorkLimitError
from grasp_env.testing import check_state, cross, hand_polygons_W, rot

SCENES_DIR = Path(__file__).resolve().parents[2] / "grasp_env" / "scenes"
SCENES = (
    "fig13",
    "square",
    "heavy_square",
    "tall_rectangle",
    "triangle",
    "pentagon",
    "offset_pentagon",
    "hexagon",
    "flat_trapezoid",
)
HALF_PI = math.pi / 2
#: Accuracy of poses compared with closed forms or with the same move cut into pieces.
POSE_TOL = 1e-7
#: At a fold (a jam where the active contacts' Jacobian turns singular) the pose moves as the
#: square root of the hand's path parameter, so Newton's residual (1e-3 contact_tol) and the
#: location of the fold leave errors of order sqrt(1e-12) in the pose.
FOLD_POSE_TOL = 1e-5
#: Room for floating-point rounding on top of contact_tol when penetration is measured.
ROUNDING = 1e-14
#: Increment cap for long randomised or single big moves. The default (10000) turns a
#: simulator loop that makes no progress into minutes of run time before it raises; no
#: valid move in these tests needs more than a few dozen increments.
MAX_ITERATIONS = 400
#: Wall-clock limit of one hand move in the randomised sweeps (seconds). A move takes well
#: under a second; the slowest (square path 253, move 7: a fall whose Newton solves on an
#: over-determined contact set converge only linearly, then the retry on the reference path)
#: takes about 10 s on a busy 2-core machine; one that runs this long is stuck in a loop.
MOVE_TIME_LIMIT = 40.0
#: Wall-clock limit of any one test (seconds); the slowest passing test takes ~5 s.
TEST_TIME_LIMIT = 90.0


# ---------------------------------------------------------------------------------------
# Invariants of a returned state (grasp_env.testing: independent geometry and mechanics)
# ---------------------------------------------------------------------------------------


def fingertip_W(scene: grasp_env.Scene, hand: np.ndarray, finger: int) -> np.ndarray:
    """Tip ``T_i`` of finger ``finger`` (1 or 2) in the world."""
    xp, yp, thp = hand[:3]
    w = scene.palm.width
    J = np.array([(-w / 2) if finger == 1 else (w / 2), 0.0])
    q = hand[2 + finger]
    T = J + scene.fingers[finger - 1].length * np.array([math.cos(q), math.sin(q)])
    return rot(thp) @ T + np.array([xp, yp])


@dataclass
class Figures:
    """Worst values over the states of this module that passed every check (reported at the
    end of the module)."""

    states: int = 0
    penetration: float = -math.inf  # deepest overlap / palm width
    residual: float = 0.0  # worst equilibrium residual / weight
    gap: float = 0.0  # worst recomputed |gap| / palm width
    descent: float = 0.0  # most negative descent-LP optimum / weight
    where: dict = field(default_factory=dict)


FIGURES = Figures()


def assert_invariants(state: State, tol: float, where: str = "") -> None:
    """Check a returned state with :func:`grasp_env.testing.check_state` (geometry and
    mechanics recomputed independently of the simulator) and note its figures.

    Args:
        state: a state returned by the simulator.
        tol: the simulator's contact tolerance as a length (``contact_tol * palm width``).
        where: text naming the state (seed, move) for failure messages.
    """
    assert state.object_pose.shape == (3,) and state.hand.shape == (5,)
    np.testing.assert_array_equal(state.palm_pose, state.hand[:3])
    np.testing.assert_array_equal(state.finger_angles, state.hand[3:])
    chk = check_state(state.scene, state.object_pose, state.hand, state.contacts, tol)
    assert not chk.violations, f"{where}: " + "; ".join(chk.violations)
    FIGURES.states += 1
    for name, larger_is_worse in (
        ("penetration", True), ("gap", True), ("residual", True), ("descent", False),
    ):  # fmt: skip
        value, old = getattr(chk, name), getattr(FIGURES, name)
        if (value > old) if larger_is_worse else (value < old):
            setattr(FIGURES, name, value)
            FIGURES.where[name] = where


#: A jam must be genuine: the hand's continued motion needs an object velocity at least this
#: many times the hand's contact-point speeds (infinite when the velocity LP is infeasible,
#: ~1e6 and more within tolerance of a fold), never a moderate one.
JAM_SPEED_RATIO = 1e3


def hand_point_velocity(
    scene: grasp_env.Scene, hand: np.ndarray, dh: np.ndarray, body: str, p: np.ndarray
) -> np.ndarray:
    """Velocity of the material point of hand ``body`` at world point ``p`` for a hand rate
    ``dh``, by central differences of that point carried along by the body's frame (joint at
    ``J_i`` turned by ``theta_p + q_i``; the palm frame for the palm)."""

    def frame(h: np.ndarray) -> tuple[np.ndarray, float]:
        xp, yp, thp, q1, q2 = h
        o = np.array([xp, yp])
        if body == "palm":
            return o, thp
        jx = (-0.5 if body == "finger1" else 0.5) * scene.palm.width
        return o + rot(thp) @ np.array([jx, 0.0]), thp + (q1 if body == "finger1" else q2)

    o, a = frame(hand)
    local = rot(a).T @ (p - o)
    eps = 1e-6
    ends = []
    for sgn in (1.0, -1.0):
        o2, a2 = frame(hand + sgn * eps * dh)
        ends.append(o2 + rot(a2) @ local)
    return (ends[0] - ends[1]) / (2 * eps)


def assert_jam_genuine(state: State, dh: np.ndarray, where: str) -> None:
    """A jammed state's contacts must forbid the hand's continued motion ``dh``: the velocity
    LP ``V_ob v >= xi`` (``xi_i = n_i . v_hand(p_i)``, eqs. 19-21) is infeasible, or it needs
    an object velocity ``JAM_SPEED_RATIO`` times the hand's (a fold). Solved here as
    ``min t s.t. V v >= xi, |v| <= t`` (twists scaled by the object size)."""
    scene = state.scene
    size = float(np.linalg.norm(scene.object.vertices_B, axis=1).max())
    com = state.object_pose[:2]
    V = np.array([[*c.normal, cross(c.point - com, c.normal) / size] for c in state.contacts])
    xi = np.array(
        [
            0.0
            if c.body == "support"
            else float(c.normal @ hand_point_velocity(scene, state.hand, dh, c.body, c.point))
            for c in state.contacts
        ]
    )
    tight = {"primal_feasibility_tolerance": 1e-10}
    free = [(None, None)] * 3
    feasible = linprog(np.zeros(3), A_ub=-V, b_ub=-xi, bounds=free, options=tight)
    if feasible.status not in (0, 2):  # HiGHS can end "unknown" at the tight tolerance
        feasible = linprog(np.zeros(3), A_ub=-V, b_ub=-xi, bounds=free)
    if feasible.status == 2:
        return  # the hand cannot go on: a genuine jam
    assert feasible.status == 0, f"{where}: jam feasibility LP: {feasible.message}"
    box = np.vstack([np.hstack([sgn * np.eye(3), -np.ones((3, 1))]) for sgn in (1.0, -1.0)])
    res = linprog(
        [0.0, 0.0, 0.0, 1.0],
        A_ub=np.vstack([np.hstack([-V, np.zeros((len(V), 1))]), box]),
        b_ub=np.concatenate([-xi, np.zeros(6)]),
        bounds=[*free, (0, None)],
    )
    # The feasible point bounds the least speed from above if the second LP stalls.
    least = res.fun if res.status == 0 else float(np.abs(feasible.x).max())
    speed = max(float(np.abs(xi).max()), 1e-12)
    assert least >= JAM_SPEED_RATIO * speed, (
        f"{where}: jammed, but the hand could go on with the object moving at {least:.3g} "
        f"(hand contact speed {speed:.3g}; contacts {contact_set(state)})"
    )


def assert_on_path(h0: np.ndarray, h1: np.ndarray, state: State, tol: float, msg: str) -> None:
    """The hand ends on the straight line from ``h0`` to ``h1``; at ``h1`` unless it stopped."""
    dh = h1 - h0
    h = state.hand
    if not np.any(dh):
        np.testing.assert_allclose(h, h0, atol=1e-12, err_msg=msg)
        return
    s = float((h - h0) @ dh / (dh @ dh))
    assert -1e-12 <= s <= 1 + 1e-12, msg + f"hand went outside the move (s = {s})"
    np.testing.assert_allclose(h, h0 + s * dh, atol=1e-9, err_msg=msg + "hand off the line")
    if not (state.jammed or state.hand_blocked):
        np.testing.assert_allclose(h, h1, atol=1e-12, err_msg=msg + "hand short of target")
    for e in state.events:
        assert -1e-12 <= e.s <= 1 + 1e-12, msg + f"event {e} outside [0, 1]"


@pytest.fixture(scope="module", autouse=True)
def _report_figures(request: pytest.FixtureRequest) -> Iterator[None]:
    """Print the worst invariant figures over the module's states (shown even with -q)."""
    yield
    if not FIGURES.states:
        return
    line = (
        f"\ntest_simulator invariants over {FIGURES.states} valid states: worst penetration "
        f"{FIGURES.penetration:.2e} x palm width ({FIGURES.where.get('penetration')}); worst "
        f"|gap| {FIGURES.gap:.2e} x palm width; worst equilibrium residual "
        f"{FIGURES.residual:.2e} x weight ({FIGURES.where.get('residual')}); most negative "
        f"descent-LP optimum {FIGURES.descent:.2e} x weight"
    )
    capman = request.config.pluginmanager.getplugin("capturemanager")
    ctx = capman.global_and_fixture_disabled() if capman else contextlib.nullcontext()
    with ctx:
        print(line)


# ---------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------


@cache
def scene_of(name: str) -> grasp_env.Scene:
    return grasp_env.load_scene(name)


def raw_scene(name: str) -> dict:
    return yaml.safe_load((SCENES_DIR / f"{name}.yaml").read_text())


def tol_of(sim: Simulator, contact_tol: float = 1e-9) -> float:
    return contact_tol * sim.scene.palm.width


def contact_set(state: State) -> list[tuple[str, str]]:
    return sorted((c.body, c.kind) for c in state.contacts)


class MoveTimeout(Exception):
    """A hand move ran longer than :data:`MOVE_TIME_LIMIT`."""


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`MoveTimeout` inside the block after ``seconds`` of wall time (Unix main
    thread; a no-op elsewhere). Nests: an enclosing limit keeps running, minus the time
    spent inside."""
    if not hasattr(signal, "setitimer"):
        yield
        return

    def _raise(signum: int, frame: object) -> None:
        raise MoveTimeout(f"still running after {seconds} s")

    outer_left = signal.getitimer(signal.ITIMER_REAL)[0]
    start = time.monotonic()
    old = signal.signal(signal.SIGALRM, _raise)
    signal.setitimer(signal.ITIMER_REAL, min(seconds, outer_left) if outer_left else seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)
        if outer_left:
            signal.setitimer(signal.ITIMER_REAL, max(outer_left - (time.monotonic() - start), 1e-3))


@pytest.fixture(autouse=True)
def _test_time_limit() -> Iterator[None]:
    """No test may hang: a simulator loop without progress fails the test instead."""
    with time_limit(TEST_TIME_LIMIT):
        yield


def equal_rate_targets(state: State, dq: float) -> tuple[float, float]:
    q1, q2 = state.finger_angles
    return float(q1 + dq), float(q2 - dq)


# ---------------------------------------------------------------------------------------
# 0. The initial states
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SCENES, ids=SCENES)
def test_reset_rests_on_support(name: str) -> None:
    """Each bundled object starts at rest on its base edge: pose = scene placement, two
    support contacts at the base vertices, forces by the lever rule."""
    scene = scene_of(name)
    sim = Simulator(scene)
    state = sim.reset()
    assert_invariants(state, tol_of(sim), f"{name} reset")
    np.testing.assert_allclose(state.object_pose, scene.object.start_pose, atol=1e-12)
    np.testing.assert_allclose(state.hand, scene.initial_hand, atol=0)
    assert not state.jammed and not state.hand_blocked
    base = raw_scene(name)["object"]["vertices"]
    feet = sorted(p[0] for p in base if abs(p[1]) < 1e-12)
    assert contact_set(state) == [("support", "edge")] * 2
    xs = sorted(float(c.point[0]) for c in state.contacts)
    np.testing.assert_allclose(xs, feet, atol=1e-12)
    # Lever rule about the COM: c_left (x_c - a) = c_right (b - x_c), c_left + c_right = W.
    a, b = feet
    xc = scene.object.start_pose[0]
    W = scene.object_weight
    expected = {a: W * (b - xc) / (b - a), b: W * (xc - a) / (b - a)}
    for c in state.contacts:
        assert c.force == pytest.approx(expected[min(expected, key=lambda x: abs(x - c.point[0]))])


# ---------------------------------------------------------------------------------------
# 2. Randomised hand paths on the bundled scenes
# ---------------------------------------------------------------------------------------


def random_path(rng: np.random.Generator, start: np.ndarray) -> list[tuple[np.ndarray, bool]]:
    """5-20 hand targets from ``start``: finger increments |dq| <= 0.15 biased towards closing
    (finger 1 up, finger 2 down), and on about half the moves a palm increment with
    |dx|, |dy| <= 0.05 and |dtheta| <= 0.1. Returns ``(target, palm_moves)`` pairs."""
    h = np.array(start, dtype=float)
    out = []
    for _ in range(int(rng.integers(5, 21))):
        close = rng.uniform(-0.05, 0.15, size=2)
        h = h.copy()
        h[3] += close[0]
        h[4] -= close[1]
        moves_palm = bool(rng.random() < 0.5)
        if moves_palm:
            h[:3] += rng.uniform([-0.05, -0.05, -0.1], [0.05, 0.05, 0.1])
        out.append((h, moves_palm))
    return out


def run_random_path(path_index: int, seed: int = 20240611) -> None:
    """Path ``path_index`` of the sweep: scene ``SCENES[path_index % 9]``, its own seed."""
    name = SCENES[path_index % len(SCENES)]
    rng = np.random.default_rng([seed, path_index])
    sim = Simulator(scene_of(name), max_iterations=MAX_ITERATIONS)
    tol = tol_of(sim)
    state = sim.reset()
    assert_invariants(state, tol, f"{name} path {path_index} reset")
    for m, (target, moves_palm) in enumerate(random_path(rng, state.hand)):
        where = f"{name} path {path_index} move {m} target {target.tolist()}"
        h0 = state.hand.copy()
        # Targets are relative to the planned path, not to where the hand stopped.
        palm = target[:3] if moves_palm else None
        try:
            with time_limit(MOVE_TIME_LIMIT):
                new = sim.move_hand(state, palm=palm, fingers=target[3:])
        except Exception as exc:  # the simulator must never raise for a valid move
            pytest.fail(f"{where}: move_hand raised {exc!r} from hand {h0.tolist()}")
        h1 = h0.copy()
        if moves_palm:
            h1[:3] = target[:3]
        lim = sim.scene.joint_limits
        h1[3:] = np.clip(target[3:], lim[:, 0], lim[:, 1])
        assert_on_path(h0, h1, new, tol, where + ": ")
        assert_invariants(new, tol, where)
        if new.jammed:
            assert_jam_genuine(new, h1 - h0, where)
        state = new


N_DEFAULT_PATHS = 27  # 3 per bundled scene
N_SLOW_PATHS = 300


def path_params(indices: range) -> list:
    return [pytest.param(i, id=f"path{i}-{SCENES[i % len(SCENES)]}") for i in indices]


@pytest.mark.parametrize("path_index", path_params(range(N_DEFAULT_PATHS)))
def test_random_paths(path_index: int) -> None:
    """Random hand paths keep every returned state valid and never raise."""
    run_random_path(path_index)


@pytest.mark.slow
@pytest.mark.parametrize(
    "path_index", path_params(range(N_DEFAULT_PATHS, N_DEFAULT_PATHS + N_SLOW_PATHS))
)
def test_random_paths_sweep(path_index: int) -> None:
    """The same check on 300 more paths (``pytest -m slow``)."""
    run_random_path(path_index)


# ---------------------------------------------------------------------------------------
# 3. Closed form: a finger tips a block about a blocked corner
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TipScene:
    """A 0.2 x 0.4 block on the support, x in [-0.1, 0.1]; palm at (0, 0.6, 0).

    Finger 2 (held still) has its tip ``T2`` on the block's right side at height 0.05;
    finger 1 (length 0.5) starts 0.05 rad open of touching the left side at height 0.3.
    Closing finger 1 presses the left side above ``T2``: the block cannot slide (``T2``) and
    must turn clockwise with its bottom-right corner sliding on the support and its right
    side sliding on ``T2``. With those two contacts kept, the pose is a function of the angle
    ``theta`` alone (:meth:`pose`), and ``theta`` follows from finger 1's contact:

    * phase A: finger 1's tip on the block's left side;
    * phase B: once the tip passes the top-left corner, that corner on finger 1's end face
      (the short edge at the tip, outward normal ``u_1``);
    * phase C: once the corner slides off the end face's far end, nothing holds the block up
      on the left and it falls back flat against ``T2``: pose ``(0, 0.2, 0)``.

    Forces: with ``T2``'s normal opposite to finger 1's (phase A) the fingers form a couple and
    the support carries the whole weight; they are positive while finger 1's contact is higher
    on the block than ``T2`` and the centre of mass is left of the support corner
    (``theta > -atan(0.1 / 0.2)``), which holds on the whole path.
    """

    hw: float = 0.1
    hh: float = 0.2
    yp: float = 0.6
    t2: tuple[float, float] = (0.1, 0.05)
    l1: float = 0.5
    thickness: float = 0.05
    open_by: float = 0.05

    @property
    def J1(self) -> np.ndarray:
        return np.array([-0.5, self.yp])

    @property
    def T2(self) -> np.ndarray:
        return np.array(self.t2)

    @property
    def q1_touch(self) -> float:
        return -math.acos((-self.hw - self.J1[0]) / self.l1)  # tip on x = -hw, below J1

    @property
    def q2(self) -> float:
        d = self.T2 - np.array([0.5, self.yp])
        return math.atan2(d[1], d[0])

    def scene_dict(self) -> dict:
        l2 = float(np.linalg.norm(self.T2 - np.array([0.5, self.yp])))
        return {
            "name": "tip_block",
            "gravity": 9.81,
            "palm": {"width": 1.0, "thickness": 0.15, "pose": [0.0, self.yp, 0.0]},
            "fingers": [
                {"length": self.l1, "thickness": self.thickness,
                 "angle": self.q1_touch - self.open_by},
                {"length": l2, "thickness": self.thickness, "angle": self.q2},
            ],
            "object": {
                "vertices": [
                    [-self.hw, 0.0], [self.hw, 0.0], [self.hw, 2 * self.hh], [-self.hw, 2 * self.hh]
                ]
            },
        }  # fmt: skip

    def pose(self, theta: float) -> np.ndarray:
        """Pose with the bottom-right corner on y = 0 and the right side through ``T2``."""
        R = rot(theta)
        vx = self.T2[0] + self.T2[1] * math.tan(theta)  # corner (vx, 0); T2 on the side
        c = np.array([vx, 0.0]) - R @ np.array([self.hw, -self.hh])
        return np.array([c[0], c[1], theta])

    def corner(self, theta: float, local: tuple[float, float]) -> np.ndarray:
        p = self.pose(theta)
        return p[:2] + rot(theta) @ np.array(local)

    def tip1(self, q1: float) -> np.ndarray:
        return self.J1 + self.l1 * np.array([math.cos(q1), math.sin(q1)])

    def phase_a_gap(self, theta: float, q1: float) -> float:
        """Signed distance of finger 1's tip outside the left side (inward normal R e_x)."""
        bl = self.corner(theta, (-self.hw, -self.hh))
        return -float(rot(theta)[:, 0] @ (self.tip1(q1) - bl))

    def phase_b_gap(self, theta: float, q1: float) -> float:
        """Signed distance of the top-left corner outside finger 1's end face (normal u_1)."""
        u1 = np.array([math.cos(q1), math.sin(q1)])
        return float(u1 @ (self.corner(theta, (-self.hw, self.hh)) - self.tip1(q1)))

    def theta_a(self, q1: float) -> float:
        return brentq(lambda t: self.phase_a_gap(t, q1), -0.46, 0.0, xtol=1e-15, rtol=1e-15)

    def theta_b(self, q1: float) -> float:
        return brentq(lambda t: self.phase_b_gap(t, q1), -0.46, 0.0, xtol=1e-15, rtol=1e-15)

    def height_on_left_side(self, q1: float) -> float:
        th = self.theta_a(q1)
        bl = self.corner(th, (-self.hw, -self.hh))
        return float(rot(th)[:, 1] @ (self.tip1(q1) - bl))

    def along_end_face(self, q1: float) -> float:
        """How far the top-left corner sits from the tip along finger 1's end face."""
        n1 = np.array([-math.sin(q1), math.cos(q1)])
        return float(-n1 @ (self.corner(self.theta_b(q1), (-self.hw, self.hh)) - self.tip1(q1)))

    @cache  # noqa: B019 - a frozen, hashable dataclass; a handful of instances
    def switches(self) -> tuple[float, float]:
        """Finger 1 angles where phase A turns into B and B into C."""
        lo = self.q1_touch + 1e-3
        a_to_b = brentq(lambda q: self.height_on_left_side(q) - 2 * self.hh, lo, lo + 0.5)
        b_to_c = brentq(lambda q: self.along_end_face(q) - self.thickness, a_to_b, a_to_b + 0.3)
        return a_to_b, b_to_c

    def expected(self, q1: float) -> tuple[np.ndarray, str]:
        a_to_b, b_to_c = self.switches()
        if q1 <= self.q1_touch:
            return self.pose(0.0), "rest"
        if q1 < a_to_b:
            return self.pose(self.theta_a(q1)), "A"
        if q1 < b_to_c:
            return self.pose(self.theta_b(q1)), "B"
        return self.pose(0.0), "C"


TIP = TipScene()
TIP_CONTACTS = {
    "rest": [("finger2", "tip"), ("support", "edge"), ("support", "edge")],
    "A": [("finger1", "tip"), ("finger2", "tip"), ("support", "edge")],
    "B": [("finger1", "edge"), ("finger2", "tip"), ("support", "edge")],
    "C": [("finger2", "tip"), ("support", "edge"), ("support", "edge")],
}


def test_tip_scene_closed_form_is_consistent() -> None:
    """Sanity of the derivation itself: the phases follow each other, the block turns less
    than its tipping angle, and the pose is continuous at the A -> B switch."""
    a_to_b, b_to_c = TIP.switches()
    assert TIP.q1_touch < a_to_b < b_to_c < 0.0
    np.testing.assert_allclose(TIP.theta_a(a_to_b), TIP.theta_b(a_to_b), atol=1e-9)
    for q1 in np.linspace(TIP.q1_touch + 1e-3, b_to_c, 50, endpoint=False):
        pose, _ = TIP.expected(q1)
        assert -math.atan(TIP.hw / TIP.hh) < pose[2] < 0.0
    # Finger 1 contact above T2 (positive couple) and the corner still on T2's side.
    assert TIP.height_on_left_side(TIP.q1_touch + 1e-3) > TIP.T2[1]


def run_tip_path(dq_values: np.ndarray) -> list[tuple[float, State]]:
    sim = Simulator(TIP.scene_dict())
    state = sim.reset()
    assert_invariants(state, tol_of(sim), "tip reset")
    out = []
    for q1 in TIP.q1_touch - TIP.open_by + dq_values:
        state = sim.move_hand(state, fingers=(float(q1), TIP.q2))
        assert_invariants(state, tol_of(sim), f"tip q1 = {q1}")
        out.append((float(q1), state))
    return out


def test_block_tips_about_blocked_corner() -> None:
    """The simulated block follows the closed-form pose (phases A, B, C) to 1e-7."""
    a_to_b, b_to_c = TIP.switches()
    q0 = TIP.q1_touch - TIP.open_by
    grid = np.array([0.02, 0.06, 0.08, 0.1, 0.13, 0.16, 0.2, 0.24, 0.27])
    grid = np.concatenate([grid, [a_to_b - q0 + 0.005, a_to_b - q0 + 0.03, a_to_b - q0 + 0.07]])
    grid = np.concatenate([grid, [b_to_c - q0 + 0.01, b_to_c - q0 + 0.1]])
    phases_seen = []
    for q1, state in run_tip_path(grid):
        pose, phase = TIP.expected(q1)
        phases_seen.append(phase)
        np.testing.assert_allclose(
            state.object_pose, pose, atol=POSE_TOL, err_msg=f"q1 = {q1} (phase {phase})"
        )
        assert contact_set(state) == TIP_CONTACTS[phase], f"q1 = {q1} (phase {phase})"
        assert not state.jammed
    assert phases_seen[0] == "rest" and {"A", "B", "C"} <= set(phases_seen)


def test_block_tipping_events() -> None:
    """Crossing each switch reports it: touching (new contact), the tip passing the corner
    (the finger-1 contact turns from tip to edge kind), and the corner leaving the end face
    (edge to tip) followed by the fall back onto the support."""
    a_to_b, b_to_c = TIP.switches()
    q0 = TIP.q1_touch - TIP.open_by
    steps = [TIP.open_by + 0.01, a_to_b - q0 + 0.01, b_to_c - q0 + 0.01]
    kinds = [[e.kind for e in st.events] for _, st in run_tip_path(np.array(steps))]
    assert "new_contact" in kinds[0]
    assert "tip_to_edge" in kinds[1]
    assert "edge_to_tip" in kinds[2] and "fall_start" in kinds[2] and "fall_end" in kinds[2]
    for k in kinds:
        assert "jam" not in k


# ---------------------------------------------------------------------------------------
# 4. One move versus the same move cut into ten
# ---------------------------------------------------------------------------------------


def split_move(sim: Simulator, state: State, target: np.ndarray, pieces: int) -> State:
    """Reach hand ``target`` from ``state`` in ``pieces`` equal straight moves."""
    h0 = state.hand.copy()
    for k in range(1, pieces + 1):
        h = h0 + (target - h0) * (k / pieces)
        state = sim.move_hand(state, palm=h[:3], fingers=h[3:])
        assert_invariants(state, tol_of(sim), f"piece {k}/{pieces}")
    return state


def tip_state_at(dq: float) -> tuple[Simulator, State]:
    sim = Simulator(TIP.scene_dict())
    state = sim.reset()
    q1 = TIP.q1_touch - TIP.open_by + dq
    return sim, sim.move_hand(state, fingers=(q1, TIP.q2))


def test_contact_arrays_are_the_contacts() -> None:
    """``State.contact_arrays`` (kept from the simulator's arrays) equals the contacts' own
    points, normals and bodies, moved or untouched, returns new arrays each call, and a copy
    of the state with other contacts (``dataclasses.replace``) gives the new contacts'."""
    import dataclasses

    from grasp_env.core.geometry import BODY_NAMES

    sim = Simulator(scene_of("fig13"))
    state = sim.reset()
    states = [state]
    for dq in (0.3, 0.3, 0.3, 0.2, 0.0):  # closing until the fingers touch; then untouched
        state = sim.move_hand(state, fingers=state.finger_angles + np.array([dq, -dq]))
        states.append(state)
    assert any(c.body.startswith("finger") for c in states[-1].contacts)
    for st in states:
        points, normals, bodies = st.contact_arrays()
        np.testing.assert_array_equal(points, [c.point for c in st.contacts])
        np.testing.assert_array_equal(normals, [c.normal for c in st.contacts])
        np.testing.assert_array_equal(bodies, [BODY_NAMES.index(c.body) for c in st.contacts])
        points[:] = np.nan  # a caller's array, not the state's
        assert np.isfinite(st.contact_arrays()[0]).all()
    fewer = dataclasses.replace(states[-1], contacts=states[-1].contacts[:1])
    points, _, bodies = fewer.contact_arrays()
    np.testing.assert_array_equal(points, [states[-1].contacts[0].point])
    assert bodies.shape == (1,)


def test_simulator_states_are_the_constructors() -> None:
    """The simulator fills its states in directly (``new_state``); each is the State the
    constructor makes from its fields: equal field by field, frozen, copied by
    ``dataclasses.replace``, pickled and compared as one."""
    import dataclasses
    import pickle

    sim = Simulator(scene_of("fig13"))
    state = sim.reset()
    for dq in (0.3, 0.3, 0.3, 0.2):
        state = sim.move_hand(state, fingers=state.finger_angles + np.array([dq, -dq]))
        names = [f.name for f in dataclasses.fields(State) if f.init]
        made = State(**{name: getattr(state, name) for name in names})
        # the simulator's keeps its contact arrays; the constructor's says it was built
        assert set(vars(made)) - {"_by_hand"} == set(vars(state)) - {"_arrays"}
        assert made._by_hand and not state._by_hand
        for name in names:
            if name in ("object_pose", "hand"):  # the constructor's copies
                np.testing.assert_array_equal(getattr(made, name), getattr(state, name))
            else:
                assert getattr(made, name) is getattr(state, name)
        with pytest.raises(dataclasses.FrozenInstanceError):
            state.jammed = True
        copied = dataclasses.replace(state)
        assert copied.contacts is state.contacts and copied._arrays is None
        again = pickle.loads(pickle.dumps(state))
        np.testing.assert_array_equal(again.object_pose, state.object_pose)
        arrays = [again.object_pose, again.hand, *(c.point for c in again.contacts)]
        assert not any(a.flags.writeable for a in arrays) and not again._by_hand
        assert [c.key for c in again.contacts] == [c.key for c in state.contacts]
        assert repr(made) == repr(state)


def test_one_move_equals_ten_without_events() -> None:
    """Inside phase A of the tipping block (no event between), one move and ten equal moves
    end in the same state, and both on the closed form."""
    a_to_b, _ = TIP.switches()
    sim, start = tip_state_at(TIP.open_by + 0.03)
    target = start.hand.copy()
    target[3] = a_to_b - 0.02
    one = sim.move_hand(start, palm=target[:3], fingers=target[3:])
    assert [e.kind for e in one.events] == []
    ten = split_move(sim, start, target, 10)
    assert_invariants(one, tol_of(sim), "one move")
    np.testing.assert_allclose(one.object_pose, ten.object_pose, atol=POSE_TOL)
    np.testing.assert_allclose(one.hand, ten.hand, atol=1e-12)
    np.testing.assert_allclose(one.object_pose, TIP.expected(target[3])[0], atol=POSE_TOL)
    assert contact_set(one) == contact_set(ten)


ONE_VS_TEN_EVENTS = [
    # id, scene, palm target or None, finger increment (closing, equal rates)
    pytest.param("tip", None, None, id="tip_block_all_phases"),
    pytest.param("fig13", None, 0.45, id="fig13_first_contacts"),
    pytest.param("fig13", (0.03, 0.69, 0.05), 0.42, id="fig13_palm_and_fingers"),
    pytest.param("square", None, 0.7, id="square_squeezed"),
]


@pytest.mark.parametrize(("name", "palm", "dq"), ONE_VS_TEN_EVENTS)
def test_one_move_equals_ten_through_events(
    name: str, palm: tuple | None, dq: float | None
) -> None:
    """Through events (new contacts, tip/edge switches, falls) the final state should still
    not depend on how the move is cut: quasi-static frictionless motion with three
    independent active contacts is a function of the hand configuration. (square_squeezed
    ends in a jam at a fold; before commit df3bcc2 the single move raised SimulationError
    'no progress' there.)"""
    if name == "tip":
        sim = Simulator(TIP.scene_dict())
        start = sim.reset()
        target = start.hand.copy()
        target[3] = TIP.switches()[1] + 0.05
    else:
        sim = Simulator(scene_of(name), max_iterations=MAX_ITERATIONS)
        start = sim.reset()
        target = start.hand.copy()
        if palm is not None:
            target[:3] = palm
        target[3] += dq
        target[4] -= dq
    one = sim.move_hand(start, palm=target[:3], fingers=target[3:])
    assert_invariants(one, tol_of(sim), f"{name} one move")
    ten = split_move(sim, start, target, 10)
    events_one = [e.kind for e in one.events]
    assert events_one, "the case should cross events"
    assert one.jammed == ten.jammed
    np.testing.assert_allclose(one.hand, ten.hand, atol=1e-9)
    np.testing.assert_allclose(
        one.object_pose,
        ten.object_pose,
        atol=FOLD_POSE_TOL if one.jammed else POSE_TOL,
        err_msg=f"events {events_one}",
    )
    assert contact_set(one) == contact_set(ten)


def test_contact_lost_again_and_again_is_dropped() -> None:
    """Regression (found by the planner's exploratory search on tall_rectangle): the object
    leans on finger 1's tip, finger 2's tip and the support while the palm turns, wedged
    with forces near 7e5 weights. Near s = 0.5 finger 2's force touches zero; the re-planned
    active set kept the contact, whose force fell to zero again 5e-7 further on, and so on:
    10000 increments and 500 s later the move raised SimulationError 'no progress'. Whether
    the force dips below zero at all is decided by rounding there, so the move must simply
    end after a bounded number of increments, valid, also when cut in 50 pieces. Every
    increment makes at least one pose solve, so the 10000 increments of the bug would show as
    as many solves."""
    sim, start, target = _turned_wedge()
    one = sim.move_hand(start, palm=target[:3], fingers=target[3:])
    assert_invariants(one, tol_of(sim), "turned palm")
    assert sim.solves <= 1000, f"{sim.solves} pose solves for one move"
    fifty = split_move(sim, start, target, 50)
    assert_invariants(fifty, tol_of(sim), "turned palm, 50 pieces")


def _turned_wedge() -> tuple[Simulator, State, np.ndarray]:
    sim = Simulator(scene_of("tall_rectangle"), max_iterations=MAX_ITERATIONS)
    pose = np.array([0.01998986868443757, 0.25615743936771634, -0.09837377974016227])
    hand = np.array([0.16, 0.77, -0.12, -0.9547500768881969, -2.373256222405706])
    start = sim.settle(pose, hand)
    assert contact_set(start) == [("finger1", "tip"), ("finger2", "tip"), ("support", "edge")]
    target = hand.copy()
    target[2] = -0.16
    return sim, start, target


@pytest.mark.xfail(
    strict=True,
    reason="the fingertips pinch the object exactly one width apart (to 6e-13): the pinch "
    "sits on the fold of its two orientations throughout the turn, and whether its forces "
    "(about 1e6 weights, one over a vanishing determinant) change sign is rounding; one long "
    "move follows the palm, the 50 short ones jam (docs/reliability.md)",
)
def test_a_wedge_turned_in_one_move_or_fifty_ends_alike() -> None:
    sim, start, target = _turned_wedge()
    one = sim.move_hand(start, palm=target[:3], fingers=target[3:])
    fifty = split_move(sim, start, target, 50)
    np.testing.assert_allclose(one.hand, fifty.hand, atol=1e-12)
    np.testing.assert_allclose(one.object_pose, fifty.object_pose, atol=FOLD_POSE_TOL)
    assert contact_set(one) == contact_set(fifty)


def test_events_cycling_at_one_point_end_the_move_early() -> None:
    """Regression (found by the planner's exploratory search on tall_rectangle): the object
    hangs on finger 1's tip and finger 2's link (force 0.012 weights) while the palm turns.
    At s = 0.41 finger 2's force reaches zero; the hand nudged just past the boundary of
    equilibrium leaves the object unheld, yet the fall from there finds no way down, and the
    move nudged on by 1e-10 again and again: first 10000 increments (200 s and more), later
    a WorkLimitError once its 5000 pose solves were spent. A nudge whose fall does not move
    the object finds nothing consistent ahead, so the hand stops there: a jam, in a few
    dozen solves, in a state that the independent check finds held with no admissible
    descent."""
    sim = Simulator(scene_of("tall_rectangle"))
    pose = np.array([0.46190532803701934, 0.7809275521238297, -0.01407965548935421])
    hand = np.array([0.16, 0.81, 0.9500000000000003, -0.7355228284215352, -2.07378577100814])
    start = sim.settle(pose, hand)
    end = sim.move_hand(start, palm=(0.16, 0.81, 1.0000000000000002))
    assert end.jammed and 0.95 < end.hand[2] < 1.0
    assert sim.solves <= 1000, f"{sim.solves} pose solves for one move"
    assert_invariants(end, tol_of(sim), "jammed at the boundary of equilibrium")


def soak_scene(palm_x: float, vertices: list, density: float) -> dict:
    """A scene as the soak draws it: fig13's palm at ``palm_x`` with the fingers hanging
    straight down, and the object ``vertices`` at ``density``."""
    return {
        "name": "stress",
        "palm": {"width": 1.0, "thickness": 0.15, "pose": [palm_x, 0.71, 0.0]},
        "fingers": [
            {"length": 0.6, "thickness": 0.05, "angle": -HALF_PI},
            {"length": 0.7, "thickness": 0.05, "angle": -HALF_PI},
        ],
        "object": {"vertices": vertices, "density": density},
    }


def settled_where_soaked(
    scene: dict, pose: list, hand: list, contacts: list
) -> tuple[Simulator, State]:
    """The simulator of a soak's ``scene`` and its state before a failing move: settled at
    ``pose`` and ``hand`` without moving, touching by ``contacts``, every invariant
    holding."""
    sim = Simulator(grasp_env.load_scene(scene))
    start = sim.settle(np.array(pose), np.array(hand))
    np.testing.assert_array_equal(start.object_pose, pose)
    assert contact_set(start) == contacts
    assert_invariants(start, tol_of(sim), "before the move")
    return sim, start


#: A near-circle (soak seed 6, shape 365), its palm, fingers and density as the soak drew them.
NEAR_CIRCLE = soak_scene(
    -0.0015772888424103182,
    [
        [-0.11576337377032639, 0.0],
        [0.11617343576038054, 0.0],
        [0.2713351263086484, 0.1289507295288007],
        [0.3068071123689645, 0.34655963305504983],
        [0.19084762596457164, 0.5224265676235489],
        [0.009861035236314881, 0.5845544149100176],
        [-0.2072278433058991, 0.5089948566345823],
        [-0.30996169005378515, 0.3275620194895235],
        [-0.2716341305863059, 0.13019381848052708],
    ],
    0.0024925981749921626,
)


def test_a_fall_does_not_come_back_to_a_potential_maximum() -> None:
    """Regression (soak seed 6, shape 365, step 506): a near-circle held by a vertex on each
    finger's face and one on the palm while the hand moves. At s = 0.098 the palm's force
    reaches zero; keeping the palm makes it negative, releasing it rolls the object into the
    palm: the two finger contacts hold the object at a maximum of its potential energy along
    their poses, which the hand's motion destroys. Nudged past it, the object fell, rolled
    2.6e-5 rad down its first step, and the fall's cradle (Newton on the two contacts'
    equilibrium) took it straight back to that maximum, 2e-10 higher (within the tolerance)
    and held there by the palm touching with zero force; the hand was nudged on by 1e-10 and
    all of it repeated until 'no progress after 200 increments' (1288 solves). A cradle is a
    minimum: the object rolls down the fingers away from the palm, and the move goes on to a
    state the independent check accepts."""
    sim, start = settled_where_soaked(
        NEAR_CIRCLE,
        [-0.07265695928901365, 0.3592271488259931, 0.4210263017412758],
        [-0.09506054110469425, 0.6544919861705529, 0.03333601585483807, -1.0588395703872222,
         -2.0604993980686834],
        [("finger1", "edge"), ("finger2", "edge"), ("finger2", "edge")],
    )  # fmt: skip
    end = sim.move_hand(
        start,
        palm=(-0.0849326736444434, 0.6361244954021203, 0.012455567036631282),
        fingers=(-1.0101075370152968, -2.1053185236017873),
    )
    assert "fall_start" in [e.kind for e in end.events]
    assert sim.solves <= 1000, f"{sim.solves} pose solves for one move"
    assert_invariants(end, tol_of(sim), "near-circle after the fall")


#: A polygon with three collinear vertices (5, 6, 7: edges 5 and 6 on one line), as the soak
#: drew it (seed 6, shape 310), with its palm, fingers and density.
COLLINEAR = soak_scene(
    0.004191952551147238,
    [
        [-0.0980207840387885, 0.0],
        [0.19210385052428575, 0.0],
        [0.2780149765879034, 0.08244490753109468],
        [0.2304631471533708, 0.20121358520292748],
        [-0.03080614563616009, 0.2959896707450321],
        [-0.2055193236577748, 0.264682810023511],
        [-0.23757519940087052, 0.1961042159001044],
        [-0.26963107148560894, 0.12752562006666213],
        [-0.19937604549250448, 0.04875841732648642],
    ],
    16.88320285912315,
)


def test_a_fall_slides_a_fingertip_past_a_vertex_between_collinear_edges() -> None:
    """Regression (soak seed 6, shape 310, step 421): held by finger 2's face and finger 1's
    tip, the object is released as the hand moves and falls with the tip sliding down object
    edge 5 toward vertex 6, where edge 6 goes on along the same line. At the vertex the
    tip's contact is at the end of its edge, and every fall step along the descent was cut
    short there at zero length: detection folds the tip on edge 6 (same point, same normal)
    into the one on edge 5, so the fall never tried the contact that carries the slide on.
    The move ended in "jam ... with the object neither held nor falling". A contact at the
    end of its edge of either kind (an object vertex at a hand edge's end, a hand vertex at
    an object edge's end) now offers the fall its twins, and the object falls on."""
    sim, start = settled_where_soaked(
        COLLINEAR,
        [0.07160738256348494, 0.3671448882345445, 1.1979681940201987],
        [0.058522808150337745, 0.6670053731072764, -0.15481543333132916, -0.8653382847040869,
         -2.2371938010558616],
        [("finger1", "tip"), ("finger2", "edge"), ("finger2", "edge")],
    )  # fmt: skip
    end = sim.move_hand(
        start,
        palm=(0.05572830368666511, 0.6777543901074747, -0.12966103643973523),
        fingers=(-0.8587852867275454, -2.2631539663180837),
    )
    assert "fall_start" in [e.kind for e in end.events]
    assert not end.jammed
    np.testing.assert_allclose(end.hand[3:], (-0.8587852867275454, -2.2631539663180837))
    assert sim.solves <= 1000, f"{sim.solves} pose solves for one move"
    assert_invariants(end, tol_of(sim), "after the fall past the collinear vertex")


def test_fall_with_no_admissible_step_stops_searching() -> None:
    """Regression (found by the planner's exploratory search): when no point along a fall
    step solves the contact equations, the step's bisection ran all 200 halvings (its
    stopping test was skipped on a failed solve), and the fall then halved the step 50 times,
    each repeating the very same solves (a halved step's points are the old step's
    bisection points): 10^5 Newton solves and 46-88 s for one hand move. Here every solve
    fails (patched into the interpreted core), for an object in the air: the fall must give
    up at once, after one bisection down to rounding (53 halvings), leaving the object where
    it is."""
    out = run_interpreted(
        """
        import numpy as np
        from grasp_env import Simulator
        from grasp_env.sim import fall, move
        calls = 0
        def failing(model, q0, h, E, solves):
            global calls
            calls += 1
            return q0, False
        fall.newton = failing
        sim = Simulator("fig13")
        start = sim.reset()
        lifted = start.object_pose + np.array([0.0, 0.1, 0.0])
        events = move.new_log()
        q, moved = fall.fall(sim.model, lifted, start.hand, 0.0, events, sim._solves)
        print(json.dumps({"q": (q - lifted).tolist(), "moved": moved, "calls": calls,
                          "events": [e[0] for e in events]}))
        """
    )
    assert out["q"] == [0.0, 0.0, 0.0] and not out["moved"]
    assert out["events"] == [FALL_START, FALL_END]
    assert 50 <= out["calls"] <= 60


def run_interpreted(code: str) -> dict:
    """Run ``code`` in a fresh interpreter with the compiled core interpreted
    (``NUMBA_DISABLE_JIT=1``), where its functions can be patched, and return the JSON it
    prints last."""
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    script = "import json\n" + textwrap.dedent(code)
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------------------
# 5. Convergence in contact_tol and max_step
# ---------------------------------------------------------------------------------------

#: fig13, fingers closing at equal rates from the start by this much in one move: finger 2
#: touches the object at about 0.385 rad, finger 1 at about 0.39, the object lifts off at
#: about 0.41 (see test_fig13_section4_experiment).
CLOSING = {"first_contacts": 0.395, "lift_off": 0.45}
#: Pose differences below this (palm widths) count as agreement: the final pose of these
#: motions is fixed by three active contacts, so it converges to rounding, not to tol.
POSE_FLOOR = 1e-10


@cache
def closing_run(dq: float, contact_tol: float = 1e-9, max_step: float | None = None) -> State:
    """fig13 from its start, both fingers closing by ``dq`` in one move (default options
    except those given)."""
    options = {} if max_step is None else {"max_step": max_step}
    sim = Simulator(scene_of("fig13"), contact_tol=contact_tol, **options)
    state = sim.move_hand(sim.reset(), fingers=(-HALF_PI + dq, -HALF_PI - dq))
    assert_invariants(state, tol_of(sim, contact_tol), f"fig13 closing {dq} tol {contact_tol}")
    return state


def first_contact_s(dq: float) -> tuple[float, float]:
    """Exact path parameter where finger 2's palmar edge meets object vertex (0.33, 0.24) of
    fig13 (the object is at rest until then), and the speed of that point of the finger."""
    scene = scene_of("fig13")
    J2 = np.array([scene.palm.pose[0] + scene.palm.width / 2, scene.palm.pose[1]])
    v = np.array([0.33, 0.24])
    q2 = math.atan2(v[1] - J2[1], v[0] - J2[0])
    assert np.linalg.norm(v - J2) < scene.fingers[1].length  # on the finger, not beyond
    return (-HALF_PI - q2) / dq, dq * float(np.linalg.norm(v - J2))


@pytest.mark.parametrize("dq", CLOSING.values(), ids=CLOSING.keys())
def test_first_contact_located_to_tolerance(dq: float) -> None:
    """The first event (finger 2 meets vertex 2) sits within contact_tol of the exact
    touching configuration, and the error falls at least 10x per 100x smaller tolerance
    until it reaches rounding (events are located by regula falsi on the gap, which may land
    on the touching point itself)."""
    s_exact, speed = first_contact_s(dq)
    errors = []
    for tol in (1e-5, 1e-7, 1e-9):
        e = closing_run(dq, tol).events[0]
        assert e.kind == "new_contact" and e.contacts[0][0] == 3  # finger 2
        errors.append(abs(e.s - s_exact) * speed)  # as a gap, in palm widths
        assert errors[-1] <= tol, f"tol {tol}: first contact off by {errors[-1]:.2e}"
    assert errors[1] <= max(errors[0] / 10, ROUNDING), errors
    assert errors[2] <= max(errors[1] / 10, ROUNDING), errors


#: Moves of the fig13 hand from a random-action episode (start "preliftoff") in which a
#: contact is lost and the object falls onto another: object pose, hand before and after.
#: Their events lie where a contact already touches at the start of the search (the check
#: sits in its band from the start), and their falls approach a contact while a hand body
#: touching the object overlaps it by about zero: bisecting to each event, and fall steps
#: taking the touching body's overlap for the event (each cut at the first point within
#: tolerance, 10-15 steps creeping toward the contact), took 371-417 pose solves a move.
FALLING_MOVES = [
    (
        [-0.1147098442461648, 0.409938965680756, -0.14257367683740604],
        [0.014953080375357005, 0.71, 0.0, -1.167714949105311, -2.3712498905065442],
        [-1.1375268922787194, -2.413602906644621],
    ),
    (
        [0.01514043088365168, 0.41527799968303064, 0.09851769703097812],
        [0.014953080375357005, 0.71, 0.0, -0.9266235752369267, -2.2048864736436653],
        [-0.9186265571380956, -2.173997501957302],
    ),
    (
        [0.07029270147296748, 0.4682165146195437, 0.23754392853595913],
        [0.014953080375357005, 0.71, 0.0, -0.7875973437319501, -2.1671927574305583],
        [-0.7627749163995489, -2.125860891047006],
    ),
]


@pytest.mark.parametrize(("pose", "hand", "fingers"), FALLING_MOVES)
def test_events_at_the_start_of_a_search_take_few_solves(pose, hand, fingers) -> None:
    """An event whose check already lies within tolerance where the search starts is
    reached by interpolation, not by halving to the last bit, and a fall step is cut where
    the term it violates reaches its limit: the move falls, ends in a state the independent
    checker passes, and needs at most 160 pose solves."""
    sim = Simulator(scene_of("fig13"))
    start = sim.settle(np.array(pose), np.array(hand))
    end = sim.move_hand(start, fingers=fingers)
    kinds = [e.kind for e in end.events]
    assert "lost_contact" in kinds and "fall_end" in kinds, kinds
    np.testing.assert_array_equal(end.finger_angles, fingers)
    assert_invariants(end, sim.tol)
    assert sim.solves <= 160, sim.solves


@pytest.mark.parametrize(
    ("lo_value", "hi_value", "expected"),
    [
        (-0.6, 1.4, 0.5),  # a check linear in s, -0.6 at 0.2 and 1.4 at 1.2: zero at 0.5
        (-1e-12, 1.0, 0.2 + 1e-3),  # kept a thousandth of the bracket from its ends
        (-1.0, 1e-12, 1.2 - 1e-3),
        (math.nan, 1.0, 0.7),  # a value not known: the midpoint
        (-1.0, -0.5, 0.7),  # no bracket: the midpoint
    ],
)
def test_false_position_step(lo_value: float, hi_value: float, expected: float) -> None:
    """The next point of the event and fall-step searches on the bracket [0.2, 1.2]."""
    assert false_position(0.2, 1.2, lo_value, hi_value) == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize("dq", CLOSING.values(), ids=CLOSING.keys())
def test_final_pose_converges_with_contact_tol(dq: float) -> None:
    """The final pose at contact_tol 1e-5 and 1e-7 approaches the 1e-9 run: within the
    tolerance, and 10x closer per 100x smaller tolerance unless already at rounding level."""
    ref = closing_run(dq, 1e-9).object_pose
    errors = [float(np.abs(closing_run(dq, tol).object_pose - ref).max()) for tol in (1e-5, 1e-7)]
    assert errors[0] <= 1e-5 and errors[1] <= 1e-7, errors
    assert errors[1] <= max(errors[0] / 10, POSE_FLOOR), errors
    for tol in (1e-5, 1e-7):
        assert contact_set(closing_run(dq, tol)) == contact_set(closing_run(dq, 1e-9))


@pytest.mark.parametrize("dq", CLOSING.values(), ids=CLOSING.keys())
def test_final_pose_converges_with_max_step(dq: float) -> None:
    """As max_step shrinks (0.5, 0.25 = the default, 0.05, 0.01) the error against a max_step
    0.005 run does not grow (beyond rounding)."""
    ref = closing_run(dq, 1e-9, 0.005).object_pose
    errors = [
        float(np.abs(closing_run(dq, 1e-9, step).object_pose - ref).max())
        for step in (0.5, 0.25, 0.05, 0.01)
    ]
    assert errors[0] <= 1e-7
    for coarse, fine in itertools.pairwise(errors):
        assert fine <= max(coarse, POSE_FLOOR), errors


def test_tighter_tolerance_agrees_at_lift_off() -> None:
    """contact_tol 1e-11 (the smallest allowed: the option takes [1e-11, 1e-2)) gives the same
    lift-off
    state as 1e-9: the hand reaches its target with the object on finger 1 (edge and tip)
    and finger 2. Regression: before commit df3bcc2 the 1e-11 run jammed at s = 0.9179 after
    finger 1's tip met object vertex 4 (a vertex-vertex touch) and a fall."""
    tight = closing_run(CLOSING["lift_off"], 1e-11)
    ref = closing_run(CLOSING["lift_off"], 1e-9)
    assert not tight.jammed
    np.testing.assert_allclose(tight.object_pose, ref.object_pose, atol=1e-9)


@pytest.mark.parametrize("tol", [1e-12, 0.0, -1e-9, 0.01, float("nan")])
def test_contact_tol_out_of_range_refused(tol) -> None:
    with pytest.raises(ValueError, match=r"contact_tol must be finite and in \[1e-11, 0.01\)"):
        Simulator(scene_of("fig13"), contact_tol=tol)


@pytest.mark.parametrize(
    ("kwargs", "error", "needle"),
    [
        ({"contact_tol": "1e-9"}, TypeError, "contact_tol must be a number, got '1e-9'"),
        ({"max_step": True}, TypeError, "max_step must be a number, got True"),
        ({"fall_step": 0.0}, ValueError, r"fall_step must be finite and in \(0, 1\], got 0.0"),
        ({"max_iterations": 10**30}, ValueError, r"max_iterations must be an integer in \[1, "),
        ({"max_solves": 2.5}, ValueError, "max_solves must be an integer >= 1, got 2.5"),
        (
            {"lp_solver": np.array(["fast"])},
            ValueError,
            r"lp_solver must be 'fast' or 'highs', got array\(\['fast'\]",
        ),
        ({"lp_solver": b"fast"}, ValueError, "lp_solver must be 'fast' or 'highs', got b'fast'"),
    ],
)
def test_bad_simulator_settings_are_named(kwargs, error, needle) -> None:
    with pytest.raises(error, match=needle):
        Simulator(scene_of("fig13"), **kwargs)


def test_numpy_scalar_settings_are_numbers() -> None:
    sim = Simulator(scene_of("fig13"), contact_tol=np.float32(1e-9), max_solves=np.int64(50))
    assert sim.tol == pytest.approx(1e-9 * sim.scene.palm.width, rel=1e-7)
    assert sim.max_solves == 50 and type(sim.max_solves) is int


# ---------------------------------------------------------------------------------------
# 6. The paper's section-4 experiment (fig13)
# ---------------------------------------------------------------------------------------


def own_form_closure(state: State) -> bool:
    """Form closure from the contacts alone: ``V_ob`` has rank 3 and ``V_ob v >= 0`` only for
    ``v = 0`` (max ``1^T V_ob v`` over that cone in a box is 0)."""
    P = np.array([c.point for c in state.contacts], dtype=float).reshape(-1, 2)
    N = np.array([c.normal for c in state.contacts], dtype=float).reshape(-1, 2)
    com = state.object_pose[:2]
    size = float(np.linalg.norm(state.scene.object.vertices_B, axis=1).max())
    V = np.column_stack([N, [cross(p - com, n) / size for p, n in zip(P, N, strict=True)]])
    if len(V) < 4 or np.linalg.matrix_rank(V, tol=1e-9) < 3:
        return False
    res = linprog(-V.sum(axis=0), A_ub=-V, b_ub=np.zeros(len(V)), bounds=[(-1, 1)] * 3)
    return res.status == 0 and -res.fun <= 1e-9


def own_force_closure(state: State) -> bool:
    """Gravity balanced by non-negative contact forces (``W_O c = w, c >= 0``)."""
    P = np.array([c.point for c in state.contacts], dtype=float).reshape(-1, 2)
    N = np.array([c.normal for c in state.contacts], dtype=float).reshape(-1, 2)
    com = state.object_pose[:2]
    W_O = np.vstack([N.T, [cross(p - com, n) for p, n in zip(P, N, strict=True)]])
    res = linprog(
        np.zeros(len(N)), A_eq=W_O, b_eq=[0.0, state.scene.object_weight, 0.0], bounds=(0, None)
    )
    return res.status == 0


@cache
def section4_run(step: float = 0.01, max_moves: int = 200) -> tuple[State, ...]:
    sim = Simulator(scene_of("fig13"))
    states = [sim.reset()]
    for _ in range(max_moves):
        states.append(sim.move_hand(states[-1], fingers=equal_rate_targets(states[-1], step)))
        if states[-1].jammed:
            break
    return tuple(states)


def test_fig13_section4_experiment() -> None:
    """Section 4 of the paper on its Fig. 13 set-up: palm fixed, both fingers closing at equal
    angular rates (q1 += 0.01, q2 -= 0.01 per move) from hanging straight down.

    Checks, on every state: the invariants; the palm never moves; the object never goes down
    (each move leaves its height the same or higher) and, once it has left the support, it
    never touches it again (no drop). Over the run: finger 2 touches first and finger 1 next;
    the object lifts off the support towards the palm; several states are three-contact
    force-closure grasps (exactly three contacts, none on the support, ``is_force_closure``
    and not ``is_form_closure``, both confirmed by LPs solved here); the run ends in a jam
    (``state.jammed``, and the hand's further closing is impossible by an LP solved here) in
    form closure (``is_form_closure``, confirmed here) with the object touching the palm.

    Events recorded with the simulator as of this writing (finger offset from -pi/2 in rad):
    0.38 finger 2's palmar edge meets object vertex 2; 0.40 finger 1's palmar edge meets
    vertex 4 and one support contact goes (the object turns); 0.42 edge 4 comes to lie along
    finger 1 (its tip becomes a second contact) and the object leaves the support: lifting on
    three finger contacts; 0.60 vertex 1 meets finger 2; 0.64 vertex 2 leaves finger 2 (a
    lost contact and a short fall between the fingers); 0.68 finger 1's tip contact turns into
    an edge contact (vertex 0 on finger 1; the event is listed twice); 0.733 vertex 3 meets
    the palm and the hand jams in form closure.
    """
    states = section4_run()
    sim_tol = tol_of(Simulator(scene_of("fig13")))
    first = states[0]
    events = []
    for k, st in enumerate(states):
        assert_invariants(st, sim_tol, f"fig13 section 4 move {k}")
        np.testing.assert_array_equal(st.palm_pose, first.palm_pose)
        events.extend((k, e.kind, e.contacts) for e in st.events)
    heights = np.array([st.object_pose[1] for st in states])
    assert np.all(np.diff(heights) >= -1e-9), "the object went down"
    on_support = [any(c.body == "support" for c in st.contacts) for st in states]
    lift = on_support.index(False)
    assert not any(on_support[lift:]), "the object came back to the support (a drop)"
    assert heights[-1] > heights[0] + 0.25, "the object should be lifted towards the palm"

    new_bodies = [c[0][0] for _, kind, c in events if kind == "new_contact" and c]
    assert new_bodies[:2] == [3, 2], f"finger 2 then finger 1 should touch first: {events}"
    three_point = [
        k
        for k, st in enumerate(states)
        if len(st.contacts) == 3
        and not on_support[k]
        and grasp_env.is_force_closure(st)
        and not grasp_env.is_form_closure(st)
    ]
    assert len(three_point) >= 3, "several three-contact force-closure grasps expected"
    for k in three_point:
        assert own_force_closure(states[k]) and not own_form_closure(states[k])

    last = states[-1]
    assert last.jammed, f"the run should end in a jam, ended after {len(states) - 1} moves"
    assert_jam_genuine(last, np.array([0.0, 0.0, 0.0, 0.01, -0.01]), "fig13 final jam")
    assert grasp_env.is_form_closure(last) and own_form_closure(last)
    assert "palm" in {c.body for c in last.contacts}
    assert events[-1][1] == "jam"
    assert all(not st.jammed for st in states[:-1])


# ---------------------------------------------------------------------------------------
# 7. A jam without form closure: the square wedged between two fingertips
# ---------------------------------------------------------------------------------------


def squeeze_scene(height: float) -> dict:
    """The square scene with the palm placed so that both fingertips touch the vertical
    sides (x = -+0.15) at the same ``height``, palm parallel to the support.

    With joints at ``x_p -+ 0.5`` and tips at ``(-+0.15, height)``:
    ``(x_p - 0.35)^2 + d^2 = L1^2`` and ``(x_p + 0.35)^2 + d^2 = L2^2`` with ``d = y_p -
    height``, so ``x_p = (L2^2 - L1^2) / 1.4``.
    """
    d = copy.deepcopy(raw_scene("square"))
    L1, L2 = d["fingers"][0]["length"], d["fingers"][1]["length"]
    xp = (L2**2 - L1**2) / 1.4
    drop = math.sqrt(L1**2 - (xp - 0.35) ** 2)
    yp = height + drop
    d["palm"]["pose"] = [xp, yp, 0.0]
    d["fingers"][0]["angle"] = math.atan2(-drop, -0.15 - (xp - 0.5))
    d["fingers"][1]["angle"] = math.atan2(-drop, 0.15 - (xp + 0.5))
    return d


@pytest.mark.parametrize("height", [0.15, 0.25, 0.05], ids=["com_height", "high", "low"])
@pytest.mark.parametrize(
    "closing", [(1, 1), (1, 0), (0, 1)], ids=["both_close", "finger1_closes", "finger2_closes"]
)
def test_square_wedged_between_parallel_fingertips(height: float, closing: tuple) -> None:
    """Derivation: both tips press horizontally on parallel faces along the same line
    y = height. Their velocity rows are ``(1, 0, -a)`` and ``(-1, 0, a)`` (``a`` the arm of
    the common line about the centre of mass) with right-hand sides ``xi_1, xi_2 >= 0`` not
    both 0 when a finger closes (each tip moves inwards at rate ``y_p - height`` per rad).
    Adding the rows gives ``0 >= xi_1 + xi_2 > 0``: the velocity LP is infeasible at once, so
    the hand jams at s = 0 with the square untouched. The square can still rise between the
    tips (``v = (0, 1, 0)`` meets every contact row with equality or slack), so it is not in
    form closure; gravity is balanced by the support alone (force closure)."""
    sim = Simulator(squeeze_scene(height))
    tol = tol_of(sim)
    state = sim.reset()
    assert_invariants(state, tol, "squeeze reset")
    for i in (1, 2):  # the construction puts both tips on the sides at the same height
        tip = fingertip_W(sim.scene, state.hand, i)
        np.testing.assert_allclose(tip, [(-0.15, 0.15)[i - 1], height], atol=1e-12)
    assert contact_set(state) == [
        ("finger1", "tip"), ("finger2", "tip"), ("support", "edge"), ("support", "edge")
    ]  # fmt: skip
    q1, q2 = state.finger_angles
    new = sim.move_hand(state, fingers=(q1 + 0.05 * closing[0], q2 - 0.05 * closing[1]))
    assert_invariants(new, tol, "squeezed")
    assert new.jammed
    assert_jam_genuine(new, np.array([0, 0, 0, 0.05 * closing[0], -0.05 * closing[1]]), "squeeze")
    assert "jam" in [e.kind for e in new.events]
    np.testing.assert_allclose(new.hand, state.hand, atol=1e-9)  # stopped at s = 0
    np.testing.assert_allclose(new.object_pose, state.object_pose, atol=1e-9)
    assert not grasp_env.is_form_closure(new) and not own_form_closure(new)
    assert grasp_env.is_force_closure(new) and own_force_closure(new)
    # Opening again is free: the tips leave the sides and nothing else moves.
    opened = sim.move_hand(new, fingers=(q1 - 0.05, q2 + 0.05))
    assert not opened.jammed
    assert_invariants(opened, tol, "opened")
    np.testing.assert_allclose(opened.object_pose, state.object_pose, atol=1e-12)
    assert contact_set(opened) == [("support", "edge")] * 2


# ---------------------------------------------------------------------------------------
# 8. The hand blocked by the support
# ---------------------------------------------------------------------------------------


def test_a_fold_located_ahead_is_logged_as_one_jam_where_the_hand_stops() -> None:
    """A pentagon on the support against finger 2 while the palm lowers and turns: the
    event search locates a fold a little ahead, the move goes on to it and the hand stops
    there. The log holds that jam once, as its last event (it held it twice: once when the
    fold was located, once when the hand stopped), and the jam is genuine there."""
    scene = grasp_env.load_scene({
        "name": "fold_ahead",
        "gravity": 9.81,
        "palm": {"width": 1.0, "thickness": 0.15, "pose": [0.014953080375357, 0.71, 0.0]},
        "fingers": [
            {"length": 0.6, "thickness": 0.05, "angle": -math.pi / 2, "limits": [-math.pi, 0.0]},
            {"length": 0.7, "thickness": 0.05, "angle": -math.pi / 2, "limits": [-math.pi, 0.0]},
        ],
        "object": {
            "vertices": [
                [-0.0009832412334686465, 0.0], [0.05987191868597047, 0.0],
                [0.056562412476674415, 0.0921442950399914],
                [0.007341724182200277, 0.1998587847422856],
                [-0.03505056993342258, 0.1452317262794504],
            ],
            "mass": 0.2467616000582789,
        },
    })  # fmt: skip
    sim = Simulator(scene)
    q = np.array([0.00660678683248418, 0.041737624338887, -1.6066974557941935])
    hand = np.array([0.02604881945110986, 0.5516798146886124, 0.14417306356069376,
                     -0.7400257516766828, -2.452611243512706])  # fmt: skip
    target = np.array([0.03196251097180077, 0.5398807796162857, 0.098061605020731,
                       -0.7790378768111509, -2.482911851790027])  # fmt: skip
    state = sim.settle(q, hand)
    np.testing.assert_array_equal(state.object_pose, q)  # held there: nothing falls
    new = sim.move_hand(state, palm=target[:3], fingers=target[3:])
    kinds = [e.kind for e in new.events]
    assert new.jammed and kinds.count("jam") == 1 and kinds[-1] == "jam", kinds
    assert_invariants(new, tol_of(sim), "fold ahead")
    s = new.events[-1].s
    assert 0.0 < s < 1.0
    np.testing.assert_allclose(new.hand, hand + s * (target - hand), atol=1e-12)
    assert_jam_genuine(new, target - hand, "fold ahead")


def lowest_hand_y(scene: grasp_env.Scene, hand: np.ndarray) -> float:
    return min(float(p[:, 1].min()) for p in hand_polygons_W(scene, hand).values())


BLOCKED_MOVES = [
    # palm target, finger target (None: unchanged), from the fig13 start. "lower" is a
    # regression case: before commit 8166210 it stopped 2.98e-9 (3x contact_tol) short.
    pytest.param((0.014953080375357005, 0.6, 0.0), None, id="lower"),
    pytest.param((0.014953080375357005, 0.5, 0.0), None, id="lower_far"),
    pytest.param((0.0, 0.62, 0.08), None, id="lower_and_tilt"),
    pytest.param((0.014953080375357005, 0.71, -0.2), None, id="tilt_only"),
    pytest.param((0.014953080375357005, 0.55, 0.0), (-1.9, -1.2), id="lower_and_open_fingers"),
]


@pytest.mark.parametrize(("palm", "fingers"), BLOCKED_MOVES)
def test_hand_blocked_by_support(palm: tuple, fingers: tuple | None) -> None:
    """A hand move that would push a hand vertex into the support stops where the lowest
    hand vertex reaches y = 0 (found here by root finding on the path parameter), with
    ``hand_blocked`` and a ``"hand_blocked"`` event; the object is not disturbed."""
    scene = scene_of("fig13")
    sim = Simulator(scene)
    tol = tol_of(sim)
    start = sim.reset()
    h0 = start.hand.copy()
    h1 = h0.copy()
    h1[:3] = palm
    if fingers is not None:
        h1[3:] = fingers
    assert lowest_hand_y(scene, h1) < -0.001  # the target is inside the support
    grid = np.linspace(0.0, 1.0, 2001)
    first_bad = next(s for s in grid if lowest_hand_y(scene, h0 + s * (h1 - h0)) < 0.0)
    s_star = brentq(
        lambda s: lowest_hand_y(scene, h0 + s * (h1 - h0)), first_bad - 5e-4, first_bad,
        xtol=1e-15,
    )  # fmt: skip
    state = sim.move_hand(start, palm=palm, fingers=fingers)
    assert_invariants(state, tol, "blocked")
    assert state.hand_blocked and not state.jammed
    assert "hand_blocked" in [e.kind for e in state.events]
    assert abs(lowest_hand_y(scene, state.hand)) <= tol + ROUNDING
    assert_on_path(h0, h1, state, tol, "blocked: ")
    s = float((state.hand - h0) @ (h1 - h0) / ((h1 - h0) @ (h1 - h0)))
    speed = (
        abs(
            lowest_hand_y(scene, h0 + (s_star + 1e-7) * (h1 - h0))
            - lowest_hand_y(scene, h0 + (s_star - 1e-7) * (h1 - h0))
        )
        / 2e-7
    )
    assert abs(s - s_star) * speed <= tol + ROUNDING, (s, s_star)
    np.testing.assert_allclose(state.object_pose, start.object_pose, atol=1e-12)
    # Moving further down from the blocked state does not move the hand.
    again = sim.move_hand(state, palm=palm, fingers=fingers)
    assert again.hand_blocked
    np.testing.assert_allclose(again.hand, state.hand, atol=1e-9)


def test_hand_not_blocked_when_touching_support_is_avoided() -> None:
    """Lowering the palm until the long finger's tip is 1e-6 above the support is not
    blocked (no spurious hand_blocked)."""
    scene = scene_of("fig13")
    sim = Simulator(scene)
    start = sim.reset()
    y = 0.7 + 1e-6  # finger 2 (length 0.7) hangs straight down from y_p
    state = sim.move_hand(start, palm=(start.palm_pose[0], y, 0.0))
    assert not state.hand_blocked and "hand_blocked" not in [e.kind for e in state.events]
    assert state.palm_pose[1] == pytest.approx(y, abs=1e-15)
    assert lowest_hand_y(scene, state.hand) == pytest.approx(1e-6, abs=1e-12)


# ---------------------------------------------------------------------------------------
# 9. Joint limits
# ---------------------------------------------------------------------------------------

LIMIT_CASES = {
    # fingers target -> expected clipped angles (fig13 limits [-pi, 0] for both)
    "both_open_past": ((-4.0, 0.5), (-math.pi, 0.0)),
    "finger1_past": ((-3.5, -1.0), (-math.pi, -1.0)),
    "finger2_past": ((-1.6, 0.3), (-1.6, 0.0)),
    "inside": ((-2.0, -1.2), (-2.0, -1.2)),
}


@pytest.mark.parametrize("case", list(LIMIT_CASES), ids=list(LIMIT_CASES))
def test_joint_limits_clip_and_report(case: str) -> None:
    """Targets beyond the joint limits are clipped to them and reported (``"joint_limit"``);
    targets inside are reached as given with no such event. These moves open the fingers
    away from the object, so nothing else happens."""
    target, expected = LIMIT_CASES[case]
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    state = sim.move_hand(start, fingers=target)
    assert_invariants(state, tol_of(sim), case)
    np.testing.assert_allclose(state.finger_angles, expected, atol=1e-15)
    lim = sim.scene.joint_limits
    assert np.all(state.finger_angles >= lim[:, 0]) and np.all(state.finger_angles <= lim[:, 1])
    clipped = expected != target
    assert ("joint_limit" in [e.kind for e in state.events]) == clipped
    assert not state.jammed and not state.hand_blocked
    np.testing.assert_allclose(state.object_pose, start.object_pose, atol=1e-12)


def test_a_clipped_target_is_reported_before_the_events_of_the_move() -> None:
    """A finger target beyond its limit while the palm goes down into the support: the
    clipping is logged at s = 0 (the target is clipped before the hand moves), then the
    support cuts the path short, so the log's ``s`` never goes back (the clipping was logged
    at s = 1, ahead of the path's end at 0.025)."""
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    x, y, theta = start.hand[:3]
    q1, q2 = start.finger_angles
    state = sim.move_hand(start, palm=(x, y - 0.4, theta), fingers=(q1 - 5.0, q2))
    assert [e.kind for e in state.events] == ["joint_limit", "hand_blocked"]
    assert state.hand_blocked and state.events[0].s == 0.0
    s = [e.s for e in state.events]
    assert s == sorted(s) and 0.0 < s[-1] < 1.0


# ---------------------------------------------------------------------------------------
# 10. Bad arguments
# ---------------------------------------------------------------------------------------

BAD_ARGS = {
    "palm_nan": ({"palm": (0.0, math.nan, 0.0)}, "palm"),
    "palm_inf": ({"palm": (math.inf, 0.7, 0.0)}, "palm"),
    "palm_short": ({"palm": (0.0, 0.7)}, "palm"),
    "palm_long": ({"palm": (0.0, 0.7, 0.0, 0.0)}, "palm"),
    "palm_string": ({"palm": "up"}, "palm"),
    "palm_strings": ({"palm": ("0", "a", "0")}, "palm"),
    "palm_none_entry": ({"palm": (0.0, None, 0.0)}, "palm"),
    "palm_scalar": ({"palm": 0.5}, "palm"),
    "fingers_nan": ({"fingers": (math.nan, -1.0)}, "fingers"),
    "fingers_inf": ({"fingers": (-1.0, -math.inf)}, "fingers"),
    "fingers_short": ({"fingers": (-1.0,)}, "fingers"),
    "fingers_long": ({"fingers": [-1.0, -1.0, -1.0]}, "fingers"),
    "fingers_string": ({"fingers": "closed"}, "fingers"),
    "fingers_dict": ({"fingers": {"q1": -1.0, "q2": -1.0}}, "fingers"),
    "fingers_nested": ({"fingers": [[-1.0, -1.0], [-1.0, -1.0]]}, "fingers"),
    "fingers_numeric_strings": ({"fingers": ("-1.0", "-1.0")}, "fingers"),
    "fingers_bools": ({"fingers": (True, False)}, "fingers"),
    "fingers_complex": ({"fingers": (-1.0 + 1j, -1.0)}, "fingers"),
    "palm_bool_array": ({"palm": np.array([True, False, True])}, "palm"),
}


@pytest.mark.parametrize("case", list(BAD_ARGS), ids=list(BAD_ARGS))
def test_bad_arguments_raise_value_error(case: str) -> None:
    """NaN, inf, wrong lengths and non-numbers raise ValueError naming the argument; the
    simulator still works afterwards (a valid move gives the right state)."""
    kwargs, name = BAD_ARGS[case]
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    with pytest.raises(ValueError, match=name):
        sim.move_hand(start, **kwargs)
    q1, q2 = start.finger_angles
    state = sim.move_hand(start, fingers=(q1 - 0.1, q2 + 0.1))
    assert_invariants(state, tol_of(sim), f"after {case}")
    np.testing.assert_allclose(state.finger_angles, (q1 - 0.1, q2 + 0.1), atol=1e-15)
    np.testing.assert_allclose(state.object_pose, start.object_pose, atol=1e-12)
    np.testing.assert_array_equal(start.hand, sim.scene.initial_hand)  # input not mutated


# ---------------------------------------------------------------------------------------
# Failed solves: one retry on the reference path with smaller increments
# ---------------------------------------------------------------------------------------


def test_failed_fast_lp_retries_on_reference_path() -> None:
    """When the fast LP path fails inside a move (injected into the interpreted core), the
    move is redone on the HiGHS path with smaller increments, and ends where a simulator on
    the reference path ends."""
    out = run_interpreted(
        """
        import math
        from grasp_env import Simulator
        from grasp_env.errors import SolverError
        from grasp_env.solvers import velocity_lp
        calls = 0
        def failing(*args):
            global calls
            calls += 1
            raise SolverError("injected", "fast path down")
        fingers = (-math.pi / 2 + 0.45, -math.pi / 2 - 0.45)
        reference = Simulator("fig13", lp_solver="highs", max_step=0.0625)
        expected = reference.move_hand(reference.reset(), fingers=fingers)
        sim = Simulator("fig13")
        start = sim.reset()
        velocity_lp.solve = failing
        state = sim.move_hand(start, fingers=fingers)
        print(json.dumps({"calls": calls, "pose": state.object_pose.tolist(),
                          "expected": expected.object_pose.tolist(),
                          "reference_lp": sim.model.reference_lp}))
        """
    )
    assert out["calls"] > 0, "the injected failure should have been hit"
    np.testing.assert_allclose(out["pose"], out["expected"], atol=POSE_TOL)
    assert not out["reference_lp"], "the retry must not change the simulator itself"


def test_retry_result_is_valid(monkeypatch: pytest.MonkeyPatch) -> None:
    """A move retried on the reference path returns a valid state: here the first attempt
    fails on the reference LP (injected once) and the retry completes."""
    from grasp_env.errors import SolverError
    from grasp_env.solvers import lp

    real = lp.velocity_lp
    calls = {"n": 0}

    def once(V, xi, weight):
        calls["n"] += 1
        if calls["n"] == 1:
            raise SolverError("injected", "down once")
        return real(V, xi, weight)

    sim = Simulator(scene_of("fig13"), lp_solver="highs")
    start = sim.reset()
    monkeypatch.setattr(lp, "velocity_lp", once)
    state = sim.move_hand(start, fingers=(-HALF_PI + 0.45, -HALF_PI - 0.45))
    assert calls["n"] > 1
    assert_invariants(state, tol_of(sim), "retried move")


def test_failed_retry_raises_simulation_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """If the reference path fails too, the move raises SimulationError naming both causes
    (here the reference LP fails, which both attempts of a reference-path simulator use)."""
    from grasp_env.errors import SolverError
    from grasp_env.solvers import lp

    def broken(V, xi, weight):
        raise SolverError("injected", "highs path down")

    sim = Simulator(scene_of("fig13"), lp_solver="highs")
    start = sim.reset()
    monkeypatch.setattr(lp, "velocity_lp", broken)
    with pytest.raises(grasp_env.SimulationError, match=r"highs path down.*again.*highs path down"):
        sim.move_hand(start, fingers=(-HALF_PI + 0.45, -HALF_PI - 0.45))


def test_independent_forces_match_lstsq() -> None:
    """The closed-form contact forces of up to three wrenches agree with numpy's SVD-based
    least squares (the reference), on random and nearly dependent wrench sets, and refuse
    dependent ones."""
    from grasp_env.sim.pose import independent_forces

    def _independent_forces(W, g):
        lam, ok = independent_forces(np.ascontiguousarray(W), g)
        return lam if ok else None

    rng = np.random.default_rng(7)
    for m in (1, 2, 3):
        for k in range(500):
            W = rng.normal(size=(3, m)) * rng.uniform(0.01, 100.0)
            if k % 5 == 0 and m > 1:  # nearly parallel columns
                W[:, 1] = W[:, 0] + 1e-4 * rng.normal(size=3)
            g = rng.normal(size=3)
            lam = _independent_forces(W, g)
            ref = np.linalg.lstsq(W, g, rcond=None)[0]
            assert lam is not None
            # as good a least-squares fit, up to rounding of the size of the forces
            slack = 1e-10 * np.linalg.norm(W) * (1.0 + np.abs(ref).max())
            assert np.linalg.norm(W @ lam - g) <= np.linalg.norm(W @ ref - g) + slack
            if m < 3 or abs(np.linalg.det(W / np.linalg.norm(W, axis=0))) > 1e-3:
                np.testing.assert_allclose(lam, ref, rtol=1e-8, atol=1e-10)
    W = np.array([[1.0, 2.0, 0.0], [0.0, 0.0, 1.0], [1.0, 2.0, 0.0]]).T  # columns 0, 2 equal
    assert _independent_forces(W, np.ones(3)) is None
    assert _independent_forces(np.zeros((3, 2)), np.ones(3)) is None


def test_no_contacts_never_reach_scipy_nnls() -> None:
    """Regression (soak seed 4, shape 52): with no contacts at all the hold test used to
    call scipy's nnls on a 3x0 matrix, which aborts the whole process in scipy 1.17
    ("double free"). No contacts hold nothing: the residual is the whole weight."""
    from grasp_env.solvers.dense import nnls

    lam, res = nnls(np.zeros((3, 0)), np.array([0.0, 2.5, 0.0]))
    assert lam.shape == (0,) and res == pytest.approx(2.5)


def test_work_limit_bounds_a_move_and_is_not_retried() -> None:
    """A move that needs more than ``max_solves`` pose solves raises WorkLimitError after
    exactly that many, without the retry on the reference path (which shares the budget, so
    it would have charged one solve more); the same move with the default budget completes."""
    sim = Simulator(scene_of("fig13"), max_solves=5)
    start = sim.reset()
    q1, q2 = start.finger_angles
    with pytest.raises(WorkLimitError, match="more than 5 pose solves"):
        sim.move_hand(start, fingers=(q1 + 0.8, q2 - 0.8))
    assert sim.solves == 6
    state = Simulator(scene_of("fig13")).move_hand(start, fingers=(q1 + 0.8, q2 - 0.8))
    assert grasp_env.is_form_closure(state)


def test_work_limit_is_validated() -> None:
    for bad in (0, -1, 2.5, "10", None, True):
        with pytest.raises(ValueError, match="max_solves"):
            Simulator(scene_of("fig13"), max_solves=bad)


@pytest.mark.parametrize(
    ("shift", "fingers", "needle"),
    [
        ((0.0, -0.5, 0.0), None, "the object enters the support"),
        ((0.2, 0.0, 0.0), None, "the finger 2 overlaps the object by 0.01"),
        ((0.0, 0.0, 0.0), (3.5, -1.5), r"finger angles \[3.5, -1.5\] outside the joint limits"),
    ],
)
def test_settle_refuses_overlapping_bodies(shift, fingers, needle) -> None:
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    hand = start.hand.copy()
    if fingers is not None:
        hand[3:] = fingers
    with pytest.raises(ValueError, match=needle):
        sim.settle(start.object_pose + shift, hand)


def test_settle_takes_bodies_within_the_contact_tolerance() -> None:
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    # half a tolerance into the support: touching, not overlapping
    state = sim.settle(start.object_pose - (0.0, 0.5 * sim.tol, 0.0), start.hand)
    assert {c.body for c in state.contacts} == {"support"}
    with pytest.raises(ValueError, match="the object enters the support"):
        sim.settle(start.object_pose - (0.0, 2 * sim.tol, 0.0), start.hand)


def test_a_state_of_another_scene_is_not_moved() -> None:
    sim = Simulator(grasp_env.load_scene("fig13"))
    again = Simulator(grasp_env.load_scene("fig13")).reset()  # the same file loaded again
    with pytest.raises(ValueError, match="state is of scene 'fig13', not of 'fig13'"):
        sim.move_hand(again, fingers=(-1.0, -2.1))
    with pytest.raises(TypeError, match=r"state must be a grasp_env\.State, got dict"):
        sim.move_hand({"hand": again.hand}, fingers=(-1.0, -2.1))


# ---------------------------------------------------------------------------------------
# States are snapshots; a state built by hand is checked before a move from it
# ---------------------------------------------------------------------------------------


def test_a_states_arrays_cannot_be_written() -> None:
    """A simulator's states and their contacts, and a state built by hand (which copies the
    arrays it is given: changing them afterwards changes nothing)."""
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    moved = sim.move_hand(start, fingers=(start.hand[3] + 0.5, start.hand[4] - 0.5))
    for state in (start, moved):
        arrays = [state.object_pose, state.hand]
        arrays += [a for c in state.contacts for a in (c.point, c.normal)]
        for a in arrays:
            with pytest.raises(ValueError, match="read-only"):
                a[0] = 1.0
    pose, hand = start.object_pose.copy(), start.hand.copy()
    built = State(sim.scene, pose, hand, start.contacts)
    pose[0], hand[3] = 9.0, 9.0
    np.testing.assert_array_equal(built.object_pose, start.object_pose)
    np.testing.assert_array_equal(built.hand, start.hand)
    with pytest.raises(ValueError, match="read-only"):
        built.hand[3] = 1.0
    points = moved.contact_arrays()[0]  # copies, the caller's to change
    points[:] = 0.0
    assert not np.array_equal(moved.contact_arrays()[0], points)


def test_a_state_built_by_hand_moves_as_the_simulators_own() -> None:
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    built = State(sim.scene, start.object_pose, start.hand, start.contacts)
    target = (start.hand[3] + 0.6, start.hand[4] - 0.6)
    a, b = sim.move_hand(start, fingers=target), sim.move_hand(built, fingers=target)
    np.testing.assert_array_equal(a.object_pose, b.object_pose)
    np.testing.assert_array_equal(a.hand, b.hand)
    assert [c.key for c in a.contacts] == [c.key for c in b.contacts]


def test_a_state_built_by_hand_with_mislabelled_contacts_is_not_moved() -> None:
    """The move takes a state's contacts as known: a support contact labelled as finger 1's
    stopped the hand at its start with a false jam. The keys must be those the simulator
    finds at the state; their order is free."""
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    c = start.contacts[0]
    relabelled = dataclasses.replace(c, body="finger1")
    no_vertex = dataclasses.replace(c, object_feature=99)
    for contacts in (
        (relabelled, *start.contacts[1:]),
        (no_vertex, *start.contacts[1:]),
        start.contacts[1:],
        (),
    ):
        built = State(sim.scene, start.object_pose, start.hand, contacts)
        with pytest.raises(ValueError, match=r"^state\.contacts \[.*\] .* are not the contacts"):
            sim.move_hand(built, fingers=(-1.0, -2.0))
    built = State(sim.scene, start.object_pose, start.hand, start.contacts[::-1])
    moved = sim.move_hand(built, fingers=(-1.0, -2.0))
    assert not moved.jammed
    np.testing.assert_array_equal(moved.hand, sim.move_hand(start, fingers=(-1.0, -2.0)).hand)


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"hand": (None, 0.2)}, r"state\.object_pose .* with state\.hand .*the palm overlaps"),
        ({"hand": (3, 1.0)}, r"state\.hand: finger angles \[1\.0, .*outside the joint limits"),
        ({"pose": (1, -0.05)}, r"the object enters the support"),
        ({"pose": (2, 1e12)}, r"state\.object_pose\[2\] must be an angle .*1000000000000\.0"),
        ({"hand": (2, -7.0)}, r"state\.hand\[2\] must be an angle .*-7\.0"),
    ],
)
def test_a_state_built_by_hand_that_overlaps_is_not_moved(change, needle) -> None:
    """The checks of :meth:`Simulator.settle`, through ``move_hand`` and the env's
    ``simulate_action``; a valid move from the simulator's own state works afterwards."""
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    pose, hand = start.object_pose.copy(), start.hand.copy()
    if "hand" in change:
        i, value = change["hand"]
        if i is None:  # the palm down into the object
            hand[1] = pose[1]
        else:
            hand[i] = value
    else:
        i, value = change["pose"]
        pose[i] = pose[i] + value if i == 1 else value
    bad = State(sim.scene, pose, hand, ())
    with pytest.raises(ValueError, match=needle):
        sim.move_hand(bad, fingers=(hand[3] + 0.1, hand[4] - 0.1))
    import gymnasium as gym

    env = gym.make("FrictionlessGrasp-v0").unwrapped
    env.reset(seed=0)
    bad = State(env.state.scene, pose, hand, ())
    with pytest.raises(ValueError, match=needle):
        env.simulate_action(bad, [1.0, 1.0])
    state = sim.move_hand(start, fingers=(start.hand[3] + 0.1, start.hand[4] - 0.1))
    assert_invariants(state, tol_of(sim))


def test_settle_refuses_angles_beyond_two_pi() -> None:
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    with pytest.raises(ValueError, match=r"^object_pose\[2\] must be an angle .* 7\.0"):
        sim.settle(start.object_pose + np.array([0.0, 0.0, 7.0]), start.hand)
    with pytest.raises(ValueError, match=r"^hand\[2\] must be an angle .* -6\.5"):
        sim.settle(start.object_pose, start.hand + np.array([0.0, 0.0, -6.5, 0.0, 0.0]))


@pytest.mark.parametrize(
    ("pose", "hand", "needle"),
    [
        ((1e16, 0.2, 0.0), None, r"^object_pose\[0\] must be within 20000 x palm\.width .*1e\+16"),
        ((0.0, 1e5, 0.0), None, r"^object_pose\[1\] must be within 20000 .*got 100000\.0"),
        (None, (-3e4, 0.71), r"^hand\[0\] must be within 20000 .*got -30000\.0"),
        (None, (0.0, 1e5), r"^hand\[1\] must be within 20000 .*got 100000\.0"),
    ],
    ids=["object-x", "object-y", "palm-x", "palm-y"],
)
def test_settle_refuses_positions_beyond_twice_the_scene_bound(pose, hand, needle) -> None:
    """Where rounding would swallow the contact tolerance (an object at 1e16 collapsed with
    'invalid value' warnings) or a fall could not end in bounded work: refused, through
    ``settle`` and a state built by hand."""
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    q = start.object_pose if pose is None else np.array(pose)
    h = start.hand.copy()
    if hand is not None:
        h[:2] = hand
    with pytest.raises(ValueError, match=needle):
        sim.settle(q, h)
    with pytest.raises(ValueError, match=needle.replace("^", "^state\\.")):
        sim.move_hand(State(sim.scene, q, h), fingers=(-1.0, -2.0))


def test_settle_takes_starts_in_the_env_workspace_of_a_far_scene() -> None:
    """The bound is twice the scene schema's: a scene at its coordinate bound, with the palm
    where the env's workspace reaches (2 palm widths past the object), still settles."""
    d = yaml.safe_load((SCENES_DIR / "fig13.yaml").read_text())
    shift = 1e4 - 0.34  # the object's rightmost vertex, x = 0.33, just inside 1e4
    d["palm"]["pose"][0] += shift
    d["object"]["vertices"] = [[x + shift, y] for x, y in d["object"]["vertices"]]
    sim = Simulator(grasp_env.load_scene(d))
    start = sim.reset()
    hand = start.hand.copy()
    hand[0] = sim.scene.object.start_pose[0] + 2.0
    assert hand[0] > 1e4
    state = sim.settle(start.object_pose, hand)
    assert state.hand[0] == hand[0] and state.on_support


def test_a_palm_angle_beyond_two_pi_is_refused() -> None:
    """Every state a move makes is one the simulator moves from again: a palm target's
    angle beyond the scene schema's 2 pi is refused, as ``settle`` refuses such a hand."""
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    x, y = start.hand[:2]
    lifted = sim.move_hand(start, palm=(x, y + 5.0, 0.0))  # the palm far above the object
    for angle in (7.0, -6.5, 2 * np.pi + 1e-9):
        with pytest.raises(ValueError, match=r"^palm\[2\] must be an angle .*" + str(angle)[:4]):
            sim.move_hand(lifted, palm=(x, y + 5.0, angle))
    turned = sim.move_hand(lifted, palm=(x, y + 5.0, 2 * np.pi))  # the bound itself is allowed
    assert turned.hand[2] == 2 * np.pi
    sim.move_hand(dataclasses.replace(turned), palm=(x, y + 5.0, 0.0))  # and moved from again


@pytest.mark.parametrize("far", [1e6, 1e15, 1e20, -1e300])
def test_a_palm_target_beyond_what_a_move_resolves_is_refused(far: float) -> None:
    """A move's rounding along its path parameter (2.2e-16 of its length) must stay below
    the contact tolerance: 16 roundings of the default 1e-9 palm widths allow 2.8e5 palm
    widths (or radians); beyond, ``palm`` is refused where a move used to end jammed at
    its start with no contact to jam it."""
    sim = Simulator(scene_of("fig13"))
    start = sim.reset()
    assert sim.max_travel == pytest.approx(1e-9 / (16 * 2.220446049250313e-16))
    x, y, th = start.hand[:3]
    for palm in ((x + far, y, th), (x, y + abs(far), th)):
        with pytest.raises(ValueError, match=r"^palm target .* farther than a move can"):
            sim.move_hand(start, palm=palm)
    with pytest.raises(ValueError, match=r"^palm\[2\] must be an angle"):  # 2 pi comes first
        sim.move_hand(start, palm=(x, y, th + far))
    fine = Simulator(scene_of("fig13"), contact_tol=1e-6)
    assert fine.max_travel == pytest.approx(1e3 * sim.max_travel)
    state = sim.move_hand(start, palm=(x, y + 0.1, th))  # a move within it still runs
    assert_invariants(state, tol_of(sim))
