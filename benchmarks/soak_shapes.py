"""The soak's random shapes: strictly convex polygons with 3-12 vertices, diameter 5%-80% of
the palm width, aspect up to 1:30, density 1e-3..1e3, with nearly collinear vertices, very
short edges, nearly parallel edges, slivers, near-circles and a bulge on the resting edge
mixed in (:func:`random_stress_scene`), each in the hand set-up of the fig13 scene
(:func:`stress_scene`). Used by the soak (``benchmarks/soak.py``), the edge probe, the step
times' suites and the stress tests."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Version of the shape population of :func:`random_stress_scene`, part of the checkpoint's
#: name: a checkpoint written with other shapes is never resumed.
POPULATION = 2

#: Gap between the hanging longer finger's tip (or the object's top) and the palm height,
#: in palm widths (the paper's "just high enough" set-up).
CLEARANCE = 0.01
#: Shape kinds drawn by :func:`stress_polygon`.
KINDS = ("plain", "collinear", "short_edge", "parallel", "sliver", "near_circle", "bulge")
#: Shape kinds drawn by :func:`random_stress_scene`: :data:`KINDS` and a bulge sunk into the
#: support (:func:`bulge_polygon` resting on the bulge's neighbours).
SCENE_KINDS = (*KINDS, "bulge_sunk")
#: Ranges of :func:`random_stress_scene`: largest aspect ratio, density (mass per unit area,
#: palm widths squared), and the offset of a resting-edge bulge's vertex from the line through
#: its neighbours (palm widths).
MAX_ASPECT = 30.0
DENSITY_RANGE = (1e-3, 1e3)
BULGE_RANGE = (1e-12, 1e-9)


def rest_on_stable_edge(v: np.ndarray) -> np.ndarray:
    """Turn a CCW polygon so that its most stable edge (the centroid projecting farthest from
    both ends) lies on ``y = 0`` as edge 0, with the centroid at ``x = 0``."""
    from grasp_env.core.geometry import norms, polygon_centroid, rotate

    c = polygon_centroid(v)
    d = np.roll(v, -1, axis=0) - v
    t = ((c - v) * d).sum(axis=1) / (d * d).sum(axis=1)
    k = int(np.argmax(np.minimum(t, 1.0 - t) * norms(d)))
    phi = math.atan2(d[k, 1], d[k, 0])
    v = np.roll(rotate(v, -phi), -k, axis=0)
    v = v - np.array([polygon_centroid(v)[0], v[0, 1]])
    v[:2, 1] = 0.0
    return v


def stress_polygon(
    rng: np.random.Generator,
    n: int,
    size: float,
    aspect: float,
    kind: str = "plain",
    eps: float = 1e-4,
) -> np.ndarray:
    """A random strictly convex CCW polygon resting on edge 0 on ``y = 0``, centroid at x = 0.

    Args:
        rng: the random generator.
        n: vertex count of the base polygon (3..12; the kinds below may add one).
        size: diameter, in palm widths.
        aspect: aspect ratio of the ellipse the base vertices lie on (>= 1).
        kind: ``"plain"``; ``"collinear"`` (a vertex added ``eps`` times an edge's length
            outside its midpoint: two nearly collinear edges); ``"short_edge"`` (a corner cut
            ``eps * size`` deep: a very short edge); ``"parallel"`` (a quadrilateral whose top
            and sides are within ``eps`` rad of parallel to the base and to each other);
            ``"sliver"`` (a rectangle of aspect ``aspect`` lying flat); ``"near_circle"``
            (8-12 vertices evenly spaced, up to a tenth of a gap, on an ellipse of aspect
            1..1.05; ``n`` and ``aspect`` are overridden); ``"bulge"`` (a vertex added inside
            the resting edge, just outside the line through its neighbours: resting on it and
            one neighbour, the other neighbour just above the support; :func:`bulge_polygon`).
        eps: the degeneracy's size (1e-12..1e-2 for ``"collinear"``, 1e-6..1e-2 otherwise;
            unused by the near-circle and bulge kinds).
    """
    from grasp_env.core.geometry import norms
    from grasp_env.envs.shapes import random_convex_polygon

    if kind == "parallel":
        b, h = size / math.hypot(1.0, 1.0 / aspect), size / aspect / math.hypot(1.0, 1.0 / aspect)
        e = eps * rng.choice([-1.0, 1.0], 3)
        v = np.array(
            [[-b / 2, 0.0], [b / 2, 0.0], [b / 2 + e[0] * h, h], [-b / 2 + e[1] * h, h + e[2] * b]]
        )
        return rest_on_stable_edge(v)
    if kind == "sliver":
        b = size / math.hypot(1.0, 1.0 / aspect)
        h = b / aspect
        return rest_on_stable_edge(np.array([[-b / 2, 0.0], [b / 2, 0.0], [b / 2, h], [-b / 2, h]]))
    if kind == "near_circle":
        m = int(rng.integers(8, 13))
        angles = 2 * math.pi * (np.arange(m) + rng.uniform(-0.1, 0.1, m)) / m
        ratio = 1.0 + 0.05 * rng.uniform()
        v = np.stack([np.cos(angles), ratio * np.sin(angles)], axis=1)
        v *= size / float(norms(v[:, None] - v[None]).max())
        return rest_on_stable_edge(v)
    if kind == "bulge":
        return bulge_polygon(rng, n, size, aspect, str(rng.choice(["left", "right"])))
    m = min(n, 11) if kind in ("collinear", "short_edge") else n
    v = random_convex_polygon(rng, (m, m), (size, size), (aspect, aspect))
    if kind == "collinear":
        k = int(rng.integers(1, len(v)))  # not edge 0, the resting edge
        a, b = v[k], v[(k + 1) % len(v)]
        d = b - a
        mid = 0.5 * (a + b) + eps * np.array([d[1], -d[0]])  # outward for a CCW polygon
        v = np.insert(v, k + 1, mid, axis=0)
    elif kind == "short_edge":
        k = int(rng.integers(2, len(v))) if len(v) > 2 else 2
        p, prv, nxt = v[k], v[k - 1], v[(k + 1) % len(v)]
        cut = eps * size
        a = p + cut * (prv - p) / norms(prv - p)
        b = p + cut * (nxt - p) / norms(nxt - p)
        v = np.concatenate([v[:k], [a, b], v[k + 1 :]])
    return rest_on_stable_edge(v)


def bulge_polygon(
    rng: np.random.Generator, n: int, size: float, aspect: float, rest: str
) -> np.ndarray:
    """A random convex polygon whose resting edge has a vertex added inside it, a distance
    ``d`` of 1e-12..1e-9 palm widths (log-uniform, ``BULGE_RANGE``) outside the line through
    its neighbours: a resting edge that is nearly but not exactly straight. (On the inner side
    the polygon would not be convex, which scenes refuse.)

    Args:
        rng: the random generator.
        n: vertex count of the base polygon (3..11 are used; the bulge adds one).
        size: diameter, in palm widths.
        aspect: aspect ratio of the ellipse the base vertices lie on (>= 1).
        rest: ``"left"`` or ``"right"``: resting on the added vertex and its left or right
            neighbour (edge 0 on ``y = 0``), the other neighbour about ``d`` above the support
            (sheared by about ``d`` over the object); ``"neighbours"``: resting on both
            neighbours, the added vertex ``d`` below the support, inside the contact tolerance
            (edge 0 is not on ``y = 0``: a scene, not a :func:`stress_polygon`).

    Returns:
        CCW vertices, the added one between vertices 0 and 1 of the base polygon's resting edge
        on :func:`rest_on_stable_edge`, centroid at ``x = 0``.
    """
    from grasp_env.envs.shapes import random_convex_polygon

    for _ in range(10):
        v = rest_on_stable_edge(
            random_convex_polygon(rng, (min(n, 11),) * 2, (size,) * 2, (aspect,) * 2)
        )
        a, b = v[0].copy(), v[1].copy()
        d = 10 ** rng.uniform(*np.log10(BULGE_RANGE))
        t = rng.uniform(0.3, 0.7)
        mid = a + t * (b - a) - np.array([0.0, d])
        v = np.insert(v, 1, mid, axis=0)  # [a, mid, b, ...]
        if rest == "left":  # shear y by d over a..mid: a and mid on the support
            v[:, 1] += d * (v[:, 0] - a[0]) / (mid[0] - a[0])
            v[:2, 1] = 0.0
        elif rest == "right":  # shear about b: mid and b on the support; mid first
            v[:, 1] += d * (b[0] - v[:, 0]) / (b[0] - mid[0])
            v[1:3, 1] = 0.0
            v = np.roll(v, -1, axis=0)
        elif rest != "neighbours":
            raise ValueError(f"rest must be left, right or neighbours, got {rest!r}")
        if rest == "neighbours" or v[2:, 1].min() > 0.0:
            v[:, 0] -= polygon_centroid_x(v)
            return v
    raise RuntimeError("no bulge polygon clear of the support in 10 draws")


def polygon_centroid_x(v: np.ndarray) -> float:
    """The x of a polygon's centroid."""
    from grasp_env.core.geometry import polygon_centroid

    return float(polygon_centroid(v)[0])


