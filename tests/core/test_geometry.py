"""The lowest layer on its own: :mod:`grasp_env.core.geometry` against closed forms and
brute force, :mod:`grasp_env.core.kinematics` against the independent polygons of
:mod:`grasp_env.testing` and finite differences."""

from __future__ import annotations

import cmath
import functools
import math

import numpy as np
import pytest

from grasp_env import testing
from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.scene_loading import load_scene


def regular_polygon(n: int, radius: float, phase: float = 0.3) -> np.ndarray:
    a = phase + 2 * math.pi * np.arange(n) / n
    return radius * np.stack([np.cos(a), np.sin(a)], axis=1)


def random_convex(rng: np.random.Generator, n: int) -> np.ndarray:
    """CCW convex polygon: sorted angles on an ellipse, turned and shifted."""
    a = np.sort(rng.uniform(0, 2 * math.pi, n))
    v = np.stack([rng.uniform(0.5, 2) * np.cos(a), rng.uniform(0.5, 2) * np.sin(a)], axis=1)
    return geo.rotate(v, rng.uniform(-3, 3)) + rng.uniform(-2, 2, 2)


# ---------------------------------------------------------------------- geometry
@pytest.mark.parametrize("n", [3, 4, 5, 8, 13])
def test_regular_polygon_area_centroid_inertia(n: int) -> None:
    """Closed forms of a regular n-gon of circumradius R: area n R^2 sin(2 pi/n) / 2, centroid
    at its centre, inertia m R^2 (1 + 2 cos^2(pi/n)) / 6."""
    R, m = 1.7, 2.5
    centre = np.array([0.4, -1.1])
    v = regular_polygon(n, R) + centre
    assert geo.polygon_area(v) == pytest.approx(n * R * R * math.sin(2 * math.pi / n) / 2)
    np.testing.assert_allclose(geo.polygon_centroid(v), centre, atol=1e-12)
    expected = m * R * R * (1 + 2 * math.cos(math.pi / n) ** 2) / 6
    assert geo.polygon_inertia(v - centre, m) == pytest.approx(expected, rel=1e-12)
    assert geo.polygon_area(v[::-1]) == pytest.approx(-geo.polygon_area(v))  # signed


def test_rectangle_and_triangle_closed_forms() -> None:
    a, b, m = 3.0, 0.5, 4.0
    rect = np.array([[-a / 2, -b / 2], [a / 2, -b / 2], [a / 2, b / 2], [-a / 2, b / 2]])
    assert geo.polygon_inertia(rect, m) == pytest.approx(m * (a * a + b * b) / 12, rel=1e-12)
    tri = np.array([[0.0, 0.0], [a, 0.0], [0.0, b]])
    np.testing.assert_allclose(geo.polygon_centroid(tri), [a / 3, b / 3], atol=1e-12)
    # right triangle about its centroid: m (a^2 + b^2) / 18
    c = geo.polygon_centroid(tri)
    assert geo.polygon_inertia(tri - c, m) == pytest.approx(m * (a * a + b * b) / 18, rel=1e-12)


def test_rotate_and_transform_match_complex_multiplication() -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        p, th, pose = rng.normal(size=(6, 2)), rng.uniform(-7, 7), rng.normal(size=3)
        z = [complex(*row) * cmath.exp(1j * th) for row in p]
        np.testing.assert_allclose(geo.rotate(p, th), [[w.real, w.imag] for w in z], atol=1e-12)
        w = [complex(*row) * cmath.exp(1j * pose[2]) + complex(*pose[:2]) for row in p]
        np.testing.assert_allclose(
            geo.transform(pose, p), [[x.real, x.imag] for x in w], atol=1e-12
        )


def test_edge_normals_are_outward_unit_normals() -> None:
    rng = np.random.default_rng(1)
    for n in range(3, 12):
        v = random_convex(rng, n)
        normals = geo.edge_normals(v)
        d = np.roll(v, -1, axis=0) - v
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose((normals * d).sum(axis=1), 0.0, atol=1e-12)
        centroid = v.mean(axis=0)  # inside a convex polygon
        assert np.all(((centroid - v) * normals).sum(axis=1) < 0)


