"""Tests of grasp_env.mechanics.tippability against statics computed independently of the ray
construction.

The oracle: for a finger contact (p, n) the object is loaded by gravity, the finger force
c n, the two vertical support forces c_L, c_R at the ends of the supporting edge, and the
holding fingertip of Fig. 4 pushing horizontally (force b (-1, 0) at the right support
contact for the right region, b (1, 0) at the left one for the left region). For every c the
three equilibrium equations fix (c_L, c_R, b); the contact is right-tippable when a finite
c > 0 drives c_L to zero while c_R and b are still >= 0 (and mirror for the left region).
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from polygon_strategies import random_hulls
from scipy.optimize import linprog

from grasp_env.core import geometry as geo
from grasp_env.core.scene_loading import scene_from_dict
from grasp_env.errors import SceneError
from grasp_env.mechanics.tippability import MAX_TOL, support_contacts, tippability_regions

# ----------------------------------------------------------------------------------------
# Independent helpers: polygons, admissible contacts and the statics oracle
# ----------------------------------------------------------------------------------------


def _inward(v: np.ndarray) -> np.ndarray:
    """Inward unit normals of edges v_i -> v_{i+1}: the edge direction turned by +90 degrees."""
    d = np.roll(v, -1, axis=0) - v
    n = np.stack([-d[:, 1], d[:, 0]], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def rest_on_edge(v: np.ndarray, k: int, x_shift: float = 0.0) -> np.ndarray:
    """Rotate and translate a CCW polygon so that its edge k lies on y = 0 with the body above."""
    d = v[(k + 1) % len(v)] - v[k]
    a = -math.atan2(d[1], d[0])
    c, s = math.cos(a), math.sin(a)
    w = (v - v[k]) @ np.array([[c, -s], [s, c]]).T
    w[:, 1] -= w[:, 1].min()
    w[:, 1][np.abs(w[:, 1]) < 1e-14] = 0.0
    w[:, 0] += x_shift
    return w


def is_stable_on(v: np.ndarray, k: int, margin: float = 0.05) -> bool:
    """Whether the centroid projects inside edge k (with a relative margin)."""
    w = rest_on_edge(v, k)
    x_l, x_r = sorted((w[k, 0], w[(k + 1) % len(w), 0]))
    x_g = geo.polygon_centroid(w)[0]
    pad = margin * (x_r - x_l)
    return x_l + pad < x_g < x_r - pad


def well_conditioned(v: np.ndarray) -> bool:
    if len(v) < 3 or not geo.is_convex_ccw(v):
        return False
    diam = float(np.max(np.linalg.norm(v[:, None] - v[None], axis=-1)))
    d = np.roll(v, -1, axis=0) - v
    length = np.linalg.norm(d, axis=1)
    turn = np.abs(geo.cross2(d, np.roll(d, -1, axis=0))) / (length * np.roll(length, -1))
    return length.min() > 0.03 * diam and turn.min() > 0.02 and geo.polygon_area(v) > 0.02 * diam**2


@st.composite
def resting_polygons(draw) -> np.ndarray:
    """Random convex polygons (hulls of random points) resting on one of their stable edges."""
    v = draw(random_hulls(10, (0.25, 4.0), lambda rng, n, a: rng.uniform(-1, 1, (n, 2)) * [a, 1]))
    assume(well_conditioned(v))
    stable = [k for k in range(len(v)) if is_stable_on(v, k)]
    assume(stable)
    k = draw(st.sampled_from(stable))
    return rest_on_edge(v, k, x_shift=draw(st.floats(-2.0, 2.0)))


def admissible_contacts(
    v: np.ndarray, n_edge: int, n_vertex: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples of (point, normal) on the exposed perimeter.

    Edge points use the edge's inward normal; vertex points use normals spread over the cone
    between the inward normals of the two adjacent edges, including both ends of the cone.

    Returns:
        points (m, 2), normals (m, 2) and a boolean array "at a vertex" (m,).
    """
    n_in = _inward(v)
    on_support = v[:, 1] < 1e-12
    pts, nrm, at_vertex = [], [], []
    for i in range(len(v)):
        j = (i + 1) % len(v)
        if not (on_support[i] and on_support[j]):
            t = rng.uniform(1e-6, 1.0 - 1e-6, n_edge)
            pts.append(v[i] + t[:, None] * (v[j] - v[i]))
            nrm.append(np.tile(n_in[i], (n_edge, 1)))
            at_vertex.append(np.zeros(n_edge, bool))
        if not on_support[i]:
            a0 = math.atan2(n_in[i - 1, 1], n_in[i - 1, 0])
            a1 = math.atan2(n_in[i, 1], n_in[i, 0])
            cone = (a1 - a0) % (2 * math.pi)
            ang = a0 + np.concatenate([[0.0, cone], rng.uniform(0.0, cone, n_vertex)])
            pts.append(np.tile(v[i], (len(ang), 1)))
            nrm.append(np.stack([np.cos(ang), np.sin(ang)], axis=1))
            at_vertex.append(np.ones(len(ang), bool))
    return np.concatenate(pts), np.concatenate(nrm), np.concatenate(at_vertex)


