"""Pure planar geometry: rotations, polygons, hand kinematics and world polygons of every body.

Frames follow docs/conventions.md ("Frames"): world W (y up, support at y = 0), palm frame P
with the finger joints at ``(-w/2, 0)`` and ``(+w/2, 0)``, object frame O at the object's
centroid. A hand configuration is the vector ``h = (x_p, y_p, theta_p, q1, q2)``; an object
pose is ``q = (x, y, theta)``. Every polygon is an ``(n, 2)`` array of counter-clockwise
vertices.
"""

from __future__ import annotations

import math

import numpy as np

#: Body names in contact order; index 0 is the support half-plane y <= 0.
BODY_NAMES = ("support", "palm", "finger1", "finger2")
SUPPORT, PALM, FINGER1, FINGER2 = range(4)


def rot(theta: float) -> np.ndarray:
    """2x2 rotation matrix by ``theta`` (counter-clockwise)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def norms(v: np.ndarray) -> np.ndarray:
    """Euclidean norms of the vectors along the last axis (no BLAS call, see :func:`rotate`)."""
    return np.sqrt((v * v).sum(axis=-1))


def cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray | float:
    """z component of ``a x b`` for 2-vectors (broadcasts over leading axes)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def perp(a: np.ndarray) -> np.ndarray:
    """``k x a``: ``a`` rotated by +pi/2."""
    return np.stack([-a[..., 1], a[..., 0]], axis=-1)


def rotate(points: np.ndarray, theta: float) -> np.ndarray:
    """Points ``(..., 2)`` rotated by ``theta`` (counter-clockwise) about the origin.

    Written out rather than as a product with :func:`rot`: numpy's matrix products go
    through the machine's BLAS, whose rounding differs between processors.
    """
    c, s = math.cos(theta), math.sin(theta)
    x, y = points[..., 0], points[..., 1]
    return np.stack([c * x - s * y, s * x + c * y], axis=-1)


def transform(pose: np.ndarray, points_B: np.ndarray) -> np.ndarray:
    """Points ``(n, 2)`` in a body frame to the world, for a body pose ``(x, y, theta)``."""
    return rotate(points_B, pose[2]) + pose[:2]


def following(a: np.ndarray) -> np.ndarray:
    """``a`` with its first row moved to the end, so that row ``k`` is the one after ``k``
    cyclically (for polygon vertices, the next vertex): ``np.roll(a, -1, axis=0)`` without
    its overhead, which dominated building a scene."""
    return np.concatenate((a[1:], a[:1]))


def edge_vectors(vertices: np.ndarray) -> np.ndarray:
    """``v_{k+1} - v_k`` for every edge of a closed polygon, shape (n, 2)."""
    return following(vertices) - vertices


def polygon_area(vertices: np.ndarray) -> float:
    """Signed area (positive for counter-clockwise vertices)."""
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float((x * following(y)).sum() - (following(x) * y).sum())


def polygon_centroid(vertices: np.ndarray) -> np.ndarray:
    """Centroid of a simple polygon of uniform density, shape (2,)."""
    x, y = vertices[:, 0], vertices[:, 1]
    xn, yn = following(x), following(y)
    a = x * yn - xn * y
    area = 0.5 * a.sum()
    return np.array([((x + xn) * a).sum(), ((y + yn) * a).sum()]) / (6.0 * area)


def polygon_inertia(vertices_B: np.ndarray, mass: float) -> float:
    """Moment of inertia about the frame origin (the centroid) of a uniform polygon of ``mass``."""
    x, y = vertices_B[:, 0], vertices_B[:, 1]
    xn, yn = following(x), following(y)
    a = x * yn - xn * y
    area = 0.5 * a.sum()
    j = (a * (x * x + x * xn + xn * xn + y * y + y * yn + yn * yn)).sum() / 12.0
    return float(mass * j / area)


def edge_normals(vertices: np.ndarray) -> np.ndarray:
    """Outward unit normals of the edges ``v_k -> v_{k+1}`` of a CCW polygon, shape (n, 2)."""
    n = edge_vectors(vertices)[:, ::-1] * (1.0, -1.0)  # (d_y, -d_x)
    return n / norms(n)[:, None]


def finger_polygon_local(length: float, thickness: float, finger: int) -> np.ndarray:
    """CCW finger rectangle in its own link frame (x along the finger axis, origin at the joint).

    The palmar edge runs along the x axis; the body lies on the side away from the inward
    normal, which is +y for finger 1 and -y for finger 2 (docs/conventions.md, "Frames"). The
    palmar edge is always edge 3 (vertices 3 -> 0) so both fingers index it the same way.
    """
    L, t = length, thickness
    if finger == 1:  # inward normal +y; body at y in [-t, 0]
        return np.array([[0.0, 0.0], [0.0, -t], [L, -t], [L, 0.0]])
    # finger 2: inward normal -y; body at y in [0, t]
    return np.array([[L, 0.0], [L, t], [0.0, t], [0.0, 0.0]])


#: Index of the palmar (inner) edge of a finger polygon and of the fingertip vertex on it.
FINGER_PALMAR_EDGE = 3


