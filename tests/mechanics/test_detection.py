"""Contact detection (:func:`grasp_env.mechanics.contacts.detect`) against a brute-force detection
written here from the documented rules, over every vertex-edge pair of the object and the
support, palm and fingers.

The placements are mostly contrived touches, where the rules decide: an object vertex on a
hand edge, a hand vertex on an object edge, an object edge flush with a hand edge or with
the support, a vertex on a vertex, each nudged off by a fraction of the tolerance along the
normal or past the edge's end, at random orientations (so that many candidates fail the
local-validity test). The reference has no broad phase: a pair within ``tol`` of its edge
is within ``2 tol`` of the body, well inside the kernel's ``10 tol`` margin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import grasp_env
from grasp_env.core.state import EDGE, TIP, ContactKey
from grasp_env.mechanics import contacts as ct

SCENES = ("fig13", "square", "triangle", "hexagon", "pentagon", "flat_trapezoid")
#: Contact tolerances tried, relative to the palm width.
TOLS = (1e-9, 1e-6, 1e-3)


def reference(pl: ct.Placement, tol: float, exclude=frozenset(), counts=None) -> list[tuple]:
    """Contacts by the documented rules, from the placement's world polygons and normals:
    ``|gap| <= tol``, the projection on the edge or the vertex within ``tol`` of its end,
    both of the vertex's neighbours on its side of the edge's line up to
    ``max(4 tol, 1e-7 |d|)`` (or, for a vertex more than ``2 tol`` inside a hand or object
    edge, both reaching at most ``4 tol`` into the other body), not
    excluded, and no earlier kept contact of the same body with the same point (``2 tol``)
    and normal;
    edge contacts (support, palm, fingers; by object vertex, then hand edge) before tip
    contacts (palm, fingers; by hand vertex, then object edge). ``counts`` (a dict), if
    given, counts the pairs within reach rejected as ``"invalid"`` or ``"duplicate"``, and
    the neighbours that dip behind the line by over half the slack but pass."""
    counts = {} if counts is None else counts
    obj, obj_n = pl.obj_W.tolist(), pl.obj_n_W.tolist()
    hands, hands_n = pl.hand_W.tolist(), pl.hand_n_W.tolist()

    def on_edge(p, poly, normals, e):
        a, b, nrm = poly[e], poly[(e + 1) % len(poly)], normals[e]
        rx, ry, dx, dy = p[0] - a[0], p[1] - a[1], b[0] - a[0], b[1] - a[1]
        length = math.hypot(dx, dy)
        t = (rx * dx + ry * dy) / length**2
        gap = rx * nrm[0] + ry * nrm[1]
        over = max(-t, t - 1, 0.0) * length  # past an end: within tol of it
        return abs(gap) <= tol and math.hypot(over, gap) <= tol if over else abs(gap) <= tol

    def within_flush_slack(poly, v, nrm):
        p = poly[v]
        for nbr in (poly[v - 1], poly[(v + 1) % len(poly)]):
            dx, dy = nbr[0] - p[0], nbr[1] - p[1]
            dip, slack = nrm[0] * dx + nrm[1] * dy, max(4 * tol, 1e-7 * math.hypot(dx, dy))
            if dip < -slack:
                return False
            if dip < -slack / 2:
                counts["nearly flush"] = counts.get("nearly flush", 0) + 1
        return True

    def along_within_tol(poly, v, edge, other, other_n):
        a, b = np.array(edge[0]), np.array(edge[1])
        p = np.array(poly[v])
        t = float((p - a) @ (b - a)) / float((b - a) @ (b - a))
        if min(t, 1 - t) * float(np.linalg.norm(b - a)) <= 2 * tol:
            return False
        nbrs = (poly[v - 1], poly[(v + 1) % len(poly)])
        return all(cut_depth(p, np.array(n), other, other_n) <= 4 * tol for n in nbrs)

    def valid(poly, v, nrm, edge=None, other=None, other_n=None):
        if within_flush_slack(poly, v, nrm):
            return True
        if edge is not None and along_within_tol(poly, v, edge, other, other_n):
            counts["along within tol"] = counts.get("along within tol", 0) + 1
            return True
        counts["invalid"] = counts.get("invalid", 0) + 1
        return False

    candidates = []  # (key, point, normal into the object)
    for k, p in enumerate(obj):
        if abs(p[1]) <= tol and valid(obj, k, (0.0, 1.0)):
            candidates.append(((0, EDGE, k, 0), p, (0.0, 1.0)))
    for body in (1, 2, 3):
        poly, normals = hands[body - 1], hands_n[body - 1]
        for k, p in enumerate(obj):
            for j in range(4):
                edge = (poly[j], poly[(j + 1) % 4])
                if on_edge(p, poly, normals, j) and valid(obj, k, normals[j], edge, poly, normals):
                    candidates.append(((body, EDGE, k, j), p, tuple(normals[j])))
    for body in (1, 2, 3):
        poly = hands[body - 1]
        for j, p in enumerate(poly):
            for k in range(len(obj)):
                edge = (obj[k], obj[(k + 1) % len(obj)])
                if on_edge(p, obj, obj_n, k) and valid(poly, j, obj_n[k], edge, obj, obj_n):
                    candidates.append(((body, TIP, k, j), p, (-obj_n[k][0], -obj_n[k][1])))
    kept, out = [], []
    for key, p, n in candidates:
        if key in exclude:
            continue
        if any(
            body2 == key[0]
            and abs(p[0] - p2[0]) <= 2 * tol
            and abs(p[1] - p2[1]) <= 2 * tol
            and n[0] * n2[0] + n[1] * n2[1] > 1 - 1e-9
            for body2, p2, n2 in kept
        ):
            counts["duplicate"] = counts.get("duplicate", 0) + 1
            continue
        kept.append((key[0], p, n))
        out.append(key)
    return out


def cut_depth(p: np.ndarray, q: np.ndarray, poly, normals) -> float:
    """How deep the segment from ``p`` to ``q`` reaches into the convex polygon (vertices
    ``poly``, outward normals ``normals``): the largest, along the segment, of its least
    distance inside the edges' lines. That least distance is concave along the segment, so a
    ternary search finds its largest value (to rounding, after 200 rounds)."""
    A, N = np.asarray(poly, float), np.asarray(normals, float)

    def depth(u: float) -> float:
        return float(np.min(-np.sum((p + u * (q - p) - A) * N, axis=1)))

    lo, hi = 0.0, 1.0
    for _ in range(200):
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        if depth(m1) < depth(m2):
            lo = m1
        else:
            hi = m2
    return max(depth(0.0), depth(1.0), depth(0.5 * (lo + hi)))


def rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def pose_putting(v_B: np.ndarray, at: np.ndarray, theta: float) -> np.ndarray:
    """Object pose of orientation ``theta`` that puts body-frame point ``v_B`` at ``at``."""
    return np.array([*(at - rot(theta) @ v_B), theta])


def touching(scene, rng: np.random.Generator, tol: float):
    """A random hand configuration and an object pose touching a hand body or the support in
    one of the contrived ways, nudged by up to 2 ``tol`` off the touch (half the time)."""
    verts = scene.object.vertices_B
    n = len(verts)
    d_B = np.roll(verts, -1, axis=0) - verts
    angle_B = np.arctan2(-d_B[:, 0], d_B[:, 1])  # outward edge normals' angles
    h = scene.initial_hand + rng.normal(size=5) * (0.05, 0.05, 0.3, 0.5, 0.5)
    pl = ct.Placement(scene, scene.object.start_pose, h)
    k = int(rng.integers(n))
    body, j = int(rng.integers(4)), int(rng.integers(4))
    how = rng.choice(["vertex_on_edge", "tip_on_edge", "flush", "vertex_on_vertex"])
    if body == 0:  # the support: a vertex or a flush edge on y = 0
        theta = -math.pi / 2 - angle_B[k] if how == "flush" else rng.uniform(-math.pi, math.pi)
        q = pose_putting(verts[k], np.array([rng.uniform(-1, 1), 0.0]), theta)
        normal, along = np.array([0.0, 1.0]), np.array([1.0, 0.0])
    else:
        poly, normals = pl.hand_W[body - 1], pl.hand_n_W[body - 1]
        a, b = poly[j], poly[(j + 1) % 4]
        normal, along = normals[j], (b - a) / np.linalg.norm(b - a)
        if how == "tip_on_edge":  # hand vertex j on object edge k
            theta = rng.uniform(-math.pi, math.pi)
            q = pose_putting(verts[k] + rng.uniform() * d_B[k], a, theta)
            normal = -(rot(theta) @ np.array([math.cos(angle_B[k]), math.sin(angle_B[k])]))
            along = rot(theta) @ d_B[k] / np.linalg.norm(d_B[k])
        else:
            t = {
                "vertex_on_edge": rng.uniform(),
                "vertex_on_vertex": 0.0,
                "flush": rng.choice([0.0, 1.0, rng.uniform()]),
            }[how]
            theta = rng.uniform(-math.pi, math.pi)
            if how == "flush":  # tilted half the time by up to twice the flush slack
                theta = math.atan2(-normal[1], -normal[0]) - angle_B[k]
                if rng.random() < 0.5:
                    length = float(np.linalg.norm(d_B[k]))
                    theta += rng.uniform(-2, 2) * max(4 * tol, 1e-7 * length) / length
            q = pose_putting(verts[k], a + t * (b - a), theta)
    if rng.random() < 0.5:
        q[:2] += rng.uniform(-2, 2) * tol * normal + rng.uniform(-2, 2) * tol * along
    return q, h


@pytest.mark.parametrize("name", SCENES)
def test_detect_matches_brute_force(name: str) -> None:
    scene = grasp_env.load_scene(name)
    rng = np.random.default_rng(sum(map(ord, name)))
    seen = dict.fromkeys(
        (
            "edge", "tip", "two on a body", "twin", "invalid", "duplicate", "nearly flush",
            "along within tol",
        ),
        0,
    )  # fmt: skip
    for _ in range(400):
        tol = float(rng.choice(TOLS)) * scene.palm.width
        q, h = touching(scene, rng, tol)
        pl = ct.Placement(scene, q, h)
        expected = reference(pl, tol, counts=seen)
        assert ct.detect(pl, tol) == expected, (q, h, tol)
        if expected and rng.random() < 0.5:  # release some: their twins may take over
            exclude = set(expected[: int(rng.integers(1, len(expected) + 1))])
            released = reference(pl, tol, exclude)
            assert ct.detect(pl, tol, exclude) == released
            seen["twin"] += any(key[1] == TIP for key in set(released) - set(expected))
        kinds = [key[1] for key in expected]
        seen["edge"] += EDGE in kinds
        seen["tip"] += TIP in kinds
        seen["two on a body"] += len({key[:2] for key in expected}) < len(expected)
    assert min(seen.values()) > 0, seen


def test_random_placements_match_brute_force() -> None:
    """Object poses scattered around the start (mostly on or near the support, or apart)."""
    rng = np.random.default_rng(7)
    for name in SCENES:
        scene = grasp_env.load_scene(name)
        for _ in range(100):
            q = scene.object.start_pose + rng.normal(size=3) * (0.1, 0.02, 0.2)
            h = scene.initial_hand + rng.normal(size=5) * (0.1, 0.1, 0.2, 0.5, 0.5)
            tol = float(rng.choice(TOLS)) * scene.palm.width
            pl = ct.Placement(scene, q, h)
            assert ct.detect(pl, tol) == reference(pl, tol)


def square_on_fingertip() -> tuple[ct.Placement, float]:
    """The square scene's 0.3 square with its right side flush against the inner side of
    finger 2 (hanging straight down, inner side edge 3 from (0.5, 0.71) to its tip vertex 0 at
    (0.5, 0.01)) and its bottom-right corner (vertex 1) on that tip vertex."""
    scene = grasp_env.load_scene("square")
    h = scene.initial_hand
    tip = ct.Placement(scene, scene.object.start_pose, h).hand_W[2][0]
    q = pose_putting(scene.object.vertices_B[1], tip, 0.0)
    return ct.Placement(scene, q, h), 1e-9 * scene.palm.width


def test_flush_edge_ending_at_a_fingertip() -> None:
    """Both ends of the flush stretch are edge contacts: the corner at the fingertip (which
    would cut into the square along the tip edge, so only the inner side counts) and the
    top corner. The fingertip's tip contact on the square's side coincides with the corner's
    and is folded into it, until the corner's contact is released."""
    pl, tol = square_on_fingertip()
    keys = ct.detect(pl, tol)
    assert keys == reference(pl, tol) == [(3, EDGE, 1, 3), (3, EDGE, 2, 3)]
    released = ct.detect(pl, tol, exclude={(3, EDGE, 1, 3)})
    assert released == reference(pl, tol, {(3, EDGE, 1, 3)})
    assert released == [(3, EDGE, 2, 3), (3, TIP, 1, 0)]


