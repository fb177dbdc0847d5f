"""Property-based stress tests of the simulator and the environment on random convex shapes.

Hypothesis draws convex polygons over the stress ranges (3-12 vertices, diameter 5%-80% of
the palm width, aspect up to 1:20, masses 1e-3..10, nearly collinear vertices, very short
edges, nearly parallel edges, slivers: :func:`soak_shapes.stress_polygon`) and random hand paths or
env action sequences. After every step the state is checked by
:func:`grasp_env.testing.check_state`, an independent re-computation (separating-axis
penetration, contact gaps from the points and normals, every touching vertex-body pair
listed, forces >= 0, the object's equilibrium residual, and the velocity LP's optimum solved
with scipy's HiGHS).

The default run keeps ``max_examples`` small; ``pytest -m slow`` runs the larger variants.
Failures hypothesis shrank are pinned below as explicit regression tests.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st

import grasp_env
from grasp_env import Simulator, testing
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.errors import SceneError

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import soak

from benchmarks import soak_shapes

#: Increment cap of one hand move: no valid move needs more than a few dozen increments.
MAX_ITERATIONS = 400
#: Default run: few examples and no shrinking (shrinking a failure takes minutes; the slow
#: variants shrink, and ``print_blob`` gives the failing example's reproduction seed).
FAST = settings(
    max_examples=10,
    deadline=None,
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
SLOW = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)


# ---------------------------------------------------------------------------------------
# Strategies
# ---------------------------------------------------------------------------------------


@st.composite
def polygons(draw: st.DrawFn) -> np.ndarray:
    """A stress polygon resting on y = 0 (see :func:`soak_shapes.stress_polygon`)."""
    kind = draw(st.sampled_from(soak_shapes.KINDS))
    n = draw(st.integers(3, 12))
    size = draw(st.floats(0.05, 0.8))
    aspect = math.exp(draw(st.floats(0.0, math.log(20.0))))
    eps = 10 ** draw(st.floats(-6.0, -2.0))
    seed = draw(st.integers(0, 2**32 - 1))
    return soak_shapes.stress_polygon(np.random.default_rng(seed), n, size, aspect, kind, eps)


@st.composite
def scenes(draw: st.DrawFn) -> grasp_env.Scene:
    poly = draw(polygons())
    mass = 10 ** draw(st.floats(-3.0, 1.0))
    try:
        return grasp_env.load_scene(soak_shapes.stress_scene(poly, mass))
    except SceneError:
        assume(False)  # wider than the hanging fingers: not a valid start
        raise


#: One hand move: finger increments (biased to closing) and, or not, a palm increment.
moves = st.tuples(
    st.floats(-0.1, 0.25),
    st.floats(-0.1, 0.25),
    st.one_of(
        st.none(),
        st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.1, 0.1)),
    ),
)


def tol_of(scene: grasp_env.Scene, contact_tol: float = 1e-9) -> float:
    return contact_tol * scene.palm.width


def assert_valid(scene, object_pose, hand, contacts, tol: float, where: str) -> testing.Check:
    chk = testing.check_state(scene, object_pose, hand, contacts, tol)
    assert not chk.violations, f"{where}: " + "; ".join(chk.violations)
    return chk


def run_path(scene: grasp_env.Scene, path: list) -> None:
    """Move the hand along ``path`` (increments from the planned targets) checking every
    returned state, and that the hand ends on its straight line."""
    sim = Simulator(scene, max_iterations=MAX_ITERATIONS)
    tol = tol_of(scene)
    state = sim.reset()
    assert_valid(scene, state.object_pose, state.hand, state.contacts, tol, "reset")
    target = state.hand.copy()
    lim = scene.joint_limits
    for m, (d1, d2, palm) in enumerate(path):
        target = target.copy()
        target[3] += d1
        target[4] -= d2
        if palm is not None:
            target[:3] += palm
        h0 = state.hand.copy()
        new = sim.move_hand(state, palm=target[:3] if palm is not None else None,
                            fingers=target[3:])  # fmt: skip
        where = f"move {m} from {h0.tolist()} to {target.tolist()}"
        assert_valid(scene, new.object_pose, new.hand, new.contacts, tol, where)
        h1 = h0.copy()
        if palm is not None:
            h1[:3] = target[:3]
        h1[3:] = np.clip(target[3:], lim[:, 0], lim[:, 1])
        dh = h1 - h0
        if np.any(dh):
            size = np.abs(dh).max()  # in units of the move: dh @ dh underflows for 1e-200
            s = float(((new.hand - h0) / size) @ (dh / size) / ((dh / size) @ (dh / size)))
            assert -1e-12 <= s <= 1 + 1e-12, f"{where}: hand left its move (s = {s})"
            np.testing.assert_allclose(new.hand, h0 + s * dh, atol=1e-9, err_msg=where)
            if not (new.jammed or new.hand_blocked):
                np.testing.assert_allclose(new.hand, h1, atol=1e-12, err_msg=where)
        state = new


def run_env(scene: grasp_env.Scene, start: str, actions: list, seed: int = 0) -> None:
    """Step the env with ``actions`` (palm control), checking the observation and ``info``."""
    env = FrictionlessGraspEnv(scene=scene, palm_control=True, start=start)
    tol = tol_of(scene, env.contact_tol)
    obs, info = env.reset(seed=seed)
    for k, a in enumerate([None, *actions]):
        if a is not None:
            obs, reward, term, _, info = env.step(np.array(a, dtype=np.float32))
            assert math.isfinite(reward), f"step {k}: reward {reward}"
            assert "sim_error" not in info, f"step {k}: {info['sim_error']}"
        assert env.observation_space.contains(obs), f"step {k}: observation {obs}"
        hand = np.r_[info["palm_pose"], info["finger_angles"]]
        assert_valid(scene, info["object_pose"], hand, info["contacts"], tol, f"step {k}")
        if a is not None and term:
            obs, info = env.reset(seed=k)
    env.close()


# ---------------------------------------------------------------------------------------
# The checker itself must catch broken states (else every property below is vacuous)
# ---------------------------------------------------------------------------------------


def _fig13_state():
    sim = Simulator("fig13")
    return sim, sim.reset()


@pytest.mark.parametrize(
    ("case", "expect"),
    [
        ("valid", None),
        ("sunk", "penetration"),
        ("negative_force", "force"),
        ("dropped_contact", "unlisted"),
        ("shifted_point", "contact"),
        ("nan_pose", "nan"),
        ("wrong_force", "equilibrium"),
        ("finger_inside", "penetration"),
    ],
)
def test_checker_catches_broken_states(case: str, expect: str | None) -> None:
    """:func:`grasp_env.testing.check_state` accepts a valid state and flags each kind of
    broken one."""
    sim, state = _fig13_state()
    scene, tol = sim.scene, tol_of(sim.scene)
    pose, hand = state.object_pose.copy(), state.hand.copy()
    contacts = [c.as_dict() for c in state.contacts]
    if case == "sunk":
        pose[1] -= 1e-6
    elif case == "negative_force":
        contacts[0]["force"] = -1e-3
    elif case == "dropped_contact":
        contacts = contacts[:1]
    elif case == "shifted_point":
        contacts[0]["point"] = contacts[0]["point"] + [0.0, 1e-6]
    elif case == "nan_pose":
        pose[2] = math.nan
    elif case == "wrong_force":
        contacts[0]["force"] *= 1.001
    elif case == "finger_inside":
        hand[3] += 0.6  # finger 1 swings into the object
    chk = testing.check_state(scene, pose, hand, contacts, tol)
    if expect is None:
        assert chk.violations == []
    else:
        assert any(v.startswith(expect) for v in chk.violations), chk.violations


# ---------------------------------------------------------------------------------------
# Properties
# ---------------------------------------------------------------------------------------


@FAST
@given(poly=polygons())
def test_random_polygons_are_valid_scenes(poly: np.ndarray) -> None:
    """Every generated polygon is strictly convex, CCW, 3-13 vertices, resting on edge 0."""
    n = len(poly)
    assert 3 <= n <= 13
    d = np.roll(poly, -1, axis=0) - poly
    turns = d[:, 0] * np.roll(d, -1, axis=0)[:, 1] - d[:, 1] * np.roll(d, -1, axis=0)[:, 0]
    assert np.all(turns > 0)
    assert poly[0, 1] == 0.0 and poly[1, 1] == 0.0 and poly[:, 1].min() >= 0.0


@FAST
@given(scene=scenes(), path=st.lists(moves, min_size=1, max_size=8))
def test_random_hand_paths_keep_invariants(scene: grasp_env.Scene, path: list) -> None:
    run_path(scene, path)


action = st.tuples(*[st.floats(-1.0, 1.0)] * 5)


def given_env_runs(max_actions: int):
    """``given`` the arguments of :func:`run_env`: a scene, a start, 1 to ``max_actions``
    actions."""
    return given(
        scene=scenes(),
        start=st.sampled_from(["scene", "preliftoff", "random"]),
        actions=st.lists(action, min_size=1, max_size=max_actions),
    )


@FAST
@given_env_runs(max_actions=10)
def test_random_env_actions_keep_invariants(scene, start: str, actions: list) -> None:
    run_env(scene, start, actions)


@pytest.mark.slow
@SLOW
@given(scene=scenes(), path=st.lists(moves, min_size=1, max_size=25))
def test_random_hand_paths_keep_invariants_slow(scene: grasp_env.Scene, path: list) -> None:
    run_path(scene, path)


@pytest.mark.slow
@SLOW
@given_env_runs(max_actions=40)
def test_random_env_actions_keep_invariants_slow(scene, start: str, actions: list) -> None:
    run_env(scene, start, actions)


# ---------------------------------------------------------------------------------------
# Regression cases (examples hypothesis shrank)
# ---------------------------------------------------------------------------------------


#: Found by test_random_hand_paths_keep_invariants (shrunk): a heptagon of mass 1 (world
#: vertices at the scene placement, edge 0 on the support) in the fig13 hand.
TUNNEL_POLYGON = [
    [0.06182153, 0.0],
    [0.54913621, 0.0],
    [0.70430312, 0.36064135],
    [0.46702148, 0.6856017],
    [0.18810496, 0.70201558],
    [0.01859941, 0.59877433],
    [-0.07809734, 0.43559512],
]


def test_regression_object_tunnels_through_finger() -> None:
    """Finger 1 closes onto the heptagon, the palm tilts by 0.077 rad and is lowered by 0.047:
    the palm pushes the object along the support towards finger 2, which must stop it (a new
    contact, then a jam or the object squeezed up) -- never let it pass through (with the
    simulator of commit b5f21e7 the object ends crossed by finger 2, no vertex of either body
    inside the other, penetration 0.05..0.17).
    """
    poly = np.array(TUNNEL_POLYGON) - [0.30381687, 0.0]
    scene = grasp_env.load_scene(soak_shapes.stress_scene(poly, 1.0))
    run_path(
        scene,
        [
            (0.16279415653728432, 0.0, None),
            (0.0, 0.0, (0.0, 0.0, 0.0767136501744948)),
            (0.0, 0.0, None),
            (0.2360349946698365, 0.0, None),
            (0.0, 0.0, (0.0, -0.04713586966262589, 0.0)),
        ],
    )


#: Found by the soak (``benchmarks/soak.py --seed 1``, shape 73; float32 actions).
UNHELD_POLYGON = [
    [-0.11356077806569354, 0.0],
    [0.09817862422186094, 0.0],
    [0.2042838966776319, 0.15247410462346028],
    [0.14005177079693304, 0.2928925882862563],
    [-0.021817673571276425, 0.3349400329790819],
    [-0.14869586031436588, 0.2747024760118263],
    [-0.1918786923183537, 0.08414571862657899],
]
UNHELD_ACTIONS = [
    [0.97969913, 0.6239696, -0.7702199, -0.39086124, 0.017521447],
    [0.3094846, 0.8999102, 0.8102551, -0.630868, 0.44774312],
    [0.8704793, -0.38021335, -0.28323987, -0.604663, 0.032114275],
    [0.24934125, 0.2862759, 0.7109435, -0.4603995, -0.18031769],
    [-0.30935282, -0.082278006, -0.32451516, -0.53253955, 0.5482619],
    [0.8250018, 0.41561976, 0.5929065, -0.44801414, 0.73432],
    [0.17453614, -0.16902214, -0.6394048, 0.895221, 0.94063205],
    [0.93011147, 0.017041558, 0.77973855, -0.89612865, 0.1306767],
    [0.38718632, -0.1534974, 0.82674503, 0.1218794, 0.11935905],
    [0.7301354, -0.3964292, -0.5465409, 0.07031785, -0.46834213],
    [0.9311462, 0.9250002, 0.47324634, 0.10331665, -0.7182035],
]


def test_regression_jam_after_lost_contact_is_held() -> None:
    """A heptagon of mass 0.036 in the fig13 hand, ``"random"`` start (reset seed 83305122),
    11 palm-control actions. At step 11 a contact is lost, a fall starts and ends at once, and
    the simulator reports a jam whose two finger contacts cannot hold the object (equilibrium
    residual 1.8e-6 x weight, an admissible descent of the same size; with the simulator of
    commit bb97343 plus the uncommitted changes of 01:50 UTC on 2026-11-22). This test is the
    reproducer."""
    poly = np.array(UNHELD_POLYGON)
    scene = grasp_env.load_scene(soak_shapes.stress_scene(poly, 0.03590536183244385))
    run_env(scene, "random", UNHELD_ACTIONS, seed=83305122)


def test_regression_jam_at_a_fold_is_held() -> None:
    """fig13 at the ``"preliftoff"`` start, 2,641 random steps in (env seed 1, action space
    seed 0): closing finger 1 while opening finger 2 wedges the object between both
    fingertips and a support vertex, whose normals nearly meet in one point. The forces that
    hold it are about 1e7 weights, and their rounding alone left a residual of 6.6e-9 weights
    where the jam's test allowed 1.6e-9: the move failed ("jam ... with the object neither
    held nor falling"), again on the reference path. The object is held there, as the
    independent check confirms."""
    scene = grasp_env.load_scene("fig13")
    sim = Simulator(scene)
    hand = np.array([0.014953080375357005, 0.71, 0.0, -1.569819423096805, -2.5485486958336985])
    start = sim.settle(
        np.array([-0.26986157283939066, 0.22295670322573363, 1.025141272267905]), hand
    )
    assert_valid(scene, start.object_pose, start.hand, start.contacts, tol_of(scene), "start")
    step = 0.05 * np.array([0.7128958106040955, 0.3872475326061249])  # the env's action
    state = sim.move_hand(start, fingers=(hand[3] + step[0], hand[4] + step[1]))
    assert state.jammed and state.events[-1].kind == "jam"
    assert sorted(c.body for c in state.contacts) == ["finger1", "finger2", "support"]
    assert min(c.force for c in state.contacts) > 1e6 * scene.object_weight  # a fold
    assert_valid(scene, state.object_pose, state.hand, state.contacts, tol_of(scene), "jam")


@pytest.mark.slow
def test_regression_soak_seed2_shape135() -> None:
    """Soak seed 2, shape 135 (a sliver, 0.04 thick, ``"preliftoff"`` start, random
    palm-control steps drawn from ``default_rng([2, 135])``; the first 139 of its 200 steps).
    With the simulator of commit ffaa429 plus uncommitted changes (02:30 UTC), step 138 reported
    a jam with the sliver wedged between exactly anti-parallel finger faces, contact forces
    of 1e11-2e12 x weight, an equilibrium residual of 5.7e-3 x weight and a free descent
    along the faces (the sliver should slide down between them). Faces parallel to tolerance
    are free along each other since (``grasp_env.sim.dependence``). Takes 30 s to 3 min
    (every step is checked), hence ``slow``."""
    rec = soak.soak_shape(2, 135, 139)
    assert rec["exceptions"] == rec["sim_errors"] == rec["violating_steps"] == 0, rec["examples"]


# ---------------------------------------------------------------------------------------
# Failures inside the solver (a failed solve is retried once on the reference path)
# ---------------------------------------------------------------------------------------


def _closing_run(sim: Simulator, moves: int = 12) -> list[grasp_env.State]:
    states = [sim.reset()]
    for _ in range(moves):
        q1, q2 = states[-1].finger_angles
        states.append(sim.move_hand(states[-1], fingers=(q1 + 0.04, q2 - 0.04)))
    return states


def test_fast_lp_failure_falls_back_to_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """When the fast LP cannot decide (injected: it always raises SolverError), the motion LP
    is solved on the reference path (HiGHS): the fig13 closing motion is the same as with
    ``lp_solver="highs"`` and every state is valid."""
    from grasp_env.errors import SolverError
    from grasp_env.solvers import fastlp

    reference = _closing_run(Simulator("fig13", lp_solver="highs"))

    def fail(*args, **kwargs):
        raise SolverError("injected failure", "undecided")

    monkeypatch.setattr(fastlp, "solve_velocity_lp", fail)
    states = _closing_run(Simulator("fig13", lp_solver="fast"))
    tol = tol_of(states[0].scene)
    for i, (a, b) in enumerate(zip(states, reference, strict=True)):
        assert_valid(a.scene, a.object_pose, a.hand, a.contacts, tol, f"move {i}")
        np.testing.assert_allclose(a.object_pose, b.object_pose, atol=1e-9, err_msg=f"move {i}")
        np.testing.assert_allclose(a.hand, b.hand, atol=1e-12)


def test_env_reports_solver_failure_as_sim_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every LP fails (injected into the reference path, which the simulator is switched to
    for the failing step, and which its retry uses too): ``step`` must not raise; it ends the
    episode with ``info["sim_error"]`` naming the failure and leaves the state as it was;
    once the solver works again, ``reset`` and ``step`` work."""
    from grasp_env.errors import SolverError
    from grasp_env.solvers import lp

    env = FrictionlessGraspEnv("fig13", palm_control=True)
    first, _ = env.reset(seed=0)
    good = np.array([1.0, 1.0, 0.0, 0.0, 0.0], dtype=np.float32)  # close both fingers
    obs0, info0 = first, {}
    for _ in range(40):  # close until a finger touches: the next closing step needs the LP
        obs0, _, _, _, info0 = env.step(good)
        if any(c["body"].startswith("finger") for c in info0["contacts"]):
            break
    assert any(c["body"].startswith("finger") for c in info0["contacts"])

    def fail(*args, **kwargs):
        raise SolverError("injected failure", "numerical")

    sim = env.unwrapped.simulator
    with monkeypatch.context() as m:
        m.setattr(sim, "model", sim.model._replace(reference_lp=True))
        m.setattr(lp, "velocity_lp", fail)
        obs, reward, term, _, info = env.step(good)
    assert term and "sim_error" in info and "injected failure" in info["sim_error"]
    np.testing.assert_array_equal(obs, obs0)
    np.testing.assert_array_equal(info["object_pose"], info0["object_pose"])
    assert math.isfinite(reward)
    obs, info = env.reset(seed=0)
    np.testing.assert_array_equal(obs, first)
    obs, reward, term, _, info = env.step(good)
    assert "sim_error" not in info and not term
    assert_valid(
        env.unwrapped.state.scene, info["object_pose"],
        np.r_[info["palm_pose"], info["finger_angles"]], info["contacts"],
        tol_of(env.unwrapped.state.scene), "after recovery",
    )  # fmt: skip


