"""Descents blocked at second order (``grasp_env.sim.curvature``, and the checker's own
``grasp_env.testing.wedged``), and rests that are no potential minimum, against closed forms
and the soak's failures.

Two contacts whose lines of action coincide (two fingertips on opposite faces, or two object
vertices on two parallel finger faces) leave the object free to first order to turn about
any point ``p`` of that line. Turned by ``t``, a face through a fingertip at distance ``a``
from ``p`` tilts away from it, and the fingertip cuts in: the gap is ``a (cos t - 1)``. A
vertex at distance ``a`` from ``p`` on a fixed face lifts off it: ``a (1 - cos t)``. So a
pinch between fingertips is blocked at second order (``mu . kappa = -(a + b)`` for the
self-stress ``mu = (1, 1)``), and a pinch of two vertices between faces is not
(``+(a + b)``).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

import grasp_env
from benchmarks.soak import soak_shape
from grasp_env import Simulator, testing
from grasp_env.sim.curvature import gap_hessians, unstable
from grasp_env.sim.fall import touching
from grasp_env.sim.placement import place

# A pinch along the line y = 0.3 (normal n0 = (1, 0)), turned about p = (0.1, 0.3); the
# object's centre of mass at c, its size s.
P0 = np.array([0.1, 0.3])
C0 = np.array([0.05, 0.2])
SIZE = 0.4
A, B = 0.15, 0.25  # distances of the two contacts from p along the line


def pinch(kind: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Points, normals (into the object) and kinds of the pinch: fingertips on the faces
    (``tip``: the object lies between them) or object vertices on fixed faces (``edge``)."""
    points = np.array([P0 - np.array([A, 0.0]), P0 + np.array([B, 0.0])])
    normals = np.array([[1.0, 0.0], [-1.0, 0.0]])
    return points, normals, [kind, kind]


def turn_about_p() -> np.ndarray:
    """The twist turning the object about ``p`` at unit rate, as a displacement ``(v_x, v_y,
    size omega)``: the centre of mass moves at ``omega x (c - p)``."""
    r = C0 - P0
    return np.array([-r[1], r[0], SIZE])


@pytest.mark.parametrize(("kind", "sign"), [("tip", -1.0), ("edge", 1.0)])
def test_the_gaps_curve_as_the_faces_turn(kind: str, sign: float) -> None:
    """Weighted by the self-stress ``(1, 1)``, the gaps' second derivatives along the turn
    about ``p`` are ``-(a + b)`` for fingertips and ``+(a + b)`` for vertices on faces (the
    Hessians are times the size; the straight line in the pose differs from the turn at
    second order only along the rows, which the self-stress cancels). Both the checker's
    and the simulator's Hessians."""
    points, normals, kinds = pinch(kind)
    d = turn_about_p()
    want = sign * (A + B) * SIZE
    checker = testing.gap_hessians(points, normals, kinds, C0, SIZE)
    assert sum(d @ H @ d for H in checker) == pytest.approx(want, rel=1e-12)
    codes = np.array([1 if k == "tip" else 0 for k in kinds])
    compiled = gap_hessians(points, normals, codes, C0, SIZE)
    assert sum(d @ H @ d for H in compiled) == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize(("kind", "held"), [("tip", True), ("edge", False)])
def test_a_pinch_with_a_vertex_on_the_support(kind: str, held: bool) -> None:
    """The pinch and a vertex on the support at ``(0.3, 0)``: to first order the object
    turns down about a point of the pinch line (gravity is far from the wrenches' cone).
    Between fingertips every such descent cuts into the faces: wedged. Between faces the
    vertices lift off: it falls."""
    points, normals, kinds = pinch(kind)
    points = np.vstack([points, [0.3, 0.0]])
    normals = np.vstack([normals, [0.0, 1.0]])
    kinds = [*kinds, "edge"]
    r = points - C0
    raw = np.column_stack([normals, (r[:, 0] * normals[:, 1] - r[:, 1] * normals[:, 0]) / SIZE])
    eta = 1e-9 / SIZE
    groups = testing.dependences(raw, eta)
    V = testing.free_rows(raw, eta)
    _, dist = nnls(V.T, np.array([0.0, 1.0, 0.0]))
    assert dist > 0.1  # a first-order descent
    H = testing.gap_hessians(points, normals, kinds, C0, SIZE)
    assert testing.wedged(V, groups, H, eta, 1e-7) is held


@pytest.mark.parametrize(
    ("vertices", "expected"),
    [
        ([[0.0, 0.0], [0.1, 0.1], [0.0, 0.2], [-0.1, 0.1]], True),
        ([[-0.1, 0.0], [0.1, 0.0], [0.1, 0.1], [-0.1, 0.1]], False),
    ],
    ids=["on_a_corner", "on_a_side"],
)
def test_a_rest_on_a_corner_is_a_potential_maximum(vertices: list, expected: bool) -> None:
    """A square balanced on a corner, its centre of mass ``a`` above it: turned about the
    corner by ``t`` the centre falls by ``a (1 - cos t)``, and the support's gap curves by
    ``lam . kappa = a / size = 1`` (``size = a``), far above ``2 eta``: no rest. On a side,
    the support's two contacts leave the object only sliding along it, which its potential
    does not feel: flat, a rest."""
    scene = grasp_env.load_scene(
        {
            "name": "rest",
            "palm": {"width": 1.0, "thickness": 0.15, "pose": [0.0, 0.71, 0.0]},
            "fingers": [
                {"length": 0.6, "thickness": 0.05, "angle": -np.pi / 2},
                {"length": 0.7, "thickness": 0.05, "angle": -np.pi / 2},
            ],
            "object": {"vertices": vertices, "mass": 1.0},
        }
    )
    model = Simulator(scene).model
    q = scene.object.start_pose
    world = place(model, q, scene.initial_hand)
    keys = touching(model, world, np.zeros((0, 4), dtype=np.int64))
    assert keys.shape[0] == (1 if expected else 2) and np.all(keys[:, 0] == 0)  # the support
    assert unstable(model, world, q[:2], keys) is expected


#: Soak shapes (seed 6) whose moves ended in ``sim_error`` before: pinches at a fold
#: (slivers, near-parallel quadrilaterals, near-circles), a bulged side along a finger, and
#: near-circles whose fall came back to a potential maximum (365, 368, 387, 979: a cradle
#: is a minimum, ``grasp_env.sim.curvature.unstable``), a fingertip sliding past a vertex
#: between collinear edges (310: a contact at the end of its edge offers the fall its twins),
#: pinches whose curvature opens one of three dependent contacts (301, 785, 811, 858: the
#: fall lets each go in turn, ``grasp_env.sim.fall.fall``), and an edge along a finger's face
#: just over the flush angle (410, 943: both end contacts are kept,
#: ``grasp_env.sim.detection``).
SOAK_FAILURES = {
    37: 700, 28: 620, 100: 870, 6: 30, 77: 250, 374: 810, 365: 520, 368: 820, 387: 610,
    979: 420, 310: 700, 301: 760, 785: 520, 811: 90, 858: 800, 410: 660, 943: 420,
}  # fmt: skip


@pytest.mark.parametrize("index", sorted(SOAK_FAILURES))
def test_soak_failures_replayed(index: int) -> None:
    """The soak's steps on the shape, up to past its failures, every state checked by the
    independent checker: no simulation error, no state the checker rejects."""
    rec = soak_shape(6, index, SOAK_FAILURES[index])
    assert rec["exceptions"] == 0 and rec["sim_errors"] == 0, rec["examples"]
    assert rec["violating_steps"] == 0, rec["examples"]
