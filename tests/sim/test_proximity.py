"""Fingertip positions and hand-object distances (:mod:`grasp_env.sim.proximity`) against
independent geometry: every edge pair's segment distance and the separating-axis depth of
:mod:`grasp_env.testing`, on random hands about random objects."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grasp_env
from grasp_env import testing
from grasp_env.envs.shapes import random_shape_scene
from grasp_env.sim import proximity


def polygon_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Least distance of two convex polygons, zero where they touch or overlap."""
    if testing.sat_depth(a, b) >= 0.0:
        return 0.0
    to_b = min(testing.boundary_distance(p, b) for p in a)
    to_a = min(testing.boundary_distance(p, a) for p in b)
    return min(to_a, to_b)


def point_distance(p: np.ndarray, poly: np.ndarray) -> float:
    inside = all(testing.cross(e1 - e0, p - e0) >= 0.0 for e0, e1, _ in testing.edges(poly))
    return 0.0 if inside else testing.boundary_distance(p, poly)


def reference(scene, q: np.ndarray, h: np.ndarray) -> np.ndarray:
    obj = testing.object_polygon_W(scene, q)
    hand = testing.hand_polygons_W(scene, h)
    tips = [hand["finger1"][1], hand["finger2"][1]]  # J + L u: the palmar edges' far ends
    c, s = math.cos(h[2]), math.sin(h[2])
    in_palm = [np.array([[c, s], [-s, c]]) @ (t - h[:2]) for t in tips]
    distances = [polygon_distance(hand[b], obj) for b in ("palm", "finger1", "finger2")]
    distances += [point_distance(t, obj) for t in tips]
    return np.concatenate([*in_palm, distances])


@pytest.mark.parametrize("seed", range(6))
def test_hand_features_match_independent_geometry(seed: int) -> None:
    rng = np.random.default_rng(seed)
    scene = random_shape_scene(rng, grasp_env.load_scene("fig13"))
    model = grasp_env.Simulator(scene).model
    q0, h0 = scene.object.start_pose, scene.initial_hand
    touching = 0
    for _ in range(40):
        q = q0 + rng.uniform(-0.05, 0.05, 3) * [1.0, 1.0, 3.0]
        h = h0 + rng.uniform(-1.0, 1.0, 5) * [0.3, 0.4, 0.5, 1.0, 1.0]
        got = proximity.hand_features(
            model.points, model.body, model.n_object, model.n_vertices, model.half, q, h
        )
        want = reference(scene, q, h)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
        touching += int((want[proximity.DISTANCES] == 0.0).any())
    assert 0 < touching < 40  # both sides of zero distance met


def test_touching_bodies_are_at_zero_distance() -> None:
    """At the pre-liftoff placement the fingers touch the object: distance zero."""
    sim = grasp_env.Simulator("fig13")
    state = grasp_env.planning.centred_placement(sim)
    m = sim.model
    got = proximity.hand_features(
        m.points,
        m.body,
        m.n_object,
        m.n_vertices,
        m.half,
        state.object_pose.copy(),
        state.hand.copy(),
    )
    touching = {c.body for c in state.contacts}
    for k, body in enumerate(("palm", "finger1", "finger2")):
        if body in touching:
            assert got[proximity.DISTANCES][k] < 1e-8
        else:
            assert got[proximity.DISTANCES][k] > 1e-6
