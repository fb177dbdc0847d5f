"""Scale, mirror and shift invariance of the simulator (metamorphic tests).

A scene is transformed (scaled by k, mirrored left-right, shifted along x), the same hand
path transformed the same way is run on both, and the two results must be related by the
transformation, to within the contact tolerance:

* **scale by k** (every length, the palm pose's x and y; densities kept, so masses scale by
  k^2; or masses given and multiplied by m; torque limits by the force factor times k):
  object poses ``(k x, k y, theta)``, finger angles unchanged, contact points scaled by k,
  forces and the grip objective y* scaled by the mass factor (k^2 or m), the same events. k
  runs over the whole accepted range of palm widths (``scene.PALM_WIDTH_RANGE``), and the
  weight over the ends of the gravity and density ranges; scenes beyond are refused;
* **mirror** ``x -> -x``: finger 1 and finger 2 swap (lengths, thicknesses, limits), a finger
  angle ``q`` becomes ``-pi - q`` on the other side (axis ``(cos q, sin q)`` mirrored is
  ``(cos(-pi - q), sin(-pi - q))``), palm and object angles are negated, object vertices are
  mirrored and reversed (to stay counter-clockwise), contact normals mirrored;
* **shift** by dx: every x plus dx, nothing else changes.

Each run's states are also checked by :func:`grasp_env.testing.check_state`.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import grasp_env
from grasp_env import Simulator, planning, testing
from grasp_env.core import scene as scene_mod
from grasp_env.errors import SceneError
from grasp_env.mechanics import closure as mech

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

SCENES_DIR = Path(__file__).resolve().parents[2] / "grasp_env" / "scenes"
#: Pose agreement, as a fraction of the palm width (events are located to 1e-9 of it).
POSE_RTOL = 1e-7
FORCE_RTOL = 1e-6
#: Event locations (path parameter s): events are located to the contact tolerance (1e-9 palm
#: widths) along moves that sweep about 0.1 palm widths, i.e. s to about 1e-8.
EVENT_STOL = 1e-6
#: y* / W: the grip LP is solved on data of order one to HiGHS's 1e-7, on states that agree
#: to POSE_RTOL, which moves y* / W by about as much as it moves forces / W (FORCE_RTOL).
GRIP_RTOL = 1e-6


def raw(name: str) -> dict:
    d = yaml.safe_load((SCENES_DIR / f"{name}.yaml").read_text())
    d.pop("description", None)
    return d


# ---------------------------------------------------------------------------------------
# Transformations of a scene dict and of a hand configuration
# ---------------------------------------------------------------------------------------


def scale_scene(d: dict, k: float, mass: float | None = None) -> dict:
    """Every length times k; the object's mass given as ``mass`` (else densities kept); torque
    limits times the force factor times k (they are bounded relative to weight x palm width)."""
    force = k**2 if mass is None else mass / grasp_env.load_scene(d).object.mass
    d = copy.deepcopy(d)
    p = d["palm"]
    p["width"] *= k
    p["thickness"] = p.get("thickness", 0.15) * k
    p["pose"] = [p["pose"][0] * k, p["pose"][1] * k, p["pose"][2]]
    for f in d["fingers"]:
        f["length"] *= k
        f["thickness"] = f.get("thickness", 0.05) * k
        if "torque_limits" in f:
            f["torque_limits"] = [t * force * k for t in f["torque_limits"]]
    o = d["object"]
    o["vertices"] = [[x * k, y * k] for x, y in o["vertices"]]
    if mass is not None:
        o.pop("density", None)
        o["mass"] = mass
    return d


def mirror_scene(d: dict) -> dict:
    d = copy.deepcopy(d)
    p = d["palm"]
    p["pose"] = [-p["pose"][0], p["pose"][1], -p["pose"][2]]
    f1, f2 = d["fingers"]
    new = []
    for f in (f2, f1):
        g = dict(f)
        g["angle"] = -math.pi - f["angle"]
        lo, hi = f.get("limits", [-math.pi, 0.0])
        g["limits"] = [-math.pi - hi, -math.pi - lo]
        if "torque_limits" in f:
            a, b = f["torque_limits"]
            g["torque_limits"] = [-b, -a]
        new.append(g)
    d["fingers"] = new
    d["object"]["vertices"] = [[-x, y] for x, y in reversed(d["object"]["vertices"])]
    return d


def shift_scene(d: dict, dx: float) -> dict:
    d = copy.deepcopy(d)
    d["palm"]["pose"][0] += dx
    d["object"]["vertices"] = [[x + dx, y] for x, y in d["object"]["vertices"]]
    return d


def scale_hand(h: np.ndarray, k: float) -> np.ndarray:
    return np.array([h[0] * k, h[1] * k, h[2], h[3], h[4]])


def mirror_hand(h: np.ndarray) -> np.ndarray:
    return np.array([-h[0], h[1], -h[2], -math.pi - h[4], -math.pi - h[3]])


def shift_hand(h: np.ndarray, dx: float) -> np.ndarray:
    return np.array([h[0] + dx, h[1], h[2], h[3], h[4]])


# ---------------------------------------------------------------------------------------
# Runs
# ---------------------------------------------------------------------------------------


def hand_path(d: dict, kind: str, moves: int = 8) -> list[np.ndarray]:
    """Hand targets in the original scene: ``"close"`` closes both fingers at equal rates
    (0.06 rad per move: the paper's section 4); ``"palm"`` also moves and tilts the palm."""
    sc = grasp_env.load_scene(d)
    h = sc.initial_hand.copy()
    out = []
    rng = np.random.default_rng(7)
    for m in range(moves):
        h = h.copy()
        h[3] += 0.06
        h[4] -= 0.05 if kind == "palm" else 0.06
        if kind == "palm" and m % 2:
            h[:3] += rng.uniform([-0.02, -0.02, -0.05], [0.02, 0.01, 0.05])
        out.append(h)
    return out


def run(d: dict, path: list[np.ndarray]) -> list[grasp_env.State]:
    sim = Simulator(d, max_iterations=400)
    tol = 1e-9 * sim.scene.palm.width
    states = [sim.reset()]
    for h in path:
        states.append(sim.move_hand(states[-1], palm=h[:3], fingers=h[3:]))
    for i, st in enumerate(states):
        chk = testing.check_state(st.scene, st.object_pose, st.hand, st.contacts, tol)
        assert not chk.violations, f"state {i}: {chk.violations}"
    return states


def contact_table(st: grasp_env.State, point_map, body_map) -> list[tuple]:
    rows = []
    for c in st.contacts:
        p = point_map(np.asarray(c.point))
        rows.append((body_map(c.body), c.kind, p, c.force))
    return sorted(rows, key=lambda r: (r[0], round(float(r[2][0]), 6), round(float(r[2][1]), 6)))


def compare(
    a: list[grasp_env.State],
    b: list[grasp_env.State],
    pose_map,
    hand_map,
    point_map,
    body_map,
    force_factor: float,
    length: float,
) -> None:
    """``b`` must be ``a`` transformed: poses, hands, contacts (point, body, kind), forces and
    the events (kind and place along the move)."""
    for i, (sa, sb) in enumerate(zip(a, b, strict=True)):
        where = f"state {i}"
        assert [e.kind for e in sb.events] == [e.kind for e in sa.events], where
        np.testing.assert_allclose(
            [e.s for e in sb.events], [e.s for e in sa.events], atol=EVENT_STOL, err_msg=where
        )
        np.testing.assert_allclose(
            sb.object_pose, pose_map(sa.object_pose), atol=POSE_RTOL * length, err_msg=where
        )
        np.testing.assert_allclose(
            sb.hand, hand_map(sa.hand), atol=POSE_RTOL * length, err_msg=where
        )
        assert sb.jammed == sa.jammed and sb.hand_blocked == sa.hand_blocked, where
        ta = contact_table(sa, point_map, body_map)
        tb = contact_table(sb, lambda p: p, lambda s: s)
        assert [(r[0], r[1]) for r in ta] == [(r[0], r[1]) for r in tb], where
        for ra, rb in zip(ta, tb, strict=True):
            np.testing.assert_allclose(rb[2], ra[2], atol=POSE_RTOL * length, err_msg=where)
        W = sb.scene.object_weight
        # The least total force is unique; the forces themselves are when <= 3 contacts.
        total_a, total_b = sum(r[3] for r in ta), sum(r[3] for r in tb)
        assert total_b == pytest.approx(total_a * force_factor, rel=FORCE_RTOL, abs=1e-9 * W)
        if len(ta) <= 3:
            np.testing.assert_allclose(
                [r[3] * force_factor for r in ta], [r[3] for r in tb],
                rtol=FORCE_RTOL, atol=1e-9 * W, err_msg=where,
            )  # fmt: skip


CASES = [
    pytest.param("fig13", "close", id="fig13-close"),
    pytest.param("fig13", "palm", id="fig13-palm"),
    pytest.param("triangle", "close", id="triangle-close"),
    pytest.param("offset_pentagon", "palm", id="offset_pentagon-palm"),
]


def run_scaled(d: dict, path: list, a: list, k: float) -> list:
    """The run of ``path`` on scene ``d`` with every length times ``k`` (densities kept),
    compared with the unscaled run ``a``: lengths by k, forces by k^2, the rest equal."""
    b = run(scale_scene(d, k), [scale_hand(h, k) for h in path])
    compare(
        a, b,
        pose_map=lambda q: np.array([q[0] * k, q[1] * k, q[2]]),
        hand_map=lambda h: scale_hand(h, k),
        point_map=lambda p: p * k,
        body_map=lambda s: s,
        force_factor=k**2,
        length=k,
    )  # fmt: skip
    return b


@pytest.mark.parametrize(
    "k",
    [0.01, pytest.param(3.0, marks=pytest.mark.slow), 250.0],
    ids=["k0.01", "k3", "k250"],
)
@pytest.mark.parametrize(("name", "kind"), CASES)
def test_scale_invariance(name: str, kind: str, k: float) -> None:
    """Densities kept: masses, weights and forces scale by k^2; lengths by k."""
    d = raw(name)
    path = hand_path(d, kind)
    a = run(d, path)
    b = run_scaled(d, path, a, k)
    assert b[0].scene.object.mass == pytest.approx(a[0].scene.object.mass * k**2, rel=1e-12)


#: Object-pose agreement of a wedge across scales: at a fold the pose is fixed only to about
#: the square root of the tolerance.
WEDGE_POSE_TOL = 1e-5


def square_episode(k: float) -> tuple[np.ndarray, float]:
    """Seed 1's 30 random finger actions on square scaled by ``k`` from pre-liftoff: each
    state as (object x, y in palm widths, object angle, finger angles), every state checked
    independently, and the largest contact force met, in weights."""
    import gymnasium as gym

    env = gym.make("FrictionlessGrasp-v0", scene=scale_scene(raw("square"), k), start="preliftoff")
    env.reset(seed=1)
    rng = np.random.default_rng(1)
    tol = env.unwrapped.simulator.tol
    rows, most = [], 0.0
    for i in range(30):
        _, _, _, _, info = env.step(rng.uniform(-1.0, 1.0, 2).astype(np.float32))
        assert "sim_error" not in info, f"scale {k}, step {i}: {info['sim_error']}"
        st = env.unwrapped.state
        chk = testing.check_state(st.scene, st.object_pose, st.hand, st.contacts, tol)
        assert not chk.violations, f"scale {k}, step {i}: {chk.violations}"
        weight = st.scene.object_weight
        most = max([most, *(c.force / weight for c in st.contacts)])
        rows.append(
            [st.object_pose[0] / k, st.object_pose[1] / k, *st.object_pose[2:], *st.hand[3:]]
        )
    return np.array(rows), most


@pytest.mark.parametrize("k", [500.0, 2000.0])
def test_a_wedge_is_the_same_at_every_scale(k: float) -> None:
    """Regression (scale audit): these actions wedge the square on a corner between the
    fingertips, held by forces of millions of weights. A fall once started there and ran on
    the rounding of those forces: 1,889 pose solves at 1 palm width, a ``WorkLimitError`` at
    500, 1000 and 2000. The episode is the same, scaled, at every scale, every state valid."""
    ref, most = square_episode(1.0)
    assert most > 1e6  # the wedge is met
    got, _ = square_episode(k)
    np.testing.assert_allclose(got, ref, rtol=0.0, atol=WEDGE_POSE_TOL)


@pytest.mark.parametrize("mass", [1e-3, 10.0], ids=["light", "heavy"])
def test_mass_scaling_scales_forces_only(mass: float) -> None:
    """The same geometry with the object's mass given: poses unchanged, forces scale with the
    mass (quasi-static motion does not depend on the mass, eqs. 19-21)."""
    d = raw("fig13")
    path = hand_path(d, "palm")
    a = run(d, path)
    b = run(scale_scene(d, 1.0, mass=mass), path)
    compare(
        a, b, pose_map=lambda q: q, hand_map=lambda h: h, point_map=lambda p: p,
        body_map=lambda s: s, force_factor=mass / a[0].scene.object.mass, length=1.0,
    )  # fmt: skip


# ---------------------------------------------------------------------------------------
# The whole accepted range: fig13 closed to form closure at every scale
# ---------------------------------------------------------------------------------------

#: fig13 closing at 0.06 rad per move jams in form closure on the 13th move (the palm, two
#: object vertices on finger 1, one on finger 2): the kind of grasp whose y* the env rewards.
CLOSING_MOVES = 13
#: Finger 1's torque window (in object weights x palm widths) that binds in that grasp: it
#: must press harder than the least forces need, raising y* / W from 1.49 to 2.13.
BINDING = (0.5, 30.0)
#: Palm widths over scene.PALM_WIDTH_RANGE (fig13's palm width is 1), ends included.
SCALES = [1e-6, 1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6]


def with_finger1_torques(scene: grasp_env.Scene, limits: tuple[float, float]) -> grasp_env.Scene:
    f1 = dataclasses.replace(scene.fingers[0], torque_limits=limits)
    return dataclasses.replace(scene, fingers=(f1, scene.fingers[1]))


def grips(states: list[grasp_env.State]) -> tuple[list[float], list[float]]:
    """y* / W of every state with the scene's torque limits and with :data:`BINDING`."""
    sc = states[0].scene
    W, w = sc.object_weight, sc.palm.width
    binding = with_finger1_torques(sc, (BINDING[0] * W * w, BINDING[1] * W * w))
    own = [grasp_env.grip_objective(st) / W for st in states]
    bound = [grasp_env.grip_objective(dataclasses.replace(st, scene=binding)) / W for st in states]
    return own, bound


@pytest.fixture(scope="module")
def fig13_closing() -> tuple[dict, list[np.ndarray], list[grasp_env.State]]:
    d = raw("fig13")
    path = hand_path(d, "close", moves=CLOSING_MOVES)
    return d, path, run(d, path)


def test_fig13_closing_ends_in_form_closure(fig13_closing) -> None:
    """The reference run (k = 1): form closure at the end, y* / W as the paper's grasp needs
    (above 1: the fingers squeeze), raised by the binding torque window."""
    _, _, a = fig13_closing
    assert a[-1].jammed and grasp_env.is_form_closure(a[-1]) and not a[-1].on_support
    own, bound = grips(a)
    assert own[0] == pytest.approx(1.0, rel=1e-9)  # on the support: y* = W
    assert own[-1] == pytest.approx(1.4939714507, rel=GRIP_RTOL)
    assert bound[-1] == pytest.approx(2.1271411980, rel=GRIP_RTOL)


@pytest.mark.parametrize("k", SCALES, ids=[f"k{k:g}" for k in SCALES])
def test_scale_invariance_over_accepted_range(fig13_closing, k: float) -> None:
    """Lengths times k, densities kept: poses / k, forces / W, contacts, events and y* / W (with
    the scene's torque limits and with binding ones) as at k = 1; y* >= W > 0 in form
    closure."""
    d, path, a = fig13_closing
    b = run_scaled(d, path, a, k)
    closed = [grasp_env.is_form_closure(st) for st in a]
    assert [grasp_env.is_form_closure(st) for st in b] == closed
    for ya, yb in zip(grips(a), grips(b), strict=True):
        np.testing.assert_allclose(yb, ya, rtol=GRIP_RTOL)
    for closure, y in zip(closed, grips(b)[0], strict=True):
        if closure:
            assert y >= 1.0  # y* >= W: the force rows sum unit normals


def scaled_state(st: grasp_env.State, scene: grasp_env.Scene, k: float) -> grasp_env.State:
    """``st`` with every length times k and forces times k^2, in ``scene`` (scaled alike)."""
    contacts = tuple(
        dataclasses.replace(c, point=c.point * k, force=c.force * k**2, gap=c.gap * k)
        for c in st.contacts
    )
    pose, hand = st.object_pose * [k, k, 1.0], scale_hand(st.hand, k)
    return dataclasses.replace(st, scene=scene, object_pose=pose, hand=hand, contacts=contacts)


@pytest.mark.parametrize("k", SCALES, ids=[f"k{k:g}" for k in SCALES])
def test_analysis_invariance_over_accepted_range(fig13_closing, k: float) -> None:
    """The analysis alone, on the k = 1 run's states scaled by k (no simulation): form and
    force closure, escape directions and y* / W as at k = 1, y* >= W > 0 wherever it is finite."""
    d, _, a = fig13_closing
    scene = grasp_env.load_scene(scale_scene(d, k))
    b = [scaled_state(st, scene, k) for st in a]
    for i, (sa, sb) in enumerate(zip(a, b, strict=True)):
        assert grasp_env.is_form_closure(sb) == grasp_env.is_form_closure(sa), f"state {i}"
        assert grasp_env.is_force_closure(sb) == grasp_env.is_force_closure(sa), f"state {i}"
        ub = grasp_env.escape_direction(sb)
        assert (ub is None) == (grasp_env.escape_direction(sa) is None), f"state {i}"
        if ub is not None:  # an escape twist (vx, vy, omega) at k is (k vx, k vy, omega) at 1
            p, n, _ = sa.contact_arrays()
            u = ub * [1.0 / k, 1.0 / k, 1.0]
            assert np.all(mech.V_ob(p, n, sa.object_pose[:2]) @ u >= -1e-9 * np.linalg.norm(u))
    for ya, yb in zip(grips(a), grips(b), strict=True):
        np.testing.assert_allclose(yb, ya, rtol=GRIP_RTOL)
        assert all(y >= 1.0 for y in yb)  # y* >= W, the triangle inequality on the force rows


@pytest.mark.parametrize(
    ("density", "gravity"),
    [(scene_mod.DENSITY_RANGE[0], scene_mod.GRAVITY_RANGE[0]),
     (scene_mod.DENSITY_RANGE[1], scene_mod.GRAVITY_RANGE[1])],
    ids=["lightest", "heaviest"],
)  # fmt: skip
def test_weight_invariance_at_range_ends(fig13_closing, density: float, gravity: float) -> None:
    """Every density and gravity at an end of their ranges (weights 1e-18 / 9.81 and 1e18 / 9.81
    times fig13's): the same motion, forces and y* scaled by the weight."""
    d, path, a = fig13_closing
    e = copy.deepcopy(d)
    for body in (e["palm"], *e["fingers"], e["object"]):
        body["density"] = density
    e["gravity"] = gravity
    factor = density * gravity / (d["object"]["density"] * d["gravity"])
    for f in e["fingers"]:
        f["torque_limits"] = [t * factor for t in f["torque_limits"]]
    b = run(e, path)
    compare(
        a, b, pose_map=lambda q: q, hand_map=lambda h: h, point_map=lambda p: p,
        body_map=lambda s: s, force_factor=factor, length=1.0,
    )  # fmt: skip
    for ya, yb in zip(grips(a), grips(b), strict=True):
        np.testing.assert_allclose(yb, ya, rtol=GRIP_RTOL)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: scale_scene(d, scene_mod.PALM_WIDTH_RANGE[0] / 10), r"palm\.width"),
        (lambda d: scale_scene(d, scene_mod.PALM_WIDTH_RANGE[1] * 10), r"palm\.width"),
        (lambda d: {**d, "gravity": scene_mod.GRAVITY_RANGE[0] / 10}, r"gravity"),
        (lambda d: {**d, "gravity": scene_mod.GRAVITY_RANGE[1] * 10}, r"gravity"),
        (
            lambda d: {**d, "object": {**d["object"], "density": scene_mod.DENSITY_RANGE[1] * 10}},
            r"object\.density",
        ),
        (lambda d: scale_scene(d, 1.0, mass=1e-12), r"object\.mass"),
    ],
    ids=["k-too-small", "k-too-large", "gravity-too-small", "gravity-too-large",
         "density-too-large", "mass-too-small"],
)  # fmt: skip
def test_scales_beyond_the_range_are_refused(change, field: str) -> None:
    with pytest.raises(SceneError, match=field):
        grasp_env.load_scene(change(raw("fig13")))


