"""Uncertain geometry: the object an episode simulates, drawn about the nominal object the
policy and the planner are told (the env's ``uncertainty``).

Each vertex of the nominal object at its scene placement moves by independent normal noise
of standard deviation ``sds["vertices"]`` palm widths in x and y, except that the vertices on
the support move along it only (their y is kept), so the object rests on the same edge; the
object is the convex hull of the moved vertices (a vertex the noise moves inside the others'
hull is dropped; where every moved vertex is on the hull the polygon keeps their order, its
first vertex the nominal first). The mass is scaled by ``1 + sds["mass"] * z`` with ``z``
standard normal. A draw is redrawn (up to :data:`MAX_PERTURBATION_TRIES` times) unless the
mass stays positive, the hull is a valid object clear of the hand (the scene's validation:
strictly convex, no vertex below the support, no edge too short), its centroid stays
strictly over its resting edge (so it rests there), and ``problem`` names nothing. Only the
components with a positive standard deviation draw from the generator.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from grasp_env.core.scene import Scene
from grasp_env.core.scene_loading import load_scene
from grasp_env.envs.shapes import scene_to_dict
from grasp_env.errors import SceneError

#: The perturbed quantities, in the order they draw: vertex positions (standard deviation
#: in palm widths) and mass (relative standard deviation).
UNCERTAINTY_KEYS = ("vertices", "mass")
#: Largest standard deviation of each quantity (a palm width; 100 % of the mass).
MAX_UNCERTAINTY = 1.0
#: Draws tried before giving up on a perturbation that keeps the object valid and at rest.
MAX_PERTURBATION_TRIES = 100
#: A vertex lies on the support when its y is at most this many palm widths.
SUPPORT_TOL = 1e-12


def hull(points: np.ndarray) -> np.ndarray | None:
    """The convex hull of ``points`` (shape (n, 2)) counter-clockwise from the point of
    lowest index on it, so that points already in convex counter-clockwise order come back
    as they are; None where the points span no area."""
    try:
        order = ConvexHull(points).vertices  # counter-clockwise in 2-D
    except QhullError:
        return None
    return points[np.roll(order, -int(np.argmin(order)))]


def perturbation_problem(scene: Scene) -> str | None:
    """Why a perturbed scene's object does not rest on the support: no edge on it, or its
    centroid not strictly over that edge (None if it rests)."""
    v = scene.object.vertices_W0
    x = v[v[:, 1] <= SUPPORT_TOL * scene.palm.width, 0]
    cx = float(scene.object.start_pose[0])
    if len(x) < 2 or not x.min() < cx < x.max():
        return f"its centroid x = {cx!r} is not over its resting edge (x in {x.tolist()})"
    return None


def perturbed_scene(
    rng: np.random.Generator,
    scene: Scene,
    sds: dict[str, float],
    problem: Callable[[Scene], str | None] | None = None,
) -> Scene:
    """``scene`` with its object perturbed as the module says, drawn from ``rng``; the hand,
    the name and everything else as in ``scene``.

    Raises:
        ValueError: no draw out of ``MAX_PERTURBATION_TRIES`` is valid (naming
            ``uncertainty``, the scene and the last reason).
    """
    w = scene.palm.width
    nominal = scene.object.vertices_W0
    resting = nominal[:, 1] <= SUPPORT_TOL * w
    d = scene_to_dict(scene)
    d["description"] = f"{scene.description} (perturbed)".lstrip()
    last = None
    for _ in range(MAX_PERTURBATION_TRIES):
        v, mass = nominal.copy(), scene.object.mass
        if sds["vertices"] > 0.0:
            noise = rng.normal(0.0, sds["vertices"] * w, nominal.shape)
            noise[resting, 1] = 0.0
            v = hull(v + noise)
            if v is None:
                last = "its vertices span no area"
                continue
        if sds["mass"] > 0.0:
            mass *= 1.0 + sds["mass"] * rng.standard_normal()
        if mass <= 0.0:
            last = f"mass {mass!r} is not positive"
            continue
        d["object"] = {"vertices": v.tolist(), "mass": mass}
        try:
            out = load_scene(d)
        except SceneError as exc:
            last = str(exc)
            continue
        last = perturbation_problem(out) or (problem(out) if problem else None)
        if last is None:
            return out
    raise ValueError(
        f"uncertainty {sds!r}: no perturbation out of {MAX_PERTURBATION_TRIES} of scene "
        f"{scene.name!r} keeps its object valid and at rest (last: {last})"
    )


__all__ = ["MAX_UNCERTAINTY", "UNCERTAINTY_KEYS", "perturbed_scene"]
