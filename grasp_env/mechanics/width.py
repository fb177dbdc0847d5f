"""Object width: the minimum distance between two parallel lines that enclose the object.

Section 3.2 of the paper (Fig. 12): if the object is in the hand and the distance ``d``
between the fingertips stays below the object's width ``w`` during a manipulation, the object
cannot be dropped (Toussaint 1984). For a convex polygon the minimum is attained with one of
the two parallel supporting lines flush with an edge (Toussaint's rotating calipers), so the
width is ``min over edges k of max over vertices j of dist(v_j, line of edge k)``. This module
evaluates that expression directly in ``O(n^2)``, which is faster than the ``O(n)`` caliper
walk for the polygons of this project (``n <= 20``) and has no bookkeeping to get wrong.

The helper :func:`object_vertices_W` turns a scene or a vertex array into a validated
``(n, 2)`` world polygon; :mod:`grasp_env.mechanics.tippability` uses it too.
"""

from __future__ import annotations

import numpy as np

from grasp_env.arguments import short
from grasp_env.core import geometry as geo
from grasp_env.core.scene import Scene
from grasp_env.core.scene_validation import convex_polygon
from grasp_env.errors import SceneError

__all__ = ["object_vertices_W", "object_width", "width_direction"]


def object_vertices_W(scene_or_vertices: Scene | np.ndarray) -> np.ndarray:
    """The object's world vertices at its scene placement, validated.

    Args:
        scene_or_vertices: a :class:`~grasp_env.core.scene.Scene` (its
            ``scene.object.vertices_W0`` is used) or an array-like of shape ``(n, 2)``,
            ``n >= 3``: the vertices of a strictly convex polygon, counter-clockwise, in the
            world frame W.

    Returns:
        A float64 array of shape ``(n, 2)`` (a copy).

    Raises:
        SceneError: a ``ValueError`` naming ``scene_or_vertices`` and showing the value: the
            polygon checks of a scene's ``object.vertices``
            (:func:`~grasp_env.core.scene_validation.convex_polygon`; real, finite coordinates,
            no repeated point, counter-clockwise, strictly convex, not a star).
    """
    if isinstance(scene_or_vertices, Scene):
        return np.array(scene_or_vertices.object.vertices_W0, dtype=float)
    if not isinstance(scene_or_vertices, list | tuple | np.ndarray):
        raise SceneError(
            "scene_or_vertices must be a grasp_env.Scene or a list of at least 3 [x, y] "
            f"points, got {short(scene_or_vertices)} (load a scene by name or path first: "
            "grasp_env.load_scene)"
        )
    return convex_polygon(scene_or_vertices, "scene_or_vertices")


def _min_width(vertices_W: np.ndarray) -> tuple[float, np.ndarray]:
    """Width and unit direction ``u_W`` (the inward normal of the flush edge), shape (2,)."""
    n_W = -geo.edge_normals(vertices_W)  # (n, 2) inward unit normals of the edges
    # depth[k, j]: distance of vertex j inside the line of edge k (>= 0 for a convex polygon).
    support = (vertices_W * n_W).sum(axis=1)  # each edge line's offset along its normal
    depth = (vertices_W[None, :, :] * n_W[:, None, :]).sum(-1) - support[:, None]
    extent = depth.max(axis=1)
    k = int(np.argmin(extent))
    return float(extent[k]), n_W[k].copy()


def object_width(scene_or_vertices: Scene | np.ndarray) -> float:
    """Minimum distance between two parallel lines enclosing the object (section 3.2, Fig. 12).

    Args:
        scene_or_vertices: a scene or an ``(n, 2)`` CCW convex polygon (see
            :func:`object_vertices_W`). The width does not depend on the pose.

    Returns:
        The width ``w > 0``, in the scene's length unit.
    """
    return _min_width(object_vertices_W(scene_or_vertices))[0]


def width_direction(scene_or_vertices: Scene | np.ndarray) -> np.ndarray:
    """Unit direction ``u_W``, shape (2,), world frame, along which the object is narrowest.

    The projections ``v_j . u_W`` of the vertices span exactly :func:`object_width`; ``u_W`` is
    the inward normal of an edge that is flush with one of the two width-defining lines (if
    several edges tie, the lowest edge index). Fingertips closer than the width along this
    direction cannot let the object through.
    """
    return _min_width(object_vertices_W(scene_or_vertices))[1]
