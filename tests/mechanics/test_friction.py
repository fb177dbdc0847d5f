"""Tests of grasp_env.mechanics.friction against closed forms and independent certificates.

The closed forms: two contacts pinching an object jam iff the line joining them lies in both
friction cones (mu* is the tangent of the larger angle between a normal and that line); a
finger pushing an object along the support at an angle alpha below the horizontal jams from
mu* = tan(pi/4 - alpha/2); a motion the frictionless simulator jams on has mu* = 0. Beyond
them, on the simulator's own states, each side of every computed mu* is certified in
physical terms with kinematics written here: just below it a twist of the object whose
contact velocities relative to the hand all lie in the polar of the friction cones (the
object gets out of the way), just above it contact forces inside the cones that balance and
do positive work against the hand (a jam).
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from scipy.optimize import linprog

import grasp_env
from grasp_env import Simulator, planning
from grasp_env.core.scene_loading import scaled_scene_dict
from grasp_env.core.state import Contact, State
from grasp_env.mechanics import friction

FIG13 = grasp_env.load_scene("fig13")
HAND = FIG13.initial_hand.copy()


def rotate(v: np.ndarray, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def hand_state(points, normals, bodies, pose=(0.0, 0.2, 0.0), hand=HAND, scene=FIG13) -> State:
    """A state built by hand: the given contacts (no geometry behind them is needed by the
    analysis, which reads points, normals and bodies)."""
    contacts = tuple(
        Contact(b, "tip" if b != "support" else "edge", np.array(p, float), np.array(n, float),
                0.0, i, 0)
        for i, (p, n, b) in enumerate(zip(points, normals, bodies, strict=True))
    )  # fmt: skip
    return State(scene, np.array(pose, float), np.asarray(hand, float), contacts)


def body_frame(scene, h: np.ndarray, body: str) -> tuple[np.ndarray, float]:
    """Origin and angle of ``body``'s frame for hand ``h`` (docs/conventions.md, Frames)."""
    xp, yp, th = h[:3]
    if body == "palm":
        return np.array([xp, yp]), th
    side = -1.0 if body == "finger1" else 1.0
    joint = np.array([xp, yp]) + rotate(np.array([side * scene.palm.width / 2, 0.0]), th)
    return joint, th + h[3 if body == "finger1" else 4]


def hand_point_velocity(scene, h, dh, body: str, point: np.ndarray) -> np.ndarray:
    """Velocity of the hand's material point at ``point`` for the motion ``dh``: the point
    carried along ``h + s dh`` by forward kinematics, differentiated centrally."""
    if body == "support":
        return np.zeros(2)
    origin, angle = body_frame(scene, h, body)
    local = rotate(point - origin, -angle)
    eps = 1e-6
    moved = []
    for s in (eps, -eps):
        o, a = body_frame(scene, h + s * dh, body)
        moved.append(o + rotate(local, a))
    return (moved[0] - moved[1]) / (2 * eps)


def physical_rows(state: State, dh: np.ndarray):
    """Per contact: point, normal, tangent and hand-point velocity, from this file's
    kinematics; the lengths are in units of the palm width and velocities of the fastest."""
    p, n, _ = state.contact_arrays()
    names = [c.body for c in state.contacts]
    v = np.array([hand_point_velocity(state.scene, state.hand, dh, nm, pt)
                  for nm, pt in zip(names, p, strict=True)])  # fmt: skip
    v /= np.max(np.linalg.norm(v, axis=1))
    t = np.column_stack([-n[:, 1], n[:, 0]])
    L = state.scene.palm.width
    r = (p - state.object_pose[:2]) / L
    return r, n, t, v