def statics_oracle(
    v: np.ndarray, p: np.ndarray, n: np.ndarray, side: str
) -> tuple[np.ndarray, np.ndarray]:
    """Tippability by equilibrium, for a batch of contacts.

    Args:
        v: (k, 2) resting polygon (on an edge, centroid strictly over it), weight 1.
        p: (m, 2) contact points; n: (m, 2) unit normals into the object.
        side: "right" (unload the left support) or "left".

    Returns:
        (tippable, margin): booleans (m,), and a distance (m,) of the sample from the
        decision boundary (small values are too close to call).
    """
    on = v[:, 1] < 1e-12
    x_sup = np.sort(v[on, 0])
    assert len(x_sup) == 2
    p_L, p_R = np.array([x_sup[0], 0.0]), np.array([x_sup[1], 0.0])
    p_C, h = (p_R, np.array([-1.0, 0.0])) if side == "right" else (p_L, np.array([1.0, 0.0]))
    g = geo.polygon_centroid(v)
    weight = 1.0
    # Unknowns x = (c_L, c_R, b); rows: force x, force y, moment about the origin.
    A = np.array(
        [
            [0.0, 0.0, h[0]],
            [1.0, 1.0, h[1]],
            [p_L[0], p_R[0], float(geo.cross2(p_C, h))],
        ]
    )
    rhs_gravity = -np.array([0.0, -weight, g[0] * -weight])
    finger = np.stack([n[:, 0], n[:, 1], geo.cross2(p, n)], axis=1)  # unit finger force
    x0 = np.linalg.solve(A, rhs_gravity)  # c = 0
    x1 = np.linalg.solve(A, -finger.T).T  # d x / d c, (m, 3)
    assert x0[0] > 0 and x0[1] > 0, "the object must rest stably"
    target, other = (0, 1) if side == "right" else (1, 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        c_star = np.where(x1[:, target] < 0, -x0[target] / x1[:, target], np.inf)
    finite = np.isfinite(c_star)
    c_fin = np.where(finite, c_star, 0.0)
    other_at = x0[other] + c_fin * x1[:, other]
    b_at = x0[2] + c_fin * x1[:, 2]
    tippable = finite & (other_at >= 0) & (b_at >= 0)
    # Too close to call: the force line nearly through the support contact (d c_L / d c
    # near 0), a nearly vertical normal (b ~ 0), or the other support force ~ 0 at c*.
    margin = np.minimum.reduce(
        [np.abs(x1[:, target]), np.abs(n[:, 0]), np.where(finite, np.abs(other_at), 1.0)]
    )
    return tippable, margin


def check_against_oracle(v: np.ndarray, rng: np.random.Generator, n_edge=40, n_vertex=40):
    left, right = tippability_regions(v)
    p, n, _ = admissible_contacts(v, n_edge, n_vertex, rng)
    counts = {}
    for region in (left, right):
        expected, margin = statics_oracle(v, p, n, region.side)
        keep = margin > 1e-7
        got = np.array([region.contains(pi, ni) for pi, ni in zip(p[keep], n[keep], strict=True)])
        bad = np.flatnonzero(got != expected[keep])
        assert bad.size == 0, (
            f"{region.side}: {bad.size} disagreements, e.g. p={p[keep][bad[0]]}, "
            f"n={n[keep][bad[0]]}, oracle={expected[keep][bad[0]]}"
        )
        counts[region.side] = int(expected[keep].sum())
    return counts


# ----------------------------------------------------------------------------------------
# Analytic cases
# ----------------------------------------------------------------------------------------

RECTANGLES = [(2.0, 2.0), (1.0, 3.0), (3.0, 0.5)]


@pytest.mark.parametrize(("w", "h"), RECTANGLES, ids=[f"rect-{w}x{h}" for w, h in RECTANGLES])
def test_rectangle_side_edges_are_tippable(w: float, h: float) -> None:
    v = np.array([[-w / 2, 0.0], [w / 2, 0.0], [w / 2, h], [-w / 2, h]])
    left, right = tippability_regions(v)
    # Right region: the whole left side (edge 3, top-left -> bottom-left) and, at the top-left
    # corner, the normals between the ray to the right support contact and +x.
    assert [(s.edge, s.t_start, s.t_end) for s in right.edges] == [(3, 0.0, 1.0)]
    (vr,) = right.vertices
    assert vr.vertex == 3
    assert vr.angle_min == pytest.approx(-math.atan2(h, w), abs=1e-12)
    assert vr.angle_max == pytest.approx(0.0, abs=1e-12)
    assert (vr.min_closed, vr.max_closed) == (False, True)
    # Left region: the mirror image (edge 1, the right side; top-right corner).
    assert [(s.edge, s.t_start, s.t_end) for s in left.edges] == [(1, 0.0, 1.0)]
    (vl,) = left.vertices
    assert vl.vertex == 2
    assert vl.angle_min == pytest.approx(math.pi, abs=1e-12)
    assert vl.angle_max == pytest.approx(math.pi + math.atan2(h, w), abs=1e-12)
    # A push anywhere on the side edges, straight across, tips the object.
    for y in np.linspace(0.01, 0.99, 7) * h:
        assert right.contains([-w / 2, y], [1.0, 0.0])
        assert left.contains([w / 2, y], [-1.0, 0.0])
        assert not right.contains([w / 2, y], [-1.0, 0.0])
    # Pushing straight down on the top never tips (n_x = 0 is excluded: strict).
    assert not right.contains([0.0, h], [0.0, -1.0])
    assert not left.contains([0.0, h], [0.0, -1.0])


TRAPEZOIDS = {
    "flat-trapezoid": [[-1.0, 0.0], [1.0, 0.0], [0.8, 0.1], [-0.8, 0.1]],
    "low-triangle": [[-1.0, 0.0], [1.0, 0.0], [0.0, 0.5]],
    "unit-height-triangle": [[-1.0, 0.0], [1.0, 0.0], [0.0, 1.0]],  # boundary case, strict
}


@pytest.mark.parametrize("name", list(TRAPEZOIDS))
def test_flat_objects_are_not_tippable(name: str) -> None:
    v = np.array(TRAPEZOIDS[name])
    left, right = tippability_regions(v)
    assert left.is_empty and right.is_empty
    p, n, _ = admissible_contacts(v, 200, 200, np.random.default_rng(1))
    for side in ("left", "right"):
        tippable, margin = statics_oracle(v, p, n, side)
        assert not (tippable & (margin > 1e-9)).any()


def test_right_triangle_by_hand() -> None:
    # L = (0, 0), R = (1, 0), apex (0, 1). Edge 1 (R -> apex) has inward normal
    # (-1, -1)/sqrt2; the moment about L of a unit push at (1 - t, t) is (2t - 1)/sqrt2, so
    # the left region is t in (1/2, 1]. Edge 2 (apex -> L) has normal +x and moment -y
    # about R: the right region is all of it. At the apex the cone of normals runs from
    # -3pi/4 to 0: right needs n_x > 0 and angle > angle(R - apex) = -pi/4, left needs
    # n_x < 0 and angle in (pi/2, 3pi/2) (line above L), i.e. [-3pi/4, -pi/2).
    v = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    left, right = tippability_regions(v)
    assert [(s.edge, s.t_end) for s in left.edges] == [(1, 1.0)]
    assert left.edges[0].t_start == pytest.approx(0.5, abs=1e-15)
    np.testing.assert_allclose(left.edges[0].start_W, [0.5, 0.5], atol=1e-15)
    assert [(s.edge, s.t_start, s.t_end) for s in right.edges] == [(2, 0.0, 1.0)]
    ((lv,), (rv,)) = left.vertices, right.vertices
    assert (lv.vertex, rv.vertex) == (2, 2)
    np.testing.assert_allclose([lv.angle_min, lv.angle_max], [-3 * math.pi / 4, -math.pi / 2])
    np.testing.assert_allclose([rv.angle_min, rv.angle_max], [-math.pi / 4, 0.0], atol=1e-15)
    assert (lv.min_closed, lv.max_closed, rv.min_closed, rv.max_closed) == (
        True,
        False,
        False,
        True,
    )
    s2 = math.sqrt(0.5)
    assert left.contains([0.25, 0.75], [-s2, -s2])
    assert not left.contains([0.75, 0.25], [-s2, -s2])
    assert not left.contains([0.5, 0.5], [-s2, -s2])  # force line through L: strict
    assert left.contains([0.0, 1.0], [-s2, -s2])  # finger flush with edge 1: closed end
    assert right.contains([0.0, 1.0], [1.0, 0.0])  # finger flush with edge 2: closed end
    assert not right.contains([0.0, 1.0], [s2, -s2])  # line through R: open end


@pytest.mark.parametrize("h", [1.2, math.sqrt(3.0), 3.0], ids=["h1.2", "equilateral", "h3"])
def test_isosceles_triangle_by_hand(h: float) -> None:
    # Base (-1, 0)-(1, 0), apex (0, h). Right region on the left edge (apex -> (-1, 0)):
    # t < foot of the perpendicular from R = (h^2 - 1)/(h^2 + 1); at the apex the normals
    # from angle(R - apex) = -atan(h) to the left edge's normal, -atan(1/h).
    v = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, h]])
    left, right = tippability_regions(v)
    (e,) = right.edges
    assert e.edge == 2 and e.t_start == 0.0
    assert e.t_end == pytest.approx((h * h - 1) / (h * h + 1), rel=1e-12)
    (vx,) = right.vertices
    assert vx.angle_min == pytest.approx(-math.atan(h), rel=1e-12)
    assert vx.angle_max == pytest.approx(-math.atan(1 / h), rel=1e-12)
    # The left region is the mirror image.
    (el,) = left.edges
    assert el.edge == 1 and el.t_end == 1.0
    assert el.t_start == pytest.approx(1 - (h * h - 1) / (h * h + 1), rel=1e-12)


