"""Degenerate contact geometry, one test per case, each against a closed form.

Every returned state is also checked by :func:`grasp_env.testing.check_state` (independent
geometry and mechanics). The expected poses, stopping points and contact sets come from the
geometry of each set-up, worked out in the docstrings, never from an earlier run of the
simulator.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.optimize import minimize_scalar
from scipy.spatial import ConvexHull

import grasp_env
from grasp_env import Simulator, testing

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

HALF_PI = math.pi / 2
TOL = 1e-9  # contact_tol x palm width (1)
POSE_TOL = 1e-7


def scene(
    vertices: list,
    palm: tuple[float, float, float],
    q: tuple[float, float],
    lengths: tuple[float, float] = (0.6, 0.7),
    limits: tuple[tuple[float, float], tuple[float, float]] = ((-math.pi, 0.0), (-math.pi, 0.0)),
    mass: float = 1.0,
) -> grasp_env.Scene:
    """A scene with a unit-width palm (thickness 0.15), fingers of thickness 0.05."""
    return grasp_env.load_scene(
        {
            "name": "degenerate",
            "palm": {"width": 1.0, "thickness": 0.15, "pose": list(palm)},
            "fingers": [
                {"length": L, "thickness": 0.05, "angle": a, "limits": list(lim)}
                for L, a, lim in zip(lengths, q, limits, strict=True)
            ],
            "object": {"vertices": [list(map(float, v)) for v in vertices], "mass": mass},
        }
    )


def valid(state: grasp_env.State, where: str = "") -> None:
    tol = TOL * state.scene.palm.width  # the contact tolerance at the scene's scale
    chk = testing.check_state(state.scene, state.object_pose, state.hand, state.contacts, tol)
    assert not chk.violations, f"{where}: " + "; ".join(chk.violations)


def contacts_of(state: grasp_env.State, body: str) -> list:
    return [c for c in state.contacts if c.body == body]


def kinds(state: grasp_env.State) -> list[tuple[str, str]]:
    return sorted((c.body, c.kind) for c in state.contacts)


def box(x0: float, x1: float, h: float) -> list[list[float]]:
    return [[x0, 0.0], [x1, 0.0], [x1, h], [x0, h]]


# ---------------------------------------------------------------------------------------


def test_edge_flush_with_finger_gives_two_contacts() -> None:
    """Finger 2 hangs straight down (palmar edge on x = x_p + 0.5, from y_p - 0.7 to y_p);
    the box's right side is 0.05 to its left. Moving the palm 0.08 to the left makes the
    palmar edge flush with the side after 0.05 and pushes the frictionless box 0.03 along the
    support (no rotation: the push is horizontal through a vertical side). The overlap of
    the side (y in [0, 0.3]) and the palmar edge (y in [0.05, 0.75]) is [0.05, 0.3]: two
    contacts, finger 2's tip (tip kind) at y = 0.05 and the box's top-right corner (edge
    kind) at y = 0.3."""
    sc = scene(box(0.15, 0.45, 0.3), (0.0, 0.75, 0.0), (-HALF_PI, -HALF_PI))
    sim = Simulator(sc)
    start = sim.reset()
    state = sim.move_hand(start, palm=(-0.08, 0.75, 0.0))
    valid(state, "pushed")
    assert not state.jammed
    np.testing.assert_allclose(state.object_pose, start.object_pose - [0.03, 0.0, 0.0], atol=1e-9)
    f2 = sorted(contacts_of(state, "finger2"), key=lambda c: c.point[1])
    assert [c.kind for c in f2] == ["tip", "edge"]
    np.testing.assert_allclose(f2[0].point, [0.42, 0.05], atol=1e-9)
    np.testing.assert_allclose(f2[1].point, [0.42, 0.3], atol=1e-9)
    for c in f2:
        np.testing.assert_allclose(c.normal, [-1.0, 0.0], atol=1e-12)


def test_edge_flush_with_palm_gives_two_contacts() -> None:
    """Fingers spread out sideways (q1 = -pi + 0.3, q2 = -0.3: tips 0.18 and 0.21 below the
    palm), palm lowered from y = 0.5 onto a box of height 0.3: the palm's flat underside
    comes flush with the box's top at y_p = 0.3, where the hand jams (the box cannot go
    down); the box's two top corners are the palm's two contacts, with normal (0, -1)."""
    sc = scene(box(-0.1, 0.1, 0.3), (0.0, 0.5, 0.0), (-math.pi + 0.3, -0.3))
    sim = Simulator(sc)
    start = sim.reset()
    state = sim.move_hand(start, palm=(0.0, 0.25, 0.0))  # finger 2's tip stays above y = 0
    valid(state, "pressed")
    assert state.jammed and not state.hand_blocked
    assert abs(state.palm_pose[1] - 0.3) <= TOL
    np.testing.assert_allclose(state.object_pose, start.object_pose, atol=1e-12)
    palm = sorted(contacts_of(state, "palm"), key=lambda c: c.point[0])
    assert [c.kind for c in palm] == ["edge", "edge"]
    np.testing.assert_allclose([c.point for c in palm], [[-0.1, 0.3], [0.1, 0.3]], atol=1e-9)
    for c in palm:
        np.testing.assert_allclose(c.normal, [0.0, -1.0], atol=1e-12)


def test_vertex_meets_vertex() -> None:
    """Finger 2 hangs straight down with its palmar tip corner T exactly above the apex of an
    isosceles triangle (base [0.3, 0.7], apex (0.5, 0.3)); the finger's body lies at
    x in [0.5, 0.55], over the triangle's right edge. Lowering the palm from y_p = 1.1 to 0.9
    brings T onto the apex at y_p = 1.0 (vertex on vertex). Of the two half-planes there,
    only the right edge's lets the triangle move without going down (the end face would push
    the apex into the support): the triangle slides left along the support with T on its
    right edge. At the end T = (0.5, 0.2); the right edge, of slope -3/2 from the apex,
    passes through T when the apex is at x = 0.5 - 0.1 / 1.5: a shift of -1/15, no turn."""
    sc = scene([[0.3, 0.0], [0.7, 0.0], [0.5, 0.3]], (0.0, 1.1, 0.0), (-HALF_PI, -HALF_PI))
    sim = Simulator(sc)
    start = sim.reset()
    touch = sim.move_hand(start, palm=(0.0, 1.0, 0.0))
    valid(touch, "touching")
    np.testing.assert_allclose(touch.object_pose, start.object_pose, atol=1e-12)
    assert contacts_of(touch, "finger2"), kinds(touch)  # vertex on vertex is a contact
    for c in contacts_of(touch, "finger2"):
        np.testing.assert_allclose(c.point, [0.5, 0.3], atol=2 * TOL)
    state = sim.move_hand(touch, palm=(0.0, 0.9, 0.0))
    valid(state, "vertex on vertex")
    assert not state.jammed
    np.testing.assert_allclose(
        state.object_pose, start.object_pose - [1.0 / 15.0, 0.0, 0.0], atol=POSE_TOL
    )
    f2 = contacts_of(state, "finger2")
    assert [c.kind for c in f2] == ["tip"]
    np.testing.assert_allclose(f2[0].point, [0.5, 0.2], atol=1e-9)
    np.testing.assert_allclose(f2[0].normal, -np.array([3.0, 2.0]) / math.sqrt(13), atol=1e-9)


def test_symmetric_grasp_translates_without_rotating() -> None:
    """Mirror-symmetric grasp: two fingers of length 0.6 hanging flush against the sides of a
    box exactly as wide as the finger gap (1.0), palm centred over it. Moving the whole hand
    sideways by dx pushes the box with equal and opposite horizontal palmar normals: it must
    translate by exactly dx along the frictionless support without turning."""
    sc = scene(box(-0.5, 0.5, 0.2), (0.0, 0.65, 0.0), (-HALF_PI, -HALF_PI), lengths=(0.6, 0.6))
    sim = Simulator(sc)
    start = sim.reset()
    for dx in (0.05, -0.02):
        state = sim.move_hand(start, palm=(dx, 0.65, 0.0))
        valid(state, f"translate {dx}")
        assert not state.jammed
        expected = start.object_pose + np.array([dx, 0.0, 0.0])
        np.testing.assert_allclose(state.object_pose, expected, atol=1e-9)
        assert state.object_pose[2] == pytest.approx(0.0, abs=1e-12)


def test_object_exactly_as_wide_as_fingertip_gap() -> None:
    """Fingers hanging straight down, palm width 1: the gap between the palmar edges (and the
    fingertips) is exactly 1.0, the box's width. At the start both sides are flush: finger 1
    (tip at y = 0.65 - 0.6 = 0.05) and finger 2 (tip at 0.65 - 0.62 = 0.03) each touch the box
    at their tip and at the box's top corner (y = 0.2). Closing either finger squeezes the
    box between parallel faces: the velocity LP is infeasible, so the hand jams at s = 0.
    Raising the palm lets the fingers slide up along the frictionless sides: the box stays."""
    sc = scene(box(-0.5, 0.5, 0.2), (0.0, 0.65, 0.0), (-HALF_PI, -HALF_PI), lengths=(0.6, 0.62))
    sim = Simulator(sc)
    start = sim.reset()
    valid(start, "start")
    assert kinds(start) == sorted(
        [("finger1", "edge"), ("finger1", "tip"), ("finger2", "edge"), ("finger2", "tip")]
        + [("support", "edge")] * 2
    )
    tips = sorted(
        (tuple(np.round(c.point, 9)) for c in start.contacts if c.kind == "tip"),
    )
    assert tips == [(-0.5, 0.05), (0.5, 0.03)]
    closed = sim.move_hand(start, fingers=(-HALF_PI + 0.05, -HALF_PI))
    valid(closed, "closed")
    assert closed.jammed
    np.testing.assert_allclose(closed.hand, start.hand, atol=1e-9)
    np.testing.assert_allclose(closed.object_pose, start.object_pose, atol=1e-12)
    raised = sim.move_hand(start, palm=(0.0, 0.9, 0.0))
    valid(raised, "raised")
    assert not raised.jammed
    np.testing.assert_allclose(raised.object_pose, start.object_pose, atol=1e-12)
    assert kinds(raised) == [("support", "edge")] * 2  # tips at 0.3 and 0.28 > 0.2


def _finger2_polygon(yp: float, q: float, L: float = 0.7, t: float = 0.05) -> np.ndarray:
    J = np.array([0.5, yp])
    u = np.array([math.cos(q), math.sin(q)])
    n = np.array([u[1], -u[0]])  # u turned by -pi/2: finger 2's inward normal
    T = J + L * u
    return np.array([J, T, T - t * n, J - t * n])


def _touch_shift(A: np.ndarray, B: np.ndarray) -> float:
    """Largest t such that ``A + (t, 0)`` does not overlap convex ``B`` coming from the left:
    the leftmost point of the Minkowski difference ``B - A`` on the line y = 0."""
    P = (B[:, None, :] - A[None, :, :]).reshape(-1, 2)
    hull = P[ConvexHull(P).vertices]
    xs = [
        a[0] - a[1] * (b[0] - a[0]) / (b[1] - a[1])
        for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True)
        if a[1] * b[1] <= 0 and a[1] != b[1]
    ]
    return min(xs) if xs else math.inf


def test_contact_appears_and_vanishes_in_one_move() -> None:
    """One straight hand move: the palm rises from y = 0.75 to 0.95 while finger 2 swings
    from q2 = -pi/2 + 0.3 to -pi/2 - 0.5 (tip sweeping right to left along a low arc). The
    finger catches a wedge (right triangle, hypotenuse facing up-right) standing at
    x_w = 0.55, pushes it left along the support (frictionless: it slides without turning)
    and rises off it again. Expected final x_w: the smallest, over the move, of the wedge
    position just touching the finger from the left (the Minkowski difference of the finger
    and the wedge cut by a horizontal line, minimised over s here with scipy)."""
    W0 = np.array([[0.0, 0.0], [0.15, 0.0], [0.0, 0.15]])
    x0 = 0.55
    sc = scene(W0 + np.array([x0, 0.0]), (0.0, 0.75, 0.0), (-HALF_PI, -HALF_PI + 0.3))
    sim = Simulator(sc)
    start = sim.reset()
    valid(start, "start")

    def shift(s: float) -> float:
        return _touch_shift(W0, _finger2_polygon(0.75 + 0.2 * s, -HALF_PI + 0.3 - 0.8 * s))

    grid = np.linspace(0.0, 1.0, 401)
    k = int(np.argmin([shift(s) for s in grid]))
    best = minimize_scalar(shift, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, 400)]),
                           method="bounded", options={"xatol": 1e-12})  # fmt: skip
    expected = min(x0, float(best.fun))
    assert expected < x0 - 0.05 and shift(1.0) > expected + 0.05  # touches, then leaves

    state = sim.move_hand(start, palm=(0.0, 0.95, 0.0), fingers=(-HALF_PI, -HALF_PI - 0.5))
    valid(state, "after sweep")
    assert not state.jammed
    assert "new_contact" in [e.kind for e in state.events], state.events
    assert not contacts_of(state, "finger2")
    x_w = start.object_pose[0] - x0  # centroid offset from the wedge's corner
    np.testing.assert_allclose(
        state.object_pose, [expected + x_w, start.object_pose[1], 0.0], atol=POSE_TOL
    )


def test_jam_in_first_increment() -> None:
    """The palm starts flush on the top of a box (y_p = 0.3 = box height; fingers spread
    out). Pushing the palm further down is impossible from s = 0: the hand jams at once,
    nothing moves, and the jammed state lists the palm's two contacts."""
    sc = scene(box(-0.1, 0.1, 0.3), (0.0, 0.3, 0.0), (-math.pi + 0.3, -0.3))
    sim = Simulator(sc)
    start = sim.reset()
    valid(start, "start")
    state = sim.move_hand(start, palm=(0.0, 0.25, 0.0))
    valid(state, "jammed")
    assert state.jammed
    assert [e.s for e in state.events if e.kind == "jam"] == [0.0]
    np.testing.assert_allclose(state.hand, start.hand, atol=1e-12)
    np.testing.assert_allclose(state.object_pose, start.object_pose, atol=1e-12)
    assert len(contacts_of(state, "palm")) == 2