SWAP = {"finger1": "finger2", "finger2": "finger1"}


@pytest.mark.parametrize(("name", "kind"), CASES)
def test_mirror_invariance(name: str, kind: str) -> None:
    d = raw(name)
    path = hand_path(d, kind)
    a = run(d, path)
    b = run(mirror_scene(d), [mirror_hand(h) for h in path])
    compare(
        a, b,
        pose_map=lambda q: np.array([-q[0], q[1], -q[2]]),
        hand_map=mirror_hand,
        point_map=lambda p: np.array([-p[0], p[1]]),
        body_map=lambda s: SWAP.get(s, s),
        force_factor=1.0,
        length=1.0,
    )  # fmt: skip
    for sa, sb in zip(a, b, strict=True):  # normals mirror too
        na = sorted((SWAP.get(c.body, c.body), -c.normal[0], c.normal[1]) for c in sa.contacts)
        nb = sorted((c.body, c.normal[0], c.normal[1]) for c in sb.contacts)
        for ra, rb in zip(na, nb, strict=True):
            assert ra[0] == rb[0]
            np.testing.assert_allclose(ra[1:], rb[1:], atol=1e-6)


@pytest.mark.parametrize(
    "dx", [pytest.param(-0.37, marks=pytest.mark.slow), 10.0], ids=["dx-0.37", "dx10"]
)
@pytest.mark.parametrize(("name", "kind"), CASES)
def test_shift_invariance(name: str, kind: str, dx: float) -> None:
    d = raw(name)
    path = hand_path(d, kind)
    a = run(d, path)
    b = run(shift_scene(d, dx), [shift_hand(h, dx) for h in path])
    compare(
        a, b,
        pose_map=lambda q: q + np.array([dx, 0.0, 0.0]),
        hand_map=lambda h: shift_hand(h, dx),
        point_map=lambda p: p + np.array([dx, 0.0]),
        body_map=lambda s: s,
        force_factor=1.0,
        length=1.0,
    )  # fmt: skip


