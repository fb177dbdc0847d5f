"""Contact evaluation and detection of :mod:`grasp_env.mechanics.contacts` on its own, on
set-ups whose contacts are known by construction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.scene_loading import load_scene
from grasp_env.core.state import EDGE, TIP
from grasp_env.mechanics import contacts as ct


def test_resting_object_has_its_bottom_edge_on_the_support() -> None:
    """The scene placement puts an edge of the object on y = 0: detection finds its two ends
    on the support (edge kind, support edge 0) with zero gap, normal +y, and nothing else
    (the hand starts clear of the object)."""
    for name in ("fig13", "square", "hexagon"):
        scene = load_scene(name)
        pl = ct.Placement(scene, scene.object.start_pose.copy(), scene.initial_hand)
        tol = 1e-9 * scene.palm.width
        keys = ct.detect(pl, tol)
        bottom = np.flatnonzero(np.abs(scene.object.vertices_W0[:, 1]) <= tol)
        assert sorted(keys) == [(geo.SUPPORT, EDGE, int(k), 0) for k in bottom]
        for key in keys:
            p, n, gap, _, _ = pl.evaluate(key)
            np.testing.assert_allclose(p, scene.object.vertices_W0[key[2]], atol=1e-12)
            np.testing.assert_array_equal(n, [0.0, 1.0])
            assert abs(gap) <= tol


def test_fingertip_on_an_object_edge_at_a_set_gap() -> None:
    """Finger 2's tip put a set distance from the middle of an object edge: a tip contact
    on that edge with that gap (positive apart, negative inside), the edge's inward normal,
    and an edge parameter of one half; detected only within the tolerance."""
    scene = load_scene("square")
    v = scene.object.vertices_W0
    k = int(np.argmax(geo.edge_normals(v)[:, 0]))  # the square's right-hand side
    mid = (v[k] + v[(k + 1) % len(v)]) / 2
    normal_out = geo.edge_normals(v)[k]
    tol = 1e-9 * scene.palm.width
    # finger 2 points down and to the left onto the edge; finger 1 points away, to the left
    h0 = np.array([0.0, 0.0, 0.0, math.pi, -0.75 * math.pi])
    for gap in (3e-3, 0.5 * tol, -0.5 * tol):
        target = mid + gap * normal_out
        h = h0.copy()
        h[:2] += target - kin.fingertips_W(scene, h0)[1]  # the palm puts the tip there
        pl = ct.Placement(scene, scene.object.start_pose.copy(), h)
        key = (geo.FINGER2, TIP, k, geo.fingertip_index(2))
        p, n, g, t, length = pl.evaluate(key)
        np.testing.assert_allclose(p, target, atol=1e-12)
        np.testing.assert_allclose(n, -normal_out, atol=1e-12)
        assert g == pytest.approx(gap, abs=1e-12)
        assert t == pytest.approx(0.5, abs=1e-9)
        assert length == pytest.approx(np.linalg.norm(v[(k + 1) % len(v)] - v[k]))
        assert (key in ct.detect(pl, tol)) == (abs(gap) <= tol)