def test_fingers_at_joint_limits() -> None:
    """Finger 1 starts exactly at its closing limit -pi/2 + 0.2 and finger 2 exactly at its
    opening limit -pi/2 + 0.1 (limits [-pi, -pi/2 + 0.2] and [-pi/2 - 0.4, -pi/2 + 0.1]).
    Targets beyond the limits are clipped to them exactly (a "joint_limit" event, no jam,
    nothing moves); targets inside are reached; a target past the limit on one finger only
    moves the other."""
    lim1, lim2 = (-math.pi, -HALF_PI + 0.2), (-HALF_PI - 0.4, -HALF_PI + 0.1)
    sc = scene(box(-0.15, 0.15, 0.2), (0.0, 0.75, 0.0), (lim1[1], lim2[1]), limits=(lim1, lim2))
    sim = Simulator(sc)
    start = sim.reset()
    valid(start, "start")
    state = sim.move_hand(start, fingers=(lim1[1] + 0.3, lim2[1] + 0.3))
    valid(state, "past both limits")
    assert state.finger_angles.tolist() == [lim1[1], lim2[1]]
    assert "joint_limit" in [e.kind for e in state.events] and not state.jammed
    state = sim.move_hand(start, fingers=(lim1[1] + 0.3, lim2[1] - 0.2))
    valid(state, "finger 1 past its limit")
    assert state.finger_angles.tolist() == [lim1[1], lim2[1] - 0.2]
    state = sim.move_hand(start, fingers=(lim1[0] - 1.0, lim2[0] - 1.0))
    valid(state, "past the other limits")
    assert state.finger_angles.tolist() == [lim1[0], lim2[0]]
    np.testing.assert_allclose(state.object_pose, start.object_pose, atol=1e-12)