def test_rests_on_single_vertex() -> None:
    # A square standing on a corner: no supporting edge, both support contacts at (0, 0).
    # A push whose line passes left of the corner (clockwise moment) with n_x > 0 is in the
    # right region; the two lower edges are entirely in one region each.
    v = np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 2.0], [-1.0, 1.0]])
    support, p_L, p_R = support_contacts(v)
    assert support == (0,)
    np.testing.assert_array_equal(p_L, p_R)
    left, right = tippability_regions(v)
    assert [(s.edge, s.t_start, s.t_end) for s in left.edges] == [(0, 0.0, 1.0), (1, 0.0, 1.0)]
    assert [(s.edge, s.t_start, s.t_end) for s in right.edges] == [(2, 0.0, 1.0), (3, 0.0, 1.0)]
    by_vertex = {s.vertex: (s.angle_min, s.angle_max) for s in right.vertices}
    np.testing.assert_allclose(by_vertex[3], [-math.pi / 4, math.pi / 4])
    np.testing.assert_allclose(by_vertex[2], [-math.pi / 2, -math.pi / 4])
    assert not right.contains([0.0, 0.0], [0.0, 1.0])  # the support vertex is obstructed
    s2 = math.sqrt(0.5)
    assert right.contains([-0.5, 0.5], [s2, s2])
    assert not right.contains([-1.0, 1.0], [s2, -s2])  # line through the corner: strict