def test_convexity_and_winding_checks() -> None:
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert geo.is_convex_ccw(square) and geo.turns_once(square)
    assert not geo.is_convex_ccw(square[::-1])  # clockwise
    dart = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 0.3], [1.0, 2.0]])
    assert not geo.is_convex_ccw(dart)
    collinear = np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert not geo.is_convex_ccw(collinear)
    star = regular_polygon(5, 1.0)[[0, 2, 4, 1, 3]]  # every turn to the left, winds twice
    assert not geo.turns_once(star)


def test_penetration_depth_matches_an_independent_separating_axis_test() -> None:
    """Known overlaps of axis-aligned squares; for random pairs, the same sign as the
    separating-axis test of :mod:`grasp_env.testing` (its own code), and the same depth near
    contact, where the simulator measures it (one polygon slid along a random direction to
    just past the first touch, found by bisection on the independent test)."""
    unit = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert geo.penetration_depth(unit, unit + np.array([0.75, 0.2])) == pytest.approx(0.25)
    assert geo.penetration_depth(unit, unit + np.array([1.5, 0.0])) == pytest.approx(-0.5)
    rng = np.random.default_rng(2)
    for _ in range(200):
        a, b = random_convex(rng, rng.integers(3, 9)), random_convex(rng, rng.integers(3, 9))
        assert np.sign(geo.penetration_depth(a, b)) == np.sign(testing.sat_depth(a, b))
        # slide b from far away toward a's centroid until it touches
        d = a.mean(axis=0) - b.mean(axis=0)
        far, near = -10.0, 1.0  # apart at b - 10 d... and overlapping at b + d
        for _ in range(100):
            mid = 0.5 * (far + near)
            far, near = (mid, near) if testing.sat_depth(a, b + mid * d) < 0 else (far, mid)
        for depth_step in (1e-12, 1e-9, 1e-6):
            moved = b + (near + depth_step / np.linalg.norm(d)) * d
            expected = testing.sat_depth(a, moved)
            assert geo.penetration_depth(a, moved) == pytest.approx(expected, abs=1e-12)


def test_segment_distance_against_dense_sampling() -> None:
    """Zero where the segments cross; otherwise the least distance, which dense sampling of
    both segments approaches from above."""
    assert geo.segment_distance(*np.array([[0, 0], [2, 2], [0, 2], [2, 0]], float)) == 0.0
    parallel = np.array([[0, 0], [1, 0], [0.5, 0.3], [3, 0.3]], float)
    assert geo.segment_distance(*parallel) == pytest.approx(0.3)
    rng = np.random.default_rng(3)
    s = np.linspace(0, 1, 801)[:, None]
    for _ in range(100):
        a0, a1, b0, b1 = rng.normal(size=(4, 2))
        pa, pb = a0 + s * (a1 - a0), b0 + s * (b1 - b0)
        sampled = np.linalg.norm(pa[:, None] - pb[None], axis=-1).min()
        d = geo.segment_distance(a0, a1, b0, b1)
        assert d <= sampled + 1e-12
        assert sampled - d <= 2e-3 * max(np.linalg.norm(a1 - a0), np.linalg.norm(b1 - b0))


# ---------------------------------------------------------------------- kinematics
def _same_vertices(a: np.ndarray, b: np.ndarray) -> None:
    """The same polygon vertices, in any order."""
    for p in a:
        assert np.min(np.linalg.norm(b - p, axis=1)) < 1e-12, (p, b)
    assert len(a) == len(b)