def test_hand_pressed_against_support() -> None:
    """Both fingers stretched out sideways (q1 = -pi, q2 = 0, bodies above their palmar
    edges), so the palm's underside and the palmar edges are the hand's lowest points, at
    y = y_p. Lowering the palm from y = 0.2 towards -0.1 stops exactly on the support
    (y_p = 0, hand_blocked, s = 2/3); pressing again does not move it. Sliding along the
    support is free, and finger 2's end face (x = 0.5 + 0.7 + x_p) then pushes a box standing
    at x in [1.5, 1.7]: the box's left side ends at the end face, x_p + 1.2."""
    sc = scene(box(1.5, 1.7, 0.2), (0.0, 0.2, 0.0), (-math.pi, 0.0))
    sim = Simulator(sc)
    start = sim.reset()
    state = sim.move_hand(start, palm=(0.0, -0.1, 0.0))
    valid(state, "pressed")
    assert state.hand_blocked and not state.jammed
    assert abs(state.palm_pose[1]) <= TOL
    again = sim.move_hand(state, palm=(0.0, -0.1, 0.0))
    assert again.hand_blocked
    np.testing.assert_allclose(again.hand, state.hand, atol=1e-9)
    slid = sim.move_hand(state, palm=(0.4, state.palm_pose[1], 0.0))
    valid(slid, "slid and pushed")
    assert not slid.hand_blocked and not slid.jammed
    assert slid.palm_pose[0] == pytest.approx(0.4, abs=1e-12)
    left = slid.object_pose[0] - 0.1  # the box's left side
    assert left == pytest.approx(0.4 + 1.2, abs=1e-9)
    assert slid.object_pose[1] == pytest.approx(0.1, abs=1e-12)
    assert slid.object_pose[2] == pytest.approx(0.0, abs=1e-12)
    assert contacts_of(slid, "finger2")


