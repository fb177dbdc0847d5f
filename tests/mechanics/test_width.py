"""Tests of grasp_env.mechanics.width against a direction sweep and closed-form widths
(section 3.2)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from polygon_strategies import random_hulls
from scipy.optimize import minimize_scalar

from grasp_env.core import geometry as geo
from grasp_env.core.scene_loading import scene_from_dict
from grasp_env.errors import SceneError
from grasp_env.mechanics.width import object_width, width_direction


def extent(v: np.ndarray, theta: np.ndarray | float) -> np.ndarray:
    """Length of the projection of the vertices on the direction(s) theta."""
    u = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    proj = v @ u.T
    return proj.max(axis=0) - proj.min(axis=0)


def swept_width(v: np.ndarray, n_dir: int = 20000) -> tuple[float, float]:
    """Minimum extent over a uniform sweep of directions, then refined near the best ones.

    Returns (refined minimum, raw sweep minimum). The refinement runs a bounded scalar
    minimisation on the grid cell around each of the 5 best sweep directions, so it finds
    the kink where the minimum sits to ~1e-12 rad.
    """
    theta = np.linspace(0.0, math.pi, n_dir, endpoint=False)
    w = extent(v, theta)
    step = math.pi / n_dir
    best = float(w.min())
    refined = best
    for j in np.argsort(w)[:5]:
        res = minimize_scalar(
            lambda t: float(extent(v, np.array([t]))[0]),
            bounds=(theta[j] - step, theta[j] + step),
            method="bounded",
            options={"xatol": 1e-13},
        )
        refined = min(refined, float(res.fun))
    return refined, best


def regular_polygon(n: int, side: float) -> np.ndarray:
    r = side / (2 * math.sin(math.pi / n))
    a = 2 * math.pi * np.arange(n) / n
    return r * np.stack([np.cos(a), np.sin(a)], axis=1)


ANALYTIC = {
    "square": (regular_polygon(4, 1.3), 1.3),
    "equilateral-triangle": (regular_polygon(3, 2.0), 2.0 * math.sqrt(3) / 2),
    "regular-hexagon": (regular_polygon(6, 0.7), 0.7 * math.sqrt(3)),
    # Odd n: a vertex faces an edge; width = circumradius (1 + cos(pi/5)).
    "regular-pentagon": (
        regular_polygon(5, 1.0),
        (1 + math.cos(math.pi / 5)) / (2 * math.sin(math.pi / 5)),
    ),
    "rectangle": (np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 0.4], [0.0, 0.4]]), 0.4),
    "right-triangle": (np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]]), 12.0 / 5.0),
}


@pytest.mark.parametrize("name", list(ANALYTIC))
def test_analytic_widths(name: str) -> None:
    v, expected = ANALYTIC[name]
    assert object_width(v) == pytest.approx(expected, rel=1e-12)
    u = width_direction(v)
    assert np.linalg.norm(u) == pytest.approx(1.0, rel=1e-14)
    proj = v @ u
    assert proj.max() - proj.min() == pytest.approx(expected, rel=1e-12)


SCENE = {
    "palm": {"width": 1.0, "pose": [0.0, 0.85, 0.0]},
    "fingers": [{"length": 0.6, "angle": -1.5708}, {"length": 0.7, "angle": -1.5708}],
    "object": {"vertices": [[-0.2, 0.0], [0.2, 0.0], [0.2, 0.3], [-0.2, 0.3]]},
}


def test_scene_input() -> None:
    scene = scene_from_dict(SCENE)
    assert object_width(scene) == pytest.approx(0.3, rel=1e-12)
    assert object_width(scene) == object_width(scene.object.vertices_W0)


#: A pentagram: every turn is to the left, but it winds twice (the scene loader refuses it).
PENTAGRAM = [[math.cos(k * 4 * math.pi / 5), math.sin(k * 4 * math.pi / 5)] for k in range(5)]


@pytest.mark.parametrize(
    ("bad", "pattern"),
    [
        ([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]], r"clockwise"),
        ([[0.0, 0.0], [1.0, 0.0]], r"at least 3"),
        ([[0.0, 0.0, 0.0]] * 3, r"\[0\] must be a list of 2 numbers"),
        (PENTAGRAM, r"strictly convex"),
        ([[0.0, 0.0], [1.0, 0.0], ["1", "1"], [0.0, 1.0]], r"\[2\]\[0\] must be a number, got '1'"),
        (
            [[0.0, 0.0], [True, 0.0], [1.0, 1.0], [0.0, 1.0]],
            r"\[1\]\[0\] must be a number, got True",
        ),
        ("fig13", r"at least 3 \[x, y\] points, got 'fig13'"),
        # squares of such coordinates leave the doubles' range (overflow, underflow)
        ([[0.0, 0.0], [1e308, 0.0], [0.0, 1e308]], r"\[1\]\[0\] must be within 1e\+150 .*1e\+308"),
        ([[0.0, 0.0], [1e-300, 0.0], [0.0, 1e-300]], r"span 1e-300, less than 1e-150"),
    ],
    ids=["clockwise", "two-vertices", "3d", "pentagram", "str", "bool", "name", "huge", "tiny"],
)
def test_bad_input_raises(bad, pattern: str) -> None:
    # The scene loader's checks of object.vertices, naming the argument.
    for f in (object_width, width_direction):
        with pytest.raises(SceneError, match=rf"scene_or_vertices.*{pattern}"):
            f(bad)
    with pytest.raises(SceneError):
        scene_from_dict({**SCENE, "object": {"vertices": bad}})


@pytest.mark.parametrize("k", [1e-140, 1e140])
def test_far_scales_within_the_range_give_the_scaled_answer(k: float) -> None:
    v = np.array([[0.0, 0.0], [2.0, 0.0], [0.5, 1.0]])  # width: the height, 1
    assert object_width(k * v) == pytest.approx(k, rel=1e-12)
    np.testing.assert_allclose(width_direction(k * v), width_direction(v), atol=1e-12)


@st.composite
def convex_polygons(draw) -> np.ndarray:
    v = draw(random_hulls(20, (0.05, 1.0), lambda rng, n, a: rng.normal(size=(n, 2)) * [1.0, a]))
    assume(len(v) >= 3 and geo.is_convex_ccw(v, tol=1e-9))
    return v


@settings(max_examples=80, deadline=None)
@given(v=convex_polygons())
def test_width_matches_direction_sweep(v: np.ndarray) -> None:
    w = object_width(v)
    refined, raw = swept_width(v)
    diam = float(np.max(np.linalg.norm(v[:, None] - v[None], axis=-1)))
    # The refined sweep's own error scales with the diameter (slivers: width << diameter).
    assert w == pytest.approx(refined, rel=1e-6, abs=1e-8 * diam)
    # No direction is narrower than the width; the raw sweep is within one grid step.
    assert w <= raw * (1 + 1e-12)
    assert raw - w <= diam * math.pi / 20000
    u = width_direction(v)
    proj = v @ u
    assert proj.max() - proj.min() == pytest.approx(w, rel=1e-12)


@settings(max_examples=50, deadline=None)
@given(
    v=convex_polygons(),
    theta=st.floats(-math.pi, math.pi),
    shift=st.tuples(st.floats(-10, 10), st.floats(-10, 10)),
    scale=st.floats(0.01, 100.0),
)
def test_width_is_invariant_under_rigid_motion_and_scales(v, theta, shift, scale) -> None:
    moved = scale * (v @ geo.rot(theta).T) + np.array(shift)
    assert object_width(moved) == pytest.approx(scale * object_width(v), rel=1e-9)