def certify_motion(state: State, dh: np.ndarray, mu: float) -> bool:
    """Whether some object twist leaves every contact with a relative velocity in the polar
    of its cone (``n.d >= mu |t.d|``), found by HiGHS with a margin and checked here.

    The LP is homogenised (twist ``u / tau``, ``tau`` in [0, 1], ``|u| <= 1``) since near
    ``mu*`` the way out can be fast; ``tau = 0`` is a twist that gets away from every
    contact whatever the hand does, taken large enough to outrun it."""
    r, n, t, v = physical_rows(state, dh)
    A, b = [], []
    for ri, ni, ti, vi in zip(r, n, t, v, strict=True):
        for sign in (1.0, -1.0):
            e = ni + sign * mu * ti
            e = e / np.linalg.norm(e)
            # e . (v_obj(p) - tau v) >= s  with v_obj(p) = (vx - w ry, vy + w rx)
            A.append([-e[0], -e[1], -(ri[0] * e[1] - ri[1] * e[0]), e @ vi, 1.0])
            b.append(0.0)
    res = linprog([0, 0, 0, 0, -1.0], A_ub=np.array(A), b_ub=np.array(b),
                  bounds=[(-1, 1)] * 3 + [(0, 1), (None, 1)], method="highs")  # fmt: skip
    if res.status != 0 or res.x[4] <= 1e-12:
        return False
    u, tau, margin = res.x[:3], res.x[3], res.x[4]
    u = u / tau if tau > 0.0 else u * 2 / margin
    d = np.column_stack([u[0] - u[2] * r[:, 1], u[1] + u[2] * r[:, 0]]) - v
    return bool(np.all(np.sum(n * d, axis=1) >= mu * np.abs(np.sum(t * d, axis=1))))


