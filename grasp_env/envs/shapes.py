"""Random convex objects and the paper's hand set-up for them (environment shape randomizer).

:func:`random_convex_polygon` draws a strictly convex, counter-clockwise polygon resting on a
stable supporting edge; :func:`random_shape_scene` puts it into a base scene's hand set-up
(:func:`hand_setup`: palm centred over the object, parallel to the support, just above the
longer finger's reach of the support, fingers hanging). Randomness comes only from the
``numpy.random.Generator`` passed in.

The shape ranges are relative to the base scene's palm width ``w``: sizes in palm widths,
masses in ``w**2`` (the mass of a ``w x w`` square of density 1). So a base scene scaled by
``k`` (every length times ``k``, densities kept) draws, for the same generator state, the same
object scaled by ``k``, with ``k**2`` times the mass.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core.scene import Scene
from grasp_env.core.scene_loading import load_scene
from grasp_env.errors import SceneError
from grasp_env.planning.preliftoff import centred_hand

#: Default ranges of the shape randomizer: vertex count (inclusive), size (the polygon's
#: diameter, i.e. its largest vertex-to-vertex distance, in palm widths ``w``), aspect ratio
#: of the ellipse the vertices lie on, and mass (in ``w**2``: a ``w x w`` square of density 1
#: has mass 1).
DEFAULT_SHAPE_RANGES: dict[str, tuple[float, float]] = {
    "vertices": (3, 8),
    "size": (0.2, 0.45),
    "aspect": (1.0, 3.0),
    "mass": (0.05, 0.5),
}

#: A wider range for harder benchmarks: up to 12 vertices and elongated shapes (aspect to 5).
WIDE_SHAPE_RANGES: dict[str, tuple[float, float]] = {
    **DEFAULT_SHAPE_RANGES,
    "vertices": (3, 12),
    "aspect": (1.0, 5.0),
}

#: A supporting edge is stable when the centroid projects onto it at least this fraction of
#: its length away from both ends.
STABILITY_MARGIN = 0.1

#: Shapes tried before giving up on one that fits between the hanging fingers.
MAX_SHAPE_TRIES = 100


def random_convex_polygon(
    rng: np.random.Generator,
    vertices: tuple[int, int] = (3, 8),
    size: tuple[float, float] = (0.2, 0.45),
    aspect: tuple[float, float] = (1.0, 3.0),
) -> np.ndarray:
    """A random strictly convex polygon at rest on a stable edge on the support ``y = 0``, in
    the units of ``size`` (:func:`random_shape_scene` gives it in the base scene's).

    The vertices are points of an ellipse with axes ``1`` and ``aspect`` at random angles
    (angular gaps drawn in a 1:3 range, so no two vertices nearly coincide), scaled to a
    diameter of ``size``. Among the edges over which the centroid projects with a margin of
    ``STABILITY_MARGIN`` (at least one, the edge nearest the centroid, always holds the
    polygon), one is drawn and turned down onto the support.

    Args:
        rng: the random generator.
        vertices: inclusive range of the vertex count (>= 3).
        size: range of the diameter (largest vertex-to-vertex distance).
        aspect: range of the aspect ratio of the ellipse (>= 1).

    Returns:
        Vertices ``(n, 2)`` in the world, counter-clockwise, edge 0 (``v_0 -> v_1``) on the
        support (both at ``y = 0`` exactly), centroid at ``x = 0``.
    """
    n = int(rng.integers(vertices[0], vertices[1] + 1))
    gaps = rng.uniform(1.0, 3.0, n)
    angles = rng.uniform(0.0, 2 * math.pi) + 2 * math.pi * np.cumsum(gaps) / gaps.sum()
    ratio = rng.uniform(aspect[0], aspect[1])
    # the C library's cosine and sine, one angle at a time: numpy's array versions, chosen by
    # the processor's instruction sets, may differ in the last bit, and the shapes must not
    v = np.array([(math.cos(a), ratio * math.sin(a)) for a in angles.tolist()])
    c = geo.polygon_centroid(v)
    d = geo.edge_vectors(v)
    length = geo.norms(d)
    t = ((c - v) * d).sum(axis=1) / length**2  # centroid's projection along each edge
    margin = np.minimum(t, 1.0 - t)
    stable = np.flatnonzero(margin >= STABILITY_MARGIN)
    if len(stable) == 0:
        dist = np.abs(geo.cross2(d, c - v)) / length
        k = int(np.argmin(dist))
    else:
        k = int(rng.choice(stable))
    # Turn edge k's outward normal to (0, -1) and make its start vertex 0.
    normal = geo.edge_normals(v)[k]
    v = geo.rotate(v, -0.5 * math.pi - math.atan2(normal[1], normal[0]))
    v = np.roll(v, -k, axis=0)
    v = v - np.array([geo.polygon_centroid(v)[0], v[0, 1]])
    diameter = float(geo.norms(v[:, None] - v[None]).max())
    v = v * (rng.uniform(size[0], size[1]) / diameter)
    v[:2, 1] = 0.0
    return v


def hand_setup(scene: Scene, object_vertices_W: np.ndarray | None = None) -> np.ndarray:
    """The paper's pre-liftoff hand placement for a scene's object at its scene placement:
    :func:`grasp_env.planning.centred_hand` at the paper's palm height.

    Args:
        scene: the scene (its hand and, unless given, its object).
        object_vertices_W: the object's vertices ``(n, 2)`` in the world; default the scene's.

    Returns:
        Hand configuration ``(x_p, y_p, theta_p, q1, q2)``, shape (5,).
    """
    return centred_hand(scene, object_vertices_W=object_vertices_W)


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """A scene as a dict in the scene schema of docs/conventions.md (``load_scene`` of it gives
    it back)."""

    def finger(f) -> dict[str, Any]:
        d = {
            "length": f.length,
            "thickness": f.thickness,
            "angle": f.angle,
            "limits": list(f.limits),
            "density": f.density,
        }
        if any(math.isfinite(x) for x in f.torque_limits):  # one-sided limits included
            d["torque_limits"] = list(f.torque_limits)
        return d

    return {
        "name": scene.name,
        "description": scene.description,
        "gravity": scene.gravity,
        "palm": {
            "width": scene.palm.width,
            "thickness": scene.palm.thickness,
            "pose": scene.palm.pose.tolist(),
            "density": scene.palm.density,
        },
        "fingers": [finger(f) for f in scene.fingers],
        "object": {"vertices": scene.object.vertices_W0.tolist(), "mass": scene.object.mass},
    }


def random_shape_scene(
    rng: np.random.Generator,
    base: Scene,
    ranges: dict[str, tuple[float, float]] | None = None,
    problem: Callable[[Scene], str | None] | None = None,
) -> Scene:
    """A random object (:func:`random_convex_polygon`, mass uniform in ``ranges["mass"]``) at
    ``base``'s object position, in the hand set-up of :func:`hand_setup`.

    ``ranges`` are relative to ``base``'s palm width ``w`` (sizes in ``w``, masses in
    ``w**2``), so the object keeps its size relative to the hand at every palm width: a base
    scene scaled by ``k`` gives, for the same generator state, the object scaled by ``k``.
    Shapes that overlap the hand there are skipped, and so are those for which ``problem``
    (if given) names one.

    Raises:
        ValueError: no shape out of ``MAX_SHAPE_TRIES`` fits the hand.
    """
    r = {**DEFAULT_SHAPE_RANGES, **(ranges or {})}
    d = scene_to_dict(base)
    x0 = float(base.object.start_pose[0])
    w = base.palm.width
    size = (r["size"][0] * w, r["size"][1] * w)
    mass_range = (r["mass"][0] * w * w, r["mass"][1] * w * w)
    last = None
    for _ in range(MAX_SHAPE_TRIES):
        v = random_convex_polygon(rng, r["vertices"], size, r["aspect"])
        v[:, 0] += x0
        mass = float(rng.uniform(*mass_range))
        h = hand_setup(base, v)
        d["name"] = f"{base.name}/random"
        d["description"] = f"random convex {len(v)}-gon in the hand set-up of {base.name}"
        d["palm"]["pose"] = h[:3].tolist()
        for k in range(2):
            d["fingers"][k]["angle"] = float(h[3 + k])
        d["object"] = {"vertices": v.tolist(), "mass": mass}
        try:
            scene = load_scene(d)
        except SceneError as exc:  # overlaps the hand: draw another
            last = exc
            continue
        last = problem(scene) if problem is not None else None
        if last is None:
            return scene
    raise ValueError(
        f"shape_randomizer {r!r}: no random shape out of {MAX_SHAPE_TRIES} fits the hand of "
        f"scene {base.name!r} (last: {last})"
    )


__all__ = [
    "DEFAULT_SHAPE_RANGES",
    "WIDE_SHAPE_RANGES",
    "hand_setup",
    "random_convex_polygon",
    "random_shape_scene",
    "scene_to_dict",
]
