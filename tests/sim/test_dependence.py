"""Contacts dependent to tolerance (``grasp_env.sim.dependence``), against closed forms.

A rectangle hangs between two fingers whose palmar edges converge downward at a half-angle
``alpha``, its lower corners on the edges. A wedge holds it with a force of
``W / (2 sin alpha)`` on each corner, however large that is, as long as the tolerance
resolves the angle (over the object's size, the faces part by more than ``contact_tol``);
faces parallel to tolerance hold nothing, and the object slides down between them. Every
state is checked by the independent checker, which applies the same definition with its
own code (numpy's SVD, scipy's NNLS).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import grasp_env
from grasp_env import Simulator, testing
from grasp_env.sim.dependence import free_rows

PALM_Y = 0.8
#: Height of the rectangle's lower corners, and its height.
CORNER_Y, HEIGHT = 0.4, 0.2


def wedge_scene(alpha: float) -> tuple[grasp_env.Scene, np.ndarray, np.ndarray]:
    """Fingers of length 0.7 hanging from a unit palm at ``(0, PALM_Y)``, turned inward by
    ``alpha``; a rectangle whose lower corners lie on their palmar edges at ``CORNER_Y``.
    Finger 1's palmar edge is ``x = -1/2 + (PALM_Y - y) tan alpha``, finger 2's its mirror
    image. Returns the scene, the rectangle's pose and the hand."""
    half = 0.5 - (PALM_Y - CORNER_Y) * math.tan(alpha)
    q = (-math.pi / 2 + alpha, -math.pi / 2 - alpha)
    vertices = [
        [-half, CORNER_Y],
        [half, CORNER_Y],
        [half, CORNER_Y + HEIGHT],
        [-half, CORNER_Y + HEIGHT],
    ]
    scene = grasp_env.load_scene(
        {
            "name": "wedge",
            "palm": {"width": 1.0, "thickness": 0.15, "pose": [0.0, PALM_Y, 0.0]},
            "fingers": [
                {"length": 0.7, "thickness": 0.05, "angle": a, "limits": [-math.pi, 0.0]} for a in q
            ],
            "object": {"vertices": vertices, "mass": 1.0},
        }
    )
    return scene, scene.object.start_pose.copy(), scene.initial_hand.copy()


def assert_valid(state: grasp_env.State) -> None:
    tol = 1e-9 * state.scene.palm.width
    chk = testing.check_state(state.scene, state.object_pose, state.hand, state.contacts, tol)
    assert not chk.violations, "; ".join(chk.violations)


@pytest.mark.parametrize("alpha", [1e-3, 1e-5, 1e-7])
def test_a_wedge_holds_with_the_forces_of_its_angle(alpha: float) -> None:
    """Resolved by the tolerance (the faces part by ``alpha`` x size, at least 5e-8 palm
    widths here, against 1e-9), the wedge holds the rectangle where it is, with ``W / (2 sin
    alpha)`` on each lower corner: 500 to 5 million weights, no bound on them."""
    scene, pose, hand = wedge_scene(alpha)
    state = Simulator(scene).settle(pose, hand)
    np.testing.assert_allclose(state.object_pose, pose, rtol=0, atol=1e-9)
    wedge = scene.object_weight / (2 * math.sin(alpha))
    assert sorted(c.body for c in state.contacts) == ["finger1", "finger2"]
    for c in state.contacts:
        assert c.force == pytest.approx(wedge, rel=1e-6)
    assert_valid(state)


@pytest.mark.parametrize("alpha", [0.0, 1e-12, 1e-10])
def test_faces_parallel_to_tolerance_let_the_object_slide(alpha: float) -> None:
    """Below the tolerance's resolution (the faces part by less than 1e-10 palm widths over
    the object's size) the faces are parallel: nothing holds the rectangle up between them
    (a force of ``W / (2 sin alpha)``, 5e9 weights and more, would be the rounding of the
    geometry). It slides down past the fingertips and comes to rest on the support, level,
    where it started in x."""
    scene, pose, hand = wedge_scene(alpha)
    state = Simulator(scene).settle(pose, hand)
    assert state.events[0].kind == "fall_start"
    np.testing.assert_allclose(state.object_pose, [0.0, HEIGHT / 2, 0.0], rtol=0, atol=1e-8)
    weight = scene.object_weight
    assert {c.body for c in state.contacts if c.force > 1e-9 * weight} == {"support"}
    assert_valid(state)


def test_the_checker_rejects_a_state_held_by_faces_parallel_to_tolerance() -> None:
    """The checker flags, as an admissible descent, a state that only forces of 1e9
    weights on faces parallel to tolerance would hold (what the simulator reported as a jam
    before it took such faces as free): the same rectangle with ``alpha = 1e-12``, held
    where it hangs by the forces a wedge of that angle would need."""
    scene, pose, hand = wedge_scene(1e-12)
    state = Simulator(scene).settle(pose, hand)
    weight = scene.object_weight
    force = weight / (2 * math.sin(1e-12))
    world = scene.object.vertices_W0
    contacts = [
        {"body": "finger1", "kind": "edge", "point": world[0], "force": force,
         "normal": np.array([math.cos(1e-12), math.sin(1e-12)])},
        {"body": "finger2", "kind": "edge", "point": world[1], "force": force,
         "normal": np.array([-math.cos(1e-12), math.sin(1e-12)])},
    ]  # fmt: skip
    chk = testing.check_state(scene, pose, hand, contacts, 1e-9)
    assert any("admissible descent" in v for v in chk.violations), chk.violations
    assert chk.descent < -0.99  # gravity is not balanced at all along the faces
    assert state.object_pose[1] < pose[1]  # the simulator lets it fall