#: A near-rectangle (sides within 1e-6 rad of parallel) wedged between the fingertips with
#: forces near 200 weights, found by this file's env property. At step 7 finger 1's force
#: reaches zero at a fold of the three contacts' equations; with the support and finger 2
#: left, the object is not held, and the fall's descent must find its way down a nearly flat
#: potential. With events located by bisection the fold was reached at a point where the
#: descent found no step that lowers the object (SimulationError); located by regula falsi
#: (closer to the exact event), the fall goes on. Whether such a fall finds its way is still
#: decided near rounding (docs/reliability.md): this keeps the case in view.
WEDGED_NEAR_RECTANGLE = {
    "name": "stress",
    "palm": {"width": 1.0, "thickness": 0.15, "pose": [-8.15801199649524e-08, 0.71, 0.0]},
    "fingers": [
        {"length": 0.6, "thickness": 0.05, "angle": -1.5707963267948966},
        {"length": 0.7, "thickness": 0.05, "angle": -1.5707963267948966},
    ],
    "object": {
        "vertices": [
            [-0.3426007469265146, 0.0],
            [0.34260058376627467, 0.0],
            [0.3425991741905726, 0.2520728798754651],
            [-0.3426007469250647, 0.25207096407270757],
        ],
        "mass": 2.643234028361877,
    },
}
WEDGED_ACTIONS = [
    (-0.2072627018756179, -0.8999592926653857, 0.5615634419022109, -0.4, 0.0),
    (-0.8513538123203164, 0.4578103861963283, 0.313560091271609, 0.0, -0.22770651212990933),
    (-0.19750958686296083, 0.45, -0.6365500089461484, -0.41488017737393734, 0.2871253416024311),
    (
        -0.7916294933781689,
        -0.09455089762324387,
        0.6676536689392809,
        -0.8778843850408928,
        -0.2779595673424352,
    ),
    (0.8507711484266638, 0.0, 0.0, 0.06886494509466945, 0.0),
    (0.0, 0.5427053560251656, 1e-07, 0.0, 0.0),
    (0.35654451574979995, 0.0, -0.049250712126766016, 0.0, 0.794833727293049),
    (0.88928131367659, 0.0, 0.0, -0.05318488749153638, -0.9999999999999999),
]


def test_wedged_near_rectangle_released_at_a_fold() -> None:
    run_env(grasp_env.load_scene(WEDGED_NEAR_RECTANGLE), "preliftoff", WEDGED_ACTIONS)