def stress_scene(
    polygon: np.ndarray,
    mass: float | None = None,
    base: str = "fig13",
    x0: float = 0.0,
    *,
    density: float | None = None,
) -> dict[str, Any]:
    """A scene dict: ``polygon`` (resting on y = 0, centroid at x = 0) at ``x0`` with ``mass``
    or ``density`` (one of them), in ``base``'s hand, palm centred over the polygon's extent
    just above the longer finger's reach of the support (or of the object's top), fingers
    hanging straight down."""
    import grasp_env
    from grasp_env.envs.shapes import scene_to_dict

    if (mass is None) == (density is None):
        raise ValueError("give either mass or density")
    scene = grasp_env.load_scene(base)
    d = scene_to_dict(scene)
    v = np.asarray(polygon, float) + np.array([x0, 0.0])
    w = scene.palm.width
    y = max(max(f.length for f in scene.fingers), float(v[:, 1].max())) + CLEARANCE * w
    d["palm"]["pose"] = [0.5 * float(v[:, 0].min() + v[:, 0].max()), y, 0.0]
    for f in d["fingers"]:
        f["angle"] = -0.5 * math.pi
    d["name"] = "stress"
    d["object"] = {"vertices": v.tolist()}
    if mass is not None:
        d["object"]["mass"] = float(mass)
    else:
        d["object"]["density"] = float(density)
    return d