def test_edge_along_a_face_just_over_the_flush_angle() -> None:
    """The square's right side along finger 2's inner side over the last 5 mm above the
    fingertip, turned by three times the flush angle (3e-7 rad) about the middle of that
    stretch: the two lines cross there and part by 7.5e-10 at its ends, within the
    tolerance. Both ends are contacts, the square's top corner on the finger's side and the
    fingertip on the square's side, though each one's neighbouring edge (the square's side,
    0.3 long; the finger's side, 0.7) dips behind the other's line by more than the flush
    slack: past the stretch it runs outside the other body. The lines turned about the
    corner instead part by 1.5e-9 at the fingertip, which is then no contact."""
    scene = grasp_env.load_scene("square")
    h = scene.initial_hand
    tip = ct.Placement(scene, scene.object.start_pose, h).hand_W[2][0]
    np.testing.assert_allclose(tip, (0.5, 0.01), atol=1e-12)
    corner = scene.object.vertices_B[2]  # top right
    upright = pose_putting(corner, tip + np.array([0.0, 0.005]), 0.0)
    tol = 1e-9 * scene.palm.width
    for pivot, expected in (
        (tip + np.array([0.0, 0.0025]), [(3, EDGE, 2, 3), (3, TIP, 1, 0)]),
        (tip + np.array([0.0, 0.005]), [(3, EDGE, 2, 3)]),
    ):
        theta = 3e-7
        q = np.array([*(rot(theta) @ (upright[:2] - pivot) + pivot), theta])
        pl = ct.Placement(scene, q, h)
        assert ct.detect(pl, tol) == reference(pl, tol) == expected


def test_keys_are_named_tuples_of_python_ints() -> None:
    """Keys are ContactKeys of Python ints: they compare and hash as plain 4-tuples."""
    keys = ct.detect(*square_on_fingertip())
    assert keys and all(type(k) is ContactKey and all(type(x) is int for x in k) for k in keys)
    k = keys[0]
    assert k == tuple(k) and hash(k) == hash(tuple(k))
    assert (k.body, k.kind, k.object_feature, k.hand_feature) == tuple(k)