def certify_jam(state: State, dh: np.ndarray, mu: float) -> bool:
    """Whether contact forces inside the cones balance and do positive work against the
    hand, found by HiGHS and checked here (residual and cone membership)."""
    r, n, t, v = physical_rows(state, dh)
    cols = []
    for ri, ni, ti in zip(r, n, t, strict=True):
        for sign in (1.0, -1.0):
            e = (ni + sign * mu * ti) / math.hypot(1.0, mu)
            cols.append((ri, e))
    W = np.array([[e[0], e[1], ri[0] * e[1] - ri[1] * e[0]] for ri, e in cols]).T
    power = np.array([e @ v[j // 2] for j, (_, e) in enumerate(cols)])
    res = linprog(-power, A_eq=np.vstack([W, np.ones(len(cols))]), b_eq=[0, 0, 0, 1],
                  bounds=(0, None), method="highs")  # fmt: skip
    if res.status != 0 or -res.fun <= 0.0:
        return False
    y = np.clip(res.x, 0.0, None)
    forces = y[0::2, None] * np.array([e for _, e in cols[0::2]]) + y[1::2, None] * np.array(
        [e for _, e in cols[1::2]]
    )
    normal, tangential = np.sum(forces * n, axis=1), np.sum(forces * t, axis=1)
    in_cones = np.all(np.abs(tangential) <= mu * normal * (1 + 1e-12))
    residual = np.abs(W @ y).max()
    work = np.sum(forces * v)
    return bool(in_cones and work > 0.0 and residual <= 1e-6 * work)


# ------------------------------------------------------------------------ closed forms
@pytest.mark.parametrize("seed", range(40))
def test_a_pinch_jams_from_the_tangent_of_its_larger_angle(seed: int) -> None:
    """Two fingertips on an object: forces along the line joining them, inside both cones,
    and work against the hand only when the hand closes the pinch (Nguyen's condition)."""
    rng = np.random.default_rng(seed)
    p1 = np.array([rng.uniform(-0.4, -0.05), rng.uniform(0.05, 0.5)])
    p2 = np.array([rng.uniform(0.05, 0.4), rng.uniform(0.05, 0.5)])
    d = (p2 - p1) / np.linalg.norm(p2 - p1)
    a1, a2 = rng.uniform(-1.3, 1.3, size=2)
    n1, n2 = rotate(d, a1), rotate(-d, a2)
    dh = rng.normal(size=5)
    state = hand_state([p1, p2], [n1, n2], ["finger1", "finger2"])
    v1 = hand_point_velocity(FIG13, HAND, dh, "finger1", p1)
    v2 = hand_point_velocity(FIG13, HAND, dh, "finger2", p2)
    closing = d @ (v1 - v2)
    expected = math.tan(max(abs(a1), abs(a2))) if closing > 0 else math.inf
    got = friction.critical_friction(state, dh)
    if math.isinf(expected):
        assert got == math.inf
    else:
        assert got == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("alpha_deg", [0.0, 10.0, 25.0, 40.0, 60.0])
def test_a_push_along_the_support_jams_from_the_half_angle(alpha_deg: float) -> None:
    """A finger pushing an object that stands on the support (two support contacts) with its
    normal alpha below the horizontal: the push and the support's reaction are opposite,
    each inside its cone, from tan(atan(mu) + alpha) >= cot(atan(mu)), i.e.
    mu* = tan(pi/4 - alpha/2); the line of action meets the base between the supports."""
    alpha = math.radians(alpha_deg)
    palm_x = HAND[0]
    p1 = np.array([palm_x - 0.5, 0.05])  # on finger 1's line, low on the object's left
    state = hand_state(
        [[palm_x - 0.5, 0.0], [palm_x - 0.1, 0.0], p1],
        [[0.0, 1.0], [0.0, 1.0], [math.cos(alpha), -math.sin(alpha)]],
        ["support", "support", "finger1"],
        pose=(palm_x - 0.3, 0.1, 0.0),
    )
    push = np.array([1.0, 0.0, 0.0, 0.0, 0.0])  # the palm moves right
    expected = math.tan(math.pi / 4 - alpha / 2)
    assert friction.critical_friction(state, push) == pytest.approx(expected, rel=1e-9)


def test_pressing_down_on_a_standing_object_jams_without_friction() -> None:
    """A fingertip pressing down on an object standing on the support: mu* = 0."""
    state = hand_state([[-0.1, 0.0], [0.1, 0.0], [0.0, 0.3]],
                       [[0.0, 1.0], [0.0, 1.0], [0.0, -1.0]],
                       ["support", "support", "palm"])  # fmt: skip
    assert friction.critical_friction(state, np.array([0.0, -1.0, 0.0, 0.0, 0.0])) == 0.0
    assert friction.jams_with_friction(state, np.array([0.0, -1.0, 0.0, 0.0, 0.0]), 0.0)


@pytest.mark.parametrize("scene_name", ["square", "fig13"])
def test_a_frictionless_jam_of_the_simulator_needs_no_friction(scene_name: str) -> None:
    """Close the fingers until the simulator jams; the rest of the same motion needs no
    friction to jam, and the motions before the jam needed some (mu* > 0). The simulator
    decides a jam to tolerance (contacts dependent to within it hold, docs/simulator.md):
    the square is pinched between fingertips whose line of action is 1.5e-6 rad from the
    normals, so its mu* is that small rather than 0."""
    scene = grasp_env.load_scene(scene_name)
    sim = Simulator(scene)
    state = sim.reset()
    for _ in range(400):
        target = state.hand[3:] + np.array([0.02, -0.02])
        new = sim.move_hand(state, fingers=target)
        if new.jammed:
            break
        dh = new.hand - state.hand
        if len(state.contacts) and np.any(dh):
            assert friction.critical_friction(state, dh) > 0.0
        state = new
    else:
        pytest.skip("no jam on this scene's closing")  # pragma: no cover
    dh = np.zeros(5)
    dh[3:] = target - new.hand[3:]
    assert friction.critical_friction(new, dh) <= 1e-5


def test_no_contact_or_no_push_never_jams() -> None:
    """Without contacts, with a motion that moves no contact point, with one contact or
    with fingers opening away from a pinch, no friction jams the hand."""
    free = State(FIG13, np.array([0.0, 0.2, 0.0]), HAND)
    assert friction.critical_friction(free, np.ones(5)) == math.inf
    pinch = hand_state([[-0.2, 0.2], [0.2, 0.2]], [[1.0, 0.0], [-1.0, 0.0]],
                       ["finger1", "finger2"])  # fmt: skip
    assert friction.critical_friction(pinch, np.zeros(5)) == math.inf
    opening = np.array([0.0, 0.0, 0.0, -1.0, 1.0])
    assert friction.critical_friction(pinch, opening) == math.inf
    assert friction.critical_friction(pinch, -opening) == 0.0  # a head-on squeeze
    for scale in (1e-300, 1e300):  # only the direction counts
        assert friction.critical_friction(pinch, -opening * scale) == 0.0
    one = hand_state([[-0.2, 0.2]], [[1.0, 0.0]], ["finger1"])
    assert friction.critical_friction(one, -opening) == math.inf


def test_bad_arguments_are_refused_by_name() -> None:
    state = hand_state([[-0.2, 0.2]], [[1.0, 0.0]], ["finger1"])
    for bad in ([1, 2, 3], [0, 0, 0, 0, math.nan], "fast", None):
        with pytest.raises(ValueError, match="hand_velocity"):
            friction.critical_friction(state, bad)
    for mu in (-0.1, math.nan, math.inf, 2e6):
        with pytest.raises(ValueError, match="mu"):
            friction.jams_with_friction(state, np.ones(5), mu)
    for mu in (True, "0.3", None):
        with pytest.raises(TypeError, match="mu"):
            friction.jams_with_friction(state, np.ones(5), mu)
    with pytest.raises(TypeError):
        friction.critical_friction("state", np.ones(5))


# ------------------------------------------------------------------------ certificates
def simulated_cases(count: int) -> list[tuple[State, np.ndarray]]:
    """States of random-shape episodes under random palm-and-finger actions, with the next
    step's hand motion, where the object touches the hand."""
    env = gym.make("FrictionlessGrasp-v0", palm_control=True, shape_randomizer=True)
    rng = np.random.default_rng(7)
    cases: list[tuple[State, np.ndarray]] = []
    for episode in range(40):
        env.reset(seed=100 + episode)
        base = env.unwrapped
        for _ in range(30):
            state = base.state
            action = rng.uniform(-1, 1, 5)
            action[:2] = np.abs(action[:2])  # mostly closing
            env.step(action)
            dh = base.state.hand - state.hand
            if any(c.body != "support" for c in state.contacts) and np.any(dh):
                cases.append((state, dh))
        if len(cases) >= count:
            break
    return cases[:count]


CASES = simulated_cases(60)


@pytest.mark.parametrize("case", range(len(CASES)))
def test_each_side_of_the_critical_friction_is_certified(case: int) -> None:
    """Below mu*, an object twist that gets out of the way; above it, a jam's forces: each
    found by HiGHS and checked here in physical terms."""
    state, dh = CASES[case]
    mu = friction.critical_friction(state, dh)
    if mu > 0.0:
        assert certify_motion(state, dh, mu * (1 - 1e-6) if math.isfinite(mu) else 1e3)
    if math.isfinite(mu):
        assert certify_jam(state, dh, mu * (1 + 1e-6) + 1e-9)


def test_compiled_and_reference_tests_agree() -> None:
    """The compiled jam test and HiGHS give the same answer away from mu* (at 0.5 and 2 mu*
    and at fixed coefficients)."""
    for state, dh in CASES:
        rows = friction.edge_rows(state, dh)
        mu_star = friction.critical_friction(state, dh)
        for mu in (0.1, 0.35, 1.0, 3.0, 0.5 * mu_star, 2.0 * mu_star):
            if not math.isfinite(mu) or mu > friction.MU_MAX:
                continue
            E, xi = friction.cone_edges(rows, mu)
            expected = friction.reference_jams(E, xi)
            assert friction.jams_with_friction(state, dh, mu) == expected, (mu, mu_star)
            assert expected == (mu >= mu_star)


@pytest.mark.parametrize("k", [1e-4, 1e3])
def test_the_same_at_every_scale(k: float) -> None:
    """fig13's lifting at palm width k: every step's mu* as at palm width 1."""
    base = planning.plan_grasp(FIG13)
    spec = yaml.safe_load((Path(grasp_env.__file__).parent / "scenes/fig13.yaml").read_text())
    d = scaled_scene_dict(spec, k)
    scaled = planning.plan_grasp(grasp_env.load_scene(d))
    assert len(scaled.steps) == len(base.steps)
    for k in range(len(base.steps) - 1):
        a0, a1 = base.steps[k].state, base.steps[k + 1].state
        b0, b1 = scaled.steps[k].state, scaled.steps[k + 1].state
        mu_a = friction.critical_friction(a0, a1.hand - a0.hand)
        mu_b = friction.critical_friction(b0, b1.hand - b0.hand)
        assert mu_b == pytest.approx(mu_a, rel=1e-8, abs=1e-9)