@pytest.mark.parametrize("name", ["fig13", "square", "triangle", "tall_rectangle"])
def test_hand_polygons_match_the_independent_construction(name: str) -> None:
    scene = load_scene(name)
    rng = np.random.default_rng(4)
    for _ in range(30):
        h = scene.initial_hand + rng.uniform(-1, 1, 5) * [0.3, 0.3, 0.6, 1.0, 1.0]
        ours = kin.hand_polygons_W(scene, h)
        theirs = testing.hand_polygons_W(scene, h)
        for poly, body in zip(ours, ("palm", "finger1", "finger2"), strict=True):
            _same_vertices(poly, theirs[body])
            assert geo.polygon_area(poly) > 0  # counter-clockwise
        tips = kin.fingertips_W(scene, h)
        for i, tip in enumerate(tips):
            finger = theirs[f"finger{i + 1}"]
            joint = finger[0]  # the independent construction lists the joint first
            assert np.linalg.norm(tip - joint) == pytest.approx(scene.fingers[i].length)
            assert np.min(np.linalg.norm(finger - tip, axis=1)) < 1e-12


def material_point(scene, h: np.ndarray, body: int, local: np.ndarray) -> np.ndarray:
    """World position of the point at ``local`` in hand body ``body``'s frame."""
    return geo.transform(kin.body_poses_W(scene, h)[body - 1], local[None])[0]


def test_point_velocity_is_the_derivative_of_the_material_point() -> None:
    """A material point of each hand body, carried along the hand's path, moves at
    :func:`kinematics.point_velocity_W` (central differences)."""
    scene = load_scene("fig13")
    rng = np.random.default_rng(5)
    eps = 1e-6
    for _ in range(20):
        h, dh = scene.initial_hand + rng.normal(size=5) * 0.2, rng.normal(size=5)
        poses = kin.body_poses_W(scene, h)
        for body in (geo.PALM, geo.FINGER1, geo.FINGER2):
            p = poses[body - 1, :2] + rng.normal(size=2) * 0.1
            local = geo.rotate(p - poses[body - 1, :2], -poses[body - 1, 2])
            ahead, behind = (material_point(scene, h + t * dh, body, local) for t in (eps, -eps))
            fd = (ahead - behind) / (2 * eps)
            np.testing.assert_allclose(
                kin.point_velocity_W(scene, h, dh, body, p), fd, rtol=1e-6, atol=1e-8
            )
        assert not kin.point_velocity_W(scene, h, dh, geo.SUPPORT, p).any()


def _turned_depth(a: np.ndarray, b: np.ndarray, sign: float, t: float) -> float:
    """Independent overlap depth of ``a`` turned by ``sign * t`` about the origin and ``b``."""
    return testing.sat_depth(geo.rotate(a, sign * t), b)


@pytest.mark.parametrize("ccw", [True, False])
def test_turn_to_contact_matches_a_scan_of_the_overlap(ccw: bool) -> None:
    # Independent check: scan the turn in fine steps with the separating-axis test of
    # grasp_env.testing, bisect the first step that overlaps, and compare; a turn that never
    # touches scans clean.
    rng = np.random.default_rng(11)
    sign = 1.0 if ccw else -1.0
    checked = 0
    for _ in range(40):
        a = random_convex(rng, int(rng.integers(3, 7))) * 0.3 + [2.5, 0.0]
        b = random_convex(rng, int(rng.integers(3, 7))) * 0.8
        centre = np.zeros(2)
        if testing.sat_depth(a, b) > 0:
            continue
        grid = np.linspace(0.0, 2.0 * math.pi, 1201)
        depth = functools.partial(_turned_depth, a, b, sign)
        first = next((t for t in grid if depth(t) > 0), None)  # the scan stops there
        turn = geo.turn_to_contact(a, centre, b, ccw=ccw)
        if first is None:
            assert turn == math.inf or depth(turn) > -1e-9  # at most a graze the scan missed
            continue
        lo, hi = first - grid[1], first
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if depth(mid) > 0 else (mid, hi)
        assert turn == pytest.approx(hi, abs=1e-9)
        checked += 1
    assert checked >= 12