def test_transformations_are_involutions() -> None:
    """Sanity of the helpers: mirroring twice and scaling by k then 1/k give the scene back."""
    d = raw("fig13")
    twice = mirror_scene(mirror_scene(d))
    assert twice["fingers"][0]["angle"] == pytest.approx(d["fingers"][0]["angle"])
    np.testing.assert_allclose(twice["object"]["vertices"], d["object"]["vertices"])
    np.testing.assert_allclose(mirror_hand(mirror_hand(np.arange(5.0))), np.arange(5.0))
    back = scale_scene(scale_scene(d, 4.0), 0.25)
    assert back["palm"]["width"] == pytest.approx(d["palm"]["width"])
    # The mirrored scene's fingers are the mirror images: tip of new finger 1 = mirrored tip
    # of old finger 2.
    s0, s1 = grasp_env.load_scene(d), grasp_env.load_scene(mirror_scene(d))
    t0 = testing.hand_polygons_W(s0, s0.initial_hand)["finger2"]
    t1 = testing.hand_polygons_W(s1, s1.initial_hand)["finger1"]
    assert {tuple(p) for p in np.round(t0 * [-1, 1], 12)} == {tuple(p) for p in np.round(t1, 12)}


# ---------------------------------------------------------------------------------------
# The planner
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fig13_plan() -> planning.Plan:
    return planning.plan_grasp(grasp_env.load_scene(raw("fig13")))