def test_vertex_interval_is_clipped_to_the_cone_and_to_positive_nx() -> None:
    # Where this module is stricter than the paper's (beta - pi/2, gamma) interval:
    # vertex 3 = (0, 1): the ray bound angle(R - v) = -pi/4 lies below the cone start
    # (edge 2's normal, atan2(-1, 2)), so the interval starts at the cone (closed);
    # vertex 2 of the second polygon overhangs beyond R: the ray bound is below -pi/2, and
    # n_x > 0 (open at -pi/2) takes over.
    _, right = tippability_regions(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 3.0], [0.0, 1.0]]))
    v3 = next(s for s in right.vertices if s.vertex == 3)
    assert v3.angle_min == pytest.approx(math.atan2(-1.0, 2.0), abs=1e-14) and v3.min_closed
    _, right = tippability_regions(np.array([[0.0, 0.0], [1.0, 0.0], [1.3, 3.0], [0.2, 2.5]]))
    v2 = next(s for s in right.vertices if s.vertex == 2)
    assert v2.angle_min == pytest.approx(-math.pi / 2, abs=1e-14) and not v2.min_closed
    assert v2.angle_max == pytest.approx(math.atan2(-1.1, 0.5), abs=1e-14)
    # The statics agree: a normal just below -pi/2 (n_x < 0) does not tip.
    n_out = np.array([[math.cos(-1.6), math.sin(-1.6)]])
    v = np.array([[0.0, 0.0], [1.0, 0.0], [1.3, 3.0], [0.2, 2.5]])
    assert not statics_oracle(v, np.array([[1.3, 3.0]]), n_out, "right")[0][0]
    assert not right.contains([1.3, 3.0], n_out[0])