def random_stress_scene(
    rng: np.random.Generator, kinds: tuple[str, ...] = SCENE_KINDS
) -> dict[str, Any]:
    """A random :func:`stress_scene` over the full stress ranges (for the soak): a kind drawn
    from ``kinds``, 3-12 vertices, diameter 0.05-0.8 palm widths, aspect 1..``MAX_ASPECT`` and
    density over ``DENSITY_RANGE`` (both log-uniform). ``description`` holds the kind."""
    from grasp_env.core.scene_loading import load_scene
    from grasp_env.errors import SceneError

    for _ in range(100):
        kind = str(rng.choice(kinds))
        n = int(rng.integers(3, 13))
        size = float(rng.uniform(0.05, 0.8))
        aspect = float(np.exp(rng.uniform(0.0, math.log(MAX_ASPECT))))
        if kind == "bulge_sunk":
            poly = bulge_polygon(rng, n, size, aspect, "neighbours")
        else:
            eps = float(10 ** rng.uniform(-12 if kind == "collinear" else -6, -2))
            poly = stress_polygon(rng, n, size, aspect, kind, eps)
        d = stress_scene(poly, density=float(10 ** rng.uniform(*np.log10(DENSITY_RANGE))))
        try:
            load_scene(d)
        except SceneError:
            continue  # e.g. too wide for the hanging fingers: draw another
        d["description"] = kind
        return d
    raise RuntimeError("no valid stress scene in 100 draws")