def fingertip_index(finger: int) -> int:
    """Vertex index of the fingertip (the palmar edge's end at the tip)."""
    return 3 if finger == 1 else 0


def palm_polygon_local(width: float, thickness: float) -> np.ndarray:
    """CCW palm rectangle ``[-w/2, w/2] x [0, t]`` in P; edge 0 (J1 -> J2) is the palmar edge."""
    h = width / 2.0
    return np.array([[-h, 0.0], [h, 0.0], [h, thickness], [-h, thickness]])


def segment_distance(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> float:
    """Least distance between segments ``a0 a1`` and ``b0 b1``; zero where they cross."""
    da, db, d0 = a1 - a0, b1 - b0, b0 - a0
    denom = cross2(da, db)
    if denom != 0.0:
        t, u = cross2(d0, db) / denom, cross2(d0, da) / denom
        if 0.0 <= t <= 1.0 and 0.0 <= u <= 1.0:
            return 0.0

    def to_segment(p: np.ndarray, c0: np.ndarray, dc: np.ndarray) -> float:
        r = p - c0
        t = min(max(_dot2(r, dc) / max(_dot2(dc, dc), 1e-300), 0.0), 1.0)
        e = r - t * dc
        return math.sqrt(_dot2(e, e))

    return min(
        to_segment(a0, b0, db),
        to_segment(a1, b0, db),
        to_segment(b0, a0, da),
        to_segment(b1, a0, da),
    )


def _dot2(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[0] + a[1] * b[1])


def is_convex_ccw(vertices: np.ndarray, tol: float = 1e-12) -> bool:
    """True when the polygon is strictly convex with counter-clockwise vertices."""
    d = edge_vectors(vertices)
    turn = cross2(d, following(d))
    scale = norms(d) * norms(following(d))
    return bool(np.all(turn > tol * scale)) and polygon_area(vertices) > 0


def turns_once(vertices: np.ndarray) -> bool:
    """True when the exterior angles sum to 2 pi: a convex CCW polygon that winds only once
    (rules out star polygons whose every turn is to the left)."""
    d = edge_vectors(vertices)
    ang = np.arctan2(cross2(d, following(d)), (d * following(d)).sum(axis=1))
    return bool(abs(ang.sum() - 2 * math.pi) < 1e-6)


def penetration_depth(a: np.ndarray, b: np.ndarray) -> float:
    """Depth by which convex polygons ``a`` and ``b`` overlap (separating-axis test); <= 0 if apart.

    The result is the smallest overlap over the edge normals of both polygons, i.e. minus
    their separation distance along the best axis.
    """
    depth = math.inf
    for p, other in ((a, b), (b, a)):
        n = edge_normals(p)
        # Each edge's support line: how far the other polygon reaches behind it.
        reach = (p * n).sum(axis=1) - (other[:, None, :] * n[None]).sum(-1).min(axis=0)
        depth = min(depth, float(reach.min()))
    return depth


def turn_to_contact(a: np.ndarray, centre: np.ndarray, b: np.ndarray, ccw: bool = True) -> float:
    """Least angle (rad, >= 0) through which polygon ``a`` must turn about ``centre``
    (counter-clockwise, or clockwise if not ``ccw``) for its boundary to meet polygon ``b``'s;
    ``inf`` if it never does within a full turn. ``b`` stays fixed; both ``(n, 2)`` in one frame.

    The first meeting is a vertex of one polygon reaching an edge of the other, so the
    candidates are where each vertex's circle about ``centre`` crosses the other polygon's edges:
    a vertex of ``a`` moves along its circle by the turn, a vertex of ``b`` moves along its
    circle by minus the turn in ``a``'s frame.
    """
    if not ccw:  # a clockwise turn is a counter-clockwise one in the mirrored plane
        flip = np.array([1.0, -1.0])
        return turn_to_contact(a * flip, centre * flip, b * flip)
    best = math.inf
    for moving, fixed, sign in ((a, b, 1.0), (b, a, -1.0)):
        p = moving - centre  # (m, 2) vertices about the centre
        e0 = fixed - centre  # edges e0[k] -> e1[k]
        d = edge_vectors(e0)
        # |e0 + t d|^2 = |p|^2 for every vertex and edge: a t^2 + 2 b t + c = 0
        qa = (d * d).sum(axis=1)[None, :]
        qb = (e0 * d).sum(axis=1)[None, :]
        qc = (e0 * e0).sum(axis=1)[None, :] - (p * p).sum(axis=1)[:, None]
        disc = qb * qb - qa * qc
        ok = (disc >= 0.0) & (qa > 0.0)
        root = np.sqrt(np.where(ok, disc, 0.0))
        for t in ((-qb - root) / qa, (-qb + root) / qa):
            hit = ok & (t >= 0.0) & (t <= 1.0)
            if not hit.any():
                continue
            x = e0[None, :, :] + t[:, :, None] * d[None, :, :]
            turn = np.arctan2(x[..., 1], x[..., 0]) - np.arctan2(p[:, 1], p[:, 0])[:, None]
            turn = np.mod(sign * turn, 2.0 * math.pi)[hit]
            turn[turn > 2.0 * math.pi - 1e-12] = 0.0  # a touch at the start, not a full turn
            best = min(best, float(turn.min()))
    return best