# ----------------------------------------------------------------------------------------
# contains(): input handling and tolerances
# ----------------------------------------------------------------------------------------

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@pytest.mark.parametrize(
    ("point", "normal", "expected"),
    [
        pytest.param([0.0, 0.5], [1.0, 0.0], True, id="side"),
        pytest.param([0.0, 0.5], [2.0, 0.0], True, id="unnormalised"),  # normalised
        pytest.param([0.0, 0.5], [1.0, 1e-6], False, id="wrong-normal"),  # not the edge's normal
        pytest.param([-0.1, 0.5], [1.0, 0.0], False, id="off-perimeter"),
        pytest.param([0.5, 0.0], [0.0, 1.0], False, id="supporting-edge"),
        pytest.param([0.0, 0.0], [1.0, 0.0], False, id="support-vertex"),  # the left one
        # low on the side: line 1e-4 above R
        pytest.param([0.0, 1e-4], [1.0, 0.0], True, id="low-on-side"),
        # top-left corner, flush with the side
        pytest.param([0.0, 1.0], [1.0, 0.0], True, id="corner-flush"),
        pytest.param([0.0, 1.0], [math.cos(-0.5), math.sin(-0.5)], True, id="corner-inside"),
        # below the ray to R
        pytest.param([0.0, 1.0], [math.cos(-0.8), math.sin(-0.8)], False, id="corner-outside"),
        # within tol of the corner
        pytest.param([0.0, 1.0 + 1e-12], [1.0, 0.0], True, id="corner-within-tol"),
    ],
)
def test_contains_cases(point, normal, expected: bool) -> None:
    _, right = tippability_regions(SQUARE)
    assert right.contains(np.array(point), np.array(normal)) is expected


def test_contains_rejects_zero_normal() -> None:
    _, right = tippability_regions(SQUARE)
    with pytest.raises(ValueError, match="normal_W"):
        right.contains([0.0, 0.5], [0.0, 0.0])


@pytest.mark.parametrize(
    ("point", "normal", "pattern"),
    [
        pytest.param(None, None, r"point_W must be 2 real numbers, got None", id="none"),
        pytest.param(
            [1.0], [-1.0, 0.0], r"point_W must be 2 real numbers, got \[1\.0\]", id="short-point"
        ),
        pytest.param(
            [1.0, 0.5, 0.0], [-1.0, 0.0], r"point_W must be 2 real numbers", id="long-point"
        ),
        pytest.param(
            np.array([1.0, math.nan]), [-1.0, 0.0], r"point_W must be finite", id="nan-point"
        ),
        pytest.param([1.0, 0.5], ["-1", "0"], r"normal_W must be real numbers", id="str-normal"),
        pytest.param(
            [1.0, 0.5], np.array([True, False]), r"normal_W must be real numbers", id="bool-normal"
        ),
        pytest.param(
            np.array([1.0, 0.5]), np.zeros(3), r"normal_W must be 2 real numbers", id="long-normal"
        ),
        pytest.param(
            np.ma.array([1.0, 0.5], mask=[False, True]),
            [-1.0, 0.0],
            r"point_W .* masked",
            id="masked-point",
        ),
    ],
)
def test_contains_refuses_malformed_point_or_normal(point, normal, pattern: str) -> None:
    _, right = tippability_regions(SQUARE)
    with pytest.raises(ValueError, match=pattern):
        right.contains(point, normal)