def test_jam_before_the_support_is_not_hand_blocked() -> None:
    """The palm-flush set-up lowered towards y_p = 0.2: finger 2 (q2 = -0.3, tip 0.207 below
    the palm) would enter the support only below y_p = 0.207, but the hand jams on the box at
    y_p = 0.3 first. ``hand_blocked`` means "stopped short because the hand would enter the
    support" (``State.hand_blocked``): it must be False here, with ``jammed`` True."""
    sc = scene(box(-0.1, 0.1, 0.3), (0.0, 0.5, 0.0), (-math.pi + 0.3, -0.3))
    sim = Simulator(sc)
    state = sim.move_hand(sim.reset(), palm=(0.0, 0.2, 0.0))
    valid(state, "pressed")
    assert abs(state.palm_pose[1] - 0.3) <= TOL
    assert state.jammed
    assert not state.hand_blocked, [(e.kind, e.s) for e in state.events]


@pytest.mark.parametrize("bulge", [3e-12, 1e-10, 9e-10])
@pytest.mark.parametrize("where", [0.5, 0.2])
def test_nearly_straight_resting_edge_is_one_supporting_edge(bulge: float, where: float) -> None:
    """A resting side of three vertices whose middle one lies ``bulge`` (inside the contact
    tolerance) below the line through its neighbours rests on all three: their gap
    equations are dependent and, off the line, inconsistent. They are one supporting edge,
    not a jam: the hanging fingers close in free space to their targets with no event, the
    object exactly where it was (nothing but the support touches it); closing on, finger 1
    reaches the block's top corner and the state stays valid."""
    x_mid = -0.1 + 0.2 * where
    block = [[-0.1, bulge], [x_mid, 0.0], [0.1, bulge], [0.1, 0.3], [-0.1, 0.3]]
    sim = Simulator(scene(block, palm=(0.0, 0.71, 0.0), q=(-HALF_PI, -HALF_PI)))
    state = sim.reset()
    assert sorted(c.object_feature for c in contacts_of(state, "support")) == [0, 1, 2]
    start = state.object_pose.copy()
    for k in range(1, 6):
        target = (-HALF_PI + k * 0.05, -HALF_PI - k * 0.05)
        state = sim.move_hand(state, fingers=target)
        np.testing.assert_array_equal(state.finger_angles, target)
        assert state.events == () and not state.jammed
        np.testing.assert_array_equal(state.object_pose, start)
        valid(state, f"step {k}")
    state = sim.move_hand(state, fingers=(-0.6, -HALF_PI))
    valid(state, "closing onto the block")
    touched = [e for e in state.events if e.kind == "new_contact" and e.contacts]
    assert touched and touched[0].contacts[0][0] == 2  # finger 1 reaches the block