@pytest.mark.parametrize("k", [1e-6, 1e-3, 1e3, 1e6], ids=lambda k: f"k{k:g}")
def test_plan_invariance_over_accepted_range(fig13_plan, k: float) -> None:
    """The paper's planner on fig13 with every length times k (densities kept): the same
    placement, phases and number of steps, the hand path and object poses times k, and y* / W
    as at k = 1, through the grip adjustment to its local minimum."""
    a = fig13_plan
    b = planning.plan_grasp(grasp_env.load_scene(scale_scene(raw("fig13"), k)))
    assert a.success and b.status == a.status and b.placement == a.placement
    assert [s.phase for s in b.steps] == [s.phase for s in a.steps]
    wa, wb = a.steps[0].state.scene.object_weight, b.steps[0].state.scene.object_weight
    for sa, sb in zip(a.steps, b.steps, strict=True):
        np.testing.assert_allclose(scale_hand(sb.state.hand, 1 / k), sa.state.hand, atol=POSE_RTOL)
        np.testing.assert_allclose(
            sb.state.object_pose / [k, k, 1.0], sa.state.object_pose, atol=POSE_RTOL
        )
        # y* where the plan computed it (nan: not computed, inf: no grasp)
        assert sb.grip / wb == pytest.approx(sa.grip / wa, rel=GRIP_RTOL, nan_ok=True)
    assert b.steps[-1].grip / wb == pytest.approx(1.4939660, rel=1e-6)  # the paper's 1.49