def test_contains_takes_any_real_pair() -> None:
    # Triangle edge 1: left region t in (1/2, 1] (see test_open_end_shrinks_by_tol).
    left, _ = tippability_regions(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    s2 = math.sqrt(0.5)
    assert left.contains(np.array([0.25, 0.75]), np.array([-s2, -s2]))
    assert left.contains((0.25, 0.75), [-s2, -s2])
    assert left.contains(np.array([0.25, 0.75], dtype=np.float32), [-1, -1])  # normalised here
    assert not left.contains([0.75, 0.25], (-s2, -s2))


BAD_TOLS = [
    pytest.param(math.nan, ValueError, id="nan"),
    pytest.param(-1.0, ValueError, id="negative"),
    pytest.param(1e10, ValueError, id="huge"),
    pytest.param(MAX_TOL, ValueError, id="bound"),
    pytest.param("a", TypeError, id="str"),
    pytest.param(None, TypeError, id="none"),
    pytest.param(True, TypeError, id="bool"),
]


@pytest.mark.parametrize(("tol", "error"), BAD_TOLS)
def test_bad_tol_is_refused(tol, error: type) -> None:
    pattern = rf"tol must be .*got {re.escape(repr(tol))}"
    with pytest.raises(error, match=pattern):
        tippability_regions(SQUARE, tol=tol)
    with pytest.raises(error, match=pattern):
        support_contacts(SQUARE, tol=tol)
    _, right = tippability_regions(SQUARE)
    with pytest.raises(error, match=pattern):
        right.contains([1.0, 0.5], [1.0, 0.0], tol=tol)


@pytest.mark.parametrize("tol", [0.0, 0, 0.999 * MAX_TOL], ids=["zero", "int-zero", "near-bound"])
def test_tol_range_is_accepted(tol) -> None:
    assert tippability_regions(SQUARE, tol=tol) == tippability_regions(SQUARE)
    assert support_contacts(SQUARE, tol=tol)[0] == (0, 1)


def test_open_end_shrinks_by_tol() -> None:
    # Triangle edge 1: left region t in (1/2, 1]; points within tol of t = 1/2 are refused.
    left, _ = tippability_regions(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    s2 = math.sqrt(0.5)
    assert not left.contains([0.5 - 1e-12, 0.5 + 1e-12], [-s2, -s2])
    assert left.contains([0.5 - 1e-6, 0.5 + 1e-6], [-s2, -s2])
    assert not left.contains([0.5 - 1e-6, 0.5 + 1e-6], [-s2, -s2], tol=1e-4)


@pytest.mark.parametrize(
    "bad",
    [
        [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]],  # clockwise
        [[0.0, 0.0], [1.0, 0.0]],
        [[0.0, 0.0], [1.0, 0.0], [math.nan, 1.0]],
        [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]],  # collinear
        [[math.cos(k * 4 * math.pi / 5), math.sin(k * 4 * math.pi / 5)] for k in range(5)],
        [[0.0, 0.0], [1.0, 0.0], ["0", "1"]],
        [[0.0, 0.0], [1.0, 0.0], [False, True]],
    ],
    ids=["clockwise", "two-vertices", "nan", "collinear", "pentagram", "str", "bool"],
)
def test_bad_vertices_raise(bad) -> None:
    # The scene loader's checks of object.vertices (a SceneError is a ValueError).
    with pytest.raises(SceneError, match="scene_or_vertices"):
        tippability_regions(bad)
    with pytest.raises(SceneError, match="scene_or_vertices"):
        support_contacts(bad)


def test_scene_input_matches_world_vertices() -> None:
    scene = scene_from_dict(
        {
            "palm": {"width": 1.0, "pose": [0.1, 0.85, 0.0]},
            "fingers": [{"length": 0.6, "angle": -1.5708}, {"length": 0.7, "angle": -1.5708}],
            "object": {"vertices": [[-0.2, 0.0], [0.2, 0.0], [0.15, 0.3], [-0.2, 0.25]]},
        }
    )
    from_scene = tippability_regions(scene)
    from_vertices = tippability_regions(scene.object.vertices_W0)
    assert from_scene == from_vertices
    assert not from_scene[1].is_empty  # the vertical left side is right-tippable


# ----------------------------------------------------------------------------------------
# Brute force against the statics oracle
# ----------------------------------------------------------------------------------------

FIXED = {
    "square": SQUARE,
    "tall-rect": np.array([[-0.2, 0.0], [0.2, 0.0], [0.2, 1.5], [-0.2, 1.5]]),
    "right-triangle": np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
    "overhang-right": np.array([[0.0, 0.0], [1.0, 0.0], [1.3, 3.0], [0.2, 2.5]]),
    "inverted-trapezoid": np.array([[-1.0, 0.0], [1.0, 0.0], [2.0, 1.0], [-2.0, 1.0]]),
    "hexagon": np.array(
        [
            [math.cos(a), math.sin(a) + math.sqrt(3) / 2]
            for a in np.arange(6) * math.pi / 3 - 2 * math.pi / 3
        ]
    ),
}


@pytest.mark.parametrize("name", list(FIXED))
def test_fixed_polygons_against_statics(name: str) -> None:
    v = FIXED[name]
    counts = check_against_oracle(v, np.random.default_rng(7), n_edge=300, n_vertex=300)
    assert counts["left"] + counts["right"] > 0