def test_free_rows_agree_with_the_checker() -> None:
    """The compiled projection and the checker's (numpy's SVD) give the same rows: for
    random rows made dependent to within a factor of the threshold of each other, for pairs
    and triples, with independent rows beside them."""
    rng = np.random.default_rng(7)
    model = Simulator(wedge_scene(1e-3)[0]).model
    size = model.size
    eta = model.tol / size
    for trial in range(200):
        k = 2 if trial % 2 else 3
        m = int(rng.integers(k, 6))
        normals = rng.normal(size=(m, 2))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        V = np.column_stack([normals, rng.uniform(-size, size, m)])  # rows [n, r x n]
        # make a pair or a triple dependent, up to a multiple of the threshold
        base = V[:2].copy() if k == 3 else V[:1].copy()
        weights = rng.normal(size=(1, base.shape[0]))
        V[k - 1] = (weights @ base).ravel()
        V[k - 1, :2] /= np.linalg.norm(V[k - 1, :2])
        V[k - 1] += rng.normal(size=3) * eta * rng.choice([1e-6, 0.3, 3.0])
        got = free_rows(model, V.copy())
        scaled = V * [1.0, 1.0, 1.0 / size]
        want = testing.free_rows(scaled, eta) * [1.0, 1.0, size]
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12, err_msg=f"trial {trial}")


PINCH = {
    "palm": {"width": 1.0, "thickness": 0.15, "pose": [0.0, 0.71, 0.0]},
    "fingers": [
        {"length": 0.6, "thickness": 0.05, "angle": -1.5707963267948966},
        {"length": 0.7, "thickness": 0.05, "angle": -1.5707963267948966},
    ],
    "object": {
        "vertices": [
            [-0.5, 0.0],
            [-0.16746285806256117, 0.0],
            [-0.16746285806256117, 0.4647331016059901],
            [-0.5, 0.4647331016059901],
        ],
        "density": 46.75459204038979,
    },
}


def test_a_pinch_on_faces_parallel_to_tolerance_is_a_jam_held_by_the_support() -> None:
    """A rectangle on the support, pinched between finger 1's tip and finger 2's link, whose
    face is flush with the rectangle's to 6e-10 rad. The hand's move squeezes the faces
    together: the object cannot give way (along the faces it is free, but the support holds
    it up), so the hand jams at once, the object at rest on the support. Before faces
    parallel to tolerance were free, the squeeze shot the object up along the faces as out of
    a wedge of that angle and reported a jam held by forces of 1e9 weights that the
    independent check rejects (an admissible descent along the faces)."""
    sim = grasp_env.Simulator(PINCH)
    start = sim.settle(
        np.array([0.22352792835394444, 0.2827383749232938, -0.47634009677263583]),
        np.array([0.17574841645426637, 0.8351346405512452, -0.08405719265504985,
                  -0.5607917030769372, -1.9630792327492135]),
    )  # fmt: skip
    a = [0.7140324711799622, 0.17313998937606812, 0.5143823027610779, -0.8059538006782532,
         -0.05096952244639397]  # fmt: skip
    h = start.hand
    end = sim.move_hand(
        start,
        palm=(h[0] + 0.02 * a[2], h[1] + 0.02 * a[3], h[2] + 0.05 * a[4]),
        fingers=(h[3] + 0.05 * a[0], h[4] - 0.05 * a[1]),
    )
    assert end.jammed
    assert "support" in {c.body for c in end.contacts}
    np.testing.assert_allclose(end.object_pose, start.object_pose, rtol=0, atol=1e-9)
    assert max(c.force for c in end.contacts) < 100 * sim.scene.object_weight
    assert_valid(end)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("density", 1e9),
        ("density", 1e-9),
        ("width", 1e-6),
        ("width", 1e6),
        ("gravity", 1e9),
        ("gravity", 1e-9),
    ],
)
def test_the_checker_holds_at_the_corners_of_the_ranges(field: str, value: float) -> None:
    """A pentagon resting on the support, at the ends of the accepted ranges of density,
    gravity and palm width (every length scaled): the checker accepts the resting state and
    its settled closing move, and its tests do not fail to solve (they work in units of the
    weight and the palm width)."""
    k = value if field == "width" else 1.0
    vertices = [[-0.1184, 0.0], [0.1454, 0.0], [0.1206, 0.0331], [0.0625, 0.0522],
                [-0.0881, 0.0743]]  # fmt: skip
    d = {
        "palm": {"width": k, "thickness": 0.15 * k, "pose": [0.0, 0.71 * k, 0.0]},
        "fingers": [
            {"length": 0.6 * k, "thickness": 0.05 * k, "angle": -math.pi / 2},
            {"length": 0.7 * k, "thickness": 0.05 * k, "angle": -math.pi / 2},
        ],
        "object": {
            "vertices": [[x * k, y * k] for x, y in vertices],
            "density": value if field == "density" else 1.0,
        },
    }
    if field == "gravity":
        d["gravity"] = value
    sim = Simulator(d)
    state = sim.reset()
    assert_valid(state)
    for _ in range(6):
        q1, q2 = state.finger_angles
        state = sim.move_hand(state, fingers=(q1 + 0.15, q2 - 0.15))
        assert_valid(state)