def test_nearly_straight_resting_edge_through_the_env() -> None:
    """The same through ``gym.make`` with palm control: the fingers move on every step."""
    import gymnasium as gym

    from grasp_env.envs.shapes import scene_to_dict

    d = scene_to_dict(grasp_env.load_scene("fig13"))
    d["object"] = {
        "vertices": [[-0.1, 1e-10], [0, 0], [0.1, 1e-10], [0.1, 0.1], [-0.1, 0.1]],
        "density": 1.0,
    }
    d["palm"]["pose"] = [0, 0.71, 0]
    d["fingers"][0]["angle"] = d["fingers"][1]["angle"] = -HALF_PI
    env = gym.make("FrictionlessGrasp-v0", scene=d, palm_control=True)
    env.reset(seed=0)
    for k in range(1, 4):
        env.step(np.array([1, 1, 0, 0, 0], np.float32))
        state = env.unwrapped.state
        assert state.events == ()
        assert state.finger_angles[0] == pytest.approx(-HALF_PI + k * 0.05)


#: The bundled square tilted-palm placement whose squeeze wedges the object: finger 1's edge
#: on the square's left side, finger 2's tip on its right side, the object resting on its
#: base. Squeezing turns the contact normals concurrent (a fold): the forces that hold the
#: object grow without bound, so no motion avoids penetration -- a jam.
SQUARE_FOLD = {
    "pose": [0.0, 0.15, 0.0],
    "hand": [0.32876130738160625, 0.5255149227663095, -0.4, -1.2141526834298952,
             -2.322046743957673],
    "fingers": [-1.1941526834298952, -2.342046743957673],
}  # fmt: skip