@pytest.mark.parametrize("name", ["square", "right-triangle", "overhang-right", "hexagon"])
def test_lp_feasibility_matches(name: str) -> None:
    """A second oracle: the LP "equilibrium with the unloaded support force at zero".

    Variables (c, c_other, b) >= 0 with the unloaded support force fixed at 0; feasible
    exactly when a finite squeeze unloads that support contact with all forces admissible.
    """
    v = FIXED[name]
    left, right = tippability_regions(v)
    p, n, _ = admissible_contacts(v, 15, 15, np.random.default_rng(3))
    x_sup = np.sort(v[v[:, 1] < 1e-12, 0])
    p_L, p_R = np.array([x_sup[0], 0.0]), np.array([x_sup[1], 0.0])
    g = geo.polygon_centroid(v)
    n_checked = 0
    for region, p_C, p_other, h in ((right, p_R, p_R, (-1.0, 0.0)), (left, p_L, p_L, (1.0, 0.0))):
        _, margin = statics_oracle(v, p, n, region.side)
        for pi, ni, mi in zip(p, n, margin, strict=True):
            if mi < 1e-6:
                continue
            a_eq = np.array(
                [
                    [ni[0], 0.0, h[0]],
                    [ni[1], 1.0, h[1]],
                    [geo.cross2(pi, ni), p_other[0], geo.cross2(p_C, np.array(h))],
                ]
            )
            b_eq = np.array([0.0, 1.0, g[0]])  # minus gravity: (0, +1, x_G * 1)
            res = linprog(np.zeros(3), A_eq=a_eq, b_eq=b_eq, bounds=[(0, None)] * 3)
            assert res.status in (0, 2)
            assert (res.status == 0) == region.contains(pi, ni), (region.side, pi, ni)
            n_checked += 1
    assert n_checked > 50


@settings(max_examples=40, deadline=None)
@given(v=resting_polygons(), seed=st.integers(0, 2**16))
def test_random_polygons_against_statics(v: np.ndarray, seed: int) -> None:
    check_against_oracle(v, np.random.default_rng(seed), n_edge=25, n_vertex=25)


# ----------------------------------------------------------------------------------------
# Structure: mirror symmetry and the paper's formulas
# ----------------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(v=resting_polygons())
def test_left_is_mirror_of_right(v: np.ndarray) -> None:
    k = len(v)
    mirrored = (v * np.array([-1.0, 1.0]))[::-1]  # x -> -x, reversed to stay CCW
    left, right = tippability_regions(v)
    m_left, m_right = tippability_regions(mirrored)
    for a, b in ((right, m_left), (left, m_right)):
        # Vertex i maps to k-1-i, edge i to k-2-i, t to 1-t, normal angle phi to pi - phi.
        edges_a = sorted(((k - 2 - s.edge) % k, 1 - s.t_end, 1 - s.t_start) for s in a.edges)
        edges_b = sorted((s.edge, s.t_start, s.t_end) for s in b.edges)
        assert [e[0] for e in edges_a] == [e[0] for e in edges_b]
        np.testing.assert_allclose([e[1:] for e in edges_a], [e[1:] for e in edges_b], atol=1e-9)
        verts_a = sorted((k - 1 - s.vertex, s.angle_max - s.angle_min) for s in a.vertices)
        verts_b = sorted((s.vertex, s.angle_max - s.angle_min) for s in b.vertices)
        assert [x[0] for x in verts_a] == [x[0] for x in verts_b]
        np.testing.assert_allclose([x[1] for x in verts_a], [x[1] for x in verts_b], atol=1e-9)
        for sa in a.vertices:
            sb = next(s for s in b.vertices if s.vertex == k - 1 - sa.vertex)
            diff = math.remainder((math.pi - sa.angle_max) - sb.angle_min, 2 * math.pi)
            assert abs(diff) < 1e-9
            assert (sa.min_closed, sa.max_closed) == (sb.max_closed, sb.min_closed)


def paper_right_region(v: np.ndarray) -> tuple[dict[int, tuple], dict[int, tuple]]:
    """The paper's right region (section 2.4), with its stated validity conditions.

    Edge i: the part between vertex i and the foot of the ray R_p_i (from R, perpendicular to
    edge i), valid if the ray's angle alpha_i is in (pi/2, 3pi/2). Vertex i: finger angles
    beta_i - pi/2 < phi < gamma_i, valid if 0 < gamma_i < pi; returned as normal angles
    (phi - pi/2) together with the start of the vertex's cone of normals.
    """
    k = len(v)
    on = v[:, 1] < 1e-12
    p_R = v[on][np.argmax(v[on, 0])]
    edges, verts = {}, {}
    for i in range(k):
        a, b = v[i], v[(i + 1) % k]
        if on[i] and on[(i + 1) % k]:
            continue
        d = b - a
        t_foot = float(np.dot(p_R - a, d) / np.dot(d, d))
        foot = a + t_foot * d
        alpha = math.atan2(*(foot - p_R)[::-1]) % (2 * math.pi)
        if math.pi / 2 < alpha < 3 * math.pi / 2 and t_foot > 0:
            edges[i] = (0.0, min(t_foot, 1.0))
    for i in range(k):
        if on[i]:
            continue
        nxt, prv = v[(i + 1) % k], v[i - 1]
        beta = math.atan2(v[i, 1] - p_R[1], v[i, 0] - p_R[0])
        gamma = math.atan2(v[i, 1] - nxt[1], v[i, 0] - nxt[0])
        gamma_prev = math.atan2(prv[1] - v[i, 1], prv[0] - v[i, 0])  # flush with edge i-1
        if 0 < gamma < math.pi:
            verts[i] = (beta - math.pi, gamma - math.pi / 2, gamma_prev - math.pi / 2)
    return edges, verts


@settings(max_examples=60, deadline=None)
@given(v=resting_polygons())
def test_right_region_agrees_with_paper_formulas(v: np.ndarray) -> None:
    _, right = tippability_regions(v)
    edges, verts = paper_right_region(v)
    ours = {s.edge: (s.t_start, s.t_end) for s in right.edges}
    assert ours.keys() == edges.keys()
    for i, (t0, t1) in edges.items():
        np.testing.assert_allclose(ours[i], (t0, t1), atol=1e-9)
    got = {s.vertex: s for s in right.vertices}
    for i, (lo_paper, hi, cone_start) in verts.items():
        # The paper's lower bound, then the two clips documented in the module: the cone
        # start (finger flush with edge i-1) and n_x > 0.
        lo_paper = hi + math.remainder(lo_paper - hi, 2 * math.pi)
        cone_start = hi - (hi - cone_start) % (2 * math.pi)
        lo = max(lo_paper, cone_start, -math.pi / 2)
        if hi - lo <= 1e-9:
            assert i not in got
            continue
        s = got.pop(i)
        assert math.remainder(s.angle_max - hi, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        assert s.angle_max - s.angle_min == pytest.approx(hi - lo, abs=1e-9)
    assert not got, f"vertex subregions the paper does not have: {got}"


#: A regular hexagon on an edge: the line along edge 2's inward normal through vertex 2
#: passes exactly through the left support contact (vertex 0), so that vertex's arc ends
#: on the moment half-plane's boundary.
HEXAGON = np.array(
    [[-0.1, 0.0], [0.1, 0.0], [0.2, 0.1 * math.sqrt(3)], [0.1, 0.2 * math.sqrt(3)],
     [-0.1, 0.2 * math.sqrt(3)], [-0.2, 0.1 * math.sqrt(3)]]
)  # fmt: skip


def _region_shape(region) -> tuple:
    """What a region is: its subregions, and its support contact from vertex 0 in units of
    the object's size."""
    size = np.ptp(region.vertices_W, axis=0).max()
    return (
        [(e.edge, round(e.t_start, 9), round(e.t_end, 9)) for e in region.edges],
        [
            (s.vertex, round(s.angle_min, 9), round(s.angle_max, 9), s.min_closed, s.max_closed)
            for s in region.vertices
        ],
        tuple(np.round((region.contact_W - region.vertices_W[0]) / size, 9)),
    )


@pytest.mark.parametrize("k", [1e-3, 0.01, 0.1, 3.0, 7.0, 1e3])
@pytest.mark.parametrize("dx", [0.0, 0.37])
def test_a_boundary_on_a_tie_does_not_depend_on_rounding(k: float, dx: float) -> None:
    """Scaled by k and shifted by dx (object sizes), the hexagon's regions are the same; the
    tie itself is outside (the pushing force's moment about the support contact is zero, and
    the region needs a strictly tipping one)."""
    size = np.ptp(HEXAGON, axis=0).max()
    v = (HEXAGON + np.array([dx * size, 0.0])) * k
    left, right = tippability_regions(v)
    ref_left, ref_right = tippability_regions(HEXAGON)
    assert _region_shape(left) == _region_shape(ref_left)
    assert _region_shape(right) == _region_shape(ref_right)
    d = v[3] - v[2]
    n = np.array([-d[1], d[0]]) / np.hypot(*d)  # edge 2's inward normal
    r = v[2] - v[0]
    assert abs(r[0] * n[1] - r[1] * n[0]) <= 1e-12 * k  # the moment vanishes: a tie
    assert not left.contains(v[2], n)