def _square(scale: float = 1.0, dx: float = 0.0) -> tuple[Simulator, grasp_env.State]:
    """The fold's start, every length times ``scale`` and shifted by ``dx`` palm widths
    (densities over scale^2, so the weight stays): rounding-level changes of the same move."""
    raw = yaml.safe_load((Path(grasp_env.__file__).parent / "scenes" / "square.yaml").read_text())
    raw["palm"]["width"] *= scale
    raw["palm"]["thickness"] = raw["palm"].get("thickness", 0.15) * scale
    raw["palm"]["pose"] = [
        (raw["palm"]["pose"][0] + dx) * scale,
        raw["palm"]["pose"][1] * scale,
        0.0,
    ]
    for f in raw["fingers"]:
        f["length"] *= scale
        f["thickness"] = f.get("thickness", 0.05) * scale
        f.pop("torque_limits", None)
    raw["object"]["vertices"] = [
        [(x + dx) * scale, y * scale] for x, y in raw["object"]["vertices"]
    ]
    for body in (raw["palm"], *raw["fingers"], raw["object"]):
        body["density"] = body.get("density", 1.0) / scale**2
    sim = Simulator(grasp_env.load_scene(raw))
    shift = np.array([dx, 0.0, 0.0, 0.0, 0.0])
    pose = (np.array(SQUARE_FOLD["pose"]) + shift[:3]) * [scale, scale, 1.0]
    hand = (np.array(SQUARE_FOLD["hand"]) + shift) * [scale, scale, 1.0, 1.0, 1.0]
    return sim, sim.settle(pose, hand)


@pytest.mark.parametrize(
    ("scale", "dx"), [(1.0, 0.0), (1.0 + 1e-12, 0.0), (1.0, 0.37), (1e3, 0.0), (1e-3, 0.0)]
)
def test_a_fold_is_a_jam_whatever_the_rounding(scale: float, dx: float) -> None:
    """Squeezing into the fold jams, at the same place for every rounding of the same move.
    Checked independently: the three contact wrenches are nearly dependent (their normalised
    determinant is small), every force is positive and large, and no contact was lost on the
    way (a force that passes through infinity changes sign without passing through zero)."""
    sim, start = _square(scale, dx)
    end = sim.move_hand(start, fingers=SQUARE_FOLD["fingers"])
    valid(end, "fold")
    assert end.jammed and "lost_contact" not in {e.kind for e in end.events}
    W = sim.scene.object_weight
    forces = np.array([c.force for c in end.contacts]) / W
    assert len(forces) == 3 and forces.min() > 0 and forces.max() > 1e4
    size = float(np.linalg.norm(sim.scene.object.vertices_B, axis=1).max())
    rows = []
    for c in end.contacts:
        r = (c.point - end.object_pose[:2]) / size
        rows.append([c.normal[0], c.normal[1], r[0] * c.normal[1] - r[1] * c.normal[0]])
    rows = np.array(rows) / np.linalg.norm(rows, axis=1)[:, None]
    assert abs(np.linalg.det(rows)) < 1e-3
    ref_sim, ref_start = _square()
    ref = ref_sim.move_hand(ref_start, fingers=SQUARE_FOLD["fingers"])
    np.testing.assert_allclose(
        (end.object_pose - [dx * scale, 0.0, 0.0]) / [scale, scale, 1.0], ref.object_pose, atol=1e-6
    )


def _jammed_at_a_fold() -> tuple[Simulator, grasp_env.State]:
    """A pentagon squeezed (finger 1 closing faster) until the hand jams with a fingertip of
    zero force and the contacts dependent to about 3e-10, then the palm raised: a jammed
    state on a fold."""
    scene = {
        "name": "pentagon_at_a_fold",
        "gravity": 9.81,
        "palm": {"width": 1.0, "thickness": 0.15, "pose": [-0.07856536427993029, 0.71, 0.0]},
        "fingers": [
            {"length": 0.6, "thickness": 0.05, "angle": -math.pi / 2, "torque_limits": [-50, 50]},
            {"length": 0.7, "thickness": 0.05, "angle": -math.pi / 2, "torque_limits": [-50, 50]},
        ],
        "object": {
            "vertices": [
                [-0.18665325736297378, 0.2763000833782986],
                [-0.2355220607041395, 0.0],
                [0.11269263688838925, 0.0],
                [0.17500678607058906, 0.07854049000830643],
                [0.134475895108135, 0.2997668322607216],
            ]
        },
    }
    sim = Simulator(scene)
    state, h = sim.reset(), sim.scene.initial_hand.copy()
    for k in range(13):
        h = h.copy()
        if k < 10:
            h[3] += 0.08
            h[4] -= 0.05
        else:
            h[1] += 0.05
        state = sim.move_hand(state, palm=h[:3], fingers=h[3:])
    return sim, state


@pytest.mark.xfail(
    strict=True,
    reason="from a jam on a fold, whether the first plan of a palm move finds a motion is "
    "decided by rounding in the motion LP of the dependent contacts: raised by 1e-6 or "
    "1e-3 palm widths the hand jams where it is, by 1e-5, 1e-4, 1e-2 or 0.05 the object "
    "falls and the palm rises (docs/reliability.md)",
)
def test_a_move_from_a_jam_at_a_fold_does_not_depend_on_its_length() -> None:
    sim, state = _jammed_at_a_fold()
    assert state.jammed
    raised = [
        sim.move_hand(state, palm=state.hand[:3] + np.array([0.0, dy, 0.0])).jammed
        for dy in (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.05)
    ]
    assert len(set(raised)) == 1
