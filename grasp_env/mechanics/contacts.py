"""Contact geometry between the object and the support, palm and fingers: the world
geometry of a configuration, contact points, normals and gaps, detection and clearance
(the compiled kernels of :mod:`grasp_env.sim`, called from Python). Contacts are identified
by keys ``(body, kind, object_feature, hand_feature)`` (:mod:`grasp_env.core.state`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.scene import Scene
from grasp_env.core.state import EDGE, ContactKey
from grasp_env.sim import clearance, detection
from grasp_env.sim.placement import contact_rows, world_points


class Placement:
    """World geometry of every body for one object pose ``q`` and hand configuration ``h``.

    Computed once per configuration and shared by contact detection, gaps and Jacobians, so
    that the LP, Newton and event checks of one increment do no repeated work.

    Attributes:
        obj_W: object vertices in the world, shape (n, 2).
        obj_n_W: outward unit normals of the object edges, shape (n, 2).
        hand_W: world polygons of palm, finger 1, finger 2 (each (4, 2)).
        hand_n_W: their outward edge normals (each (4, 2)).
    """

    __slots__ = (
        "com_W", "h", "hand_W", "hand_n_W", "local", "obj_W", "obj_n_W", "q", "scene",
        "world",
    )  # fmt: skip

    def __init__(self, scene: Scene, q: np.ndarray, h: np.ndarray) -> None:
        self.scene, self.q, self.h = scene, q, h
        local = self.local = local_geometry(scene)
        m, n = local.n_vertices, local.n_object
        world = self.world = world_points(local.points, local.body, m, local.half, q, h)
        self.com_W = q[:2]
        self.obj_W, self.obj_n_W = world[:n], world[m : m + n]
        self.hand_W = world[n:m].reshape(3, 4, 2)
        self.hand_n_W = world[m + n :].reshape(3, 4, 2)

    def evaluate(self, key: ContactKey) -> tuple[np.ndarray, np.ndarray, float, float, float]:
        """Point (2,), normal into the object (2,), gap, edge parameter t and edge length.

        ``t`` is the position of the vertex's projection along the edge (0 at the edge's first
        vertex, 1 at its second); for the support it is 0.5 and the length infinite.
        """
        local = self.local
        P, N, F, T, L = contact_rows(
            self.world, local.n_object, local.n_vertices, np.array([key], dtype=np.int64)
        )
        return P[0], N[0], float(F[0]), float(T[0]), float(L[0])


class LocalGeometry:
    """Body-frame vertices, then outward edge normals, of the object and the three hand bodies
    stacked in one array, with each row's body (0 object, 1-3 hand), so that one rotation
    places them all (:func:`grasp_env.sim.placement.world_points`)."""

    __slots__ = ("body", "half", "n_object", "n_vertices", "points")

    def __init__(self, scene: Scene) -> None:
        polys = [scene.object.vertices_B, *kin.hand_polygons_local(scene)]
        body = np.repeat(np.arange(4), [len(p) for p in polys])
        self.points = np.ascontiguousarray(
            np.concatenate(polys + [geo.edge_normals(p) for p in polys]), dtype=float
        )
        self.body = np.concatenate((body, body)).astype(np.int64)
        self.n_object, self.n_vertices = len(polys[0]), len(body)
        self.half = float(scene.palm.width) / 2.0


@lru_cache(maxsize=64)
def local_geometry(scene: Scene) -> LocalGeometry:
    """The scene's stacked body-frame geometry (scenes hash by identity; the last 64 are
    kept, as :func:`grasp_env.core.kinematics.hand_polygons_local` keeps theirs)."""
    return LocalGeometry(scene)


def detect(pl: Placement, tol: float, exclude: set = frozenset()) -> list[ContactKey]:
    """Contacts at a placement: vertex-edge pairs with ``|gap| <= tol`` whose edge separates
    the bodies near the vertex, edge contacts first
    (:func:`grasp_env.sim.detection.detect` gives the rules).

    An edge lying along an edge yields its two end contacts. Coincident duplicates (the same
    point and normal seen as both an edge and a tip contact) keep the edge-kind one, unless
    it is in ``exclude`` (a contact the simulator has just released: its twin takes over).
    """
    local = pl.local
    ex = (
        np.array(list(exclude), dtype=np.int64).reshape(-1, 4)
        if exclude
        else np.zeros((0, 4), dtype=np.int64)
    )
    keys = detection.detect(pl.world, local.n_object, local.n_vertices, tol, ex)
    return [ContactKey(*k) for k in keys.tolist()]


def vertex_of(key: ContactKey) -> tuple[int, int, int]:
    """The (body, kind, vertex) a contact key pins: the object vertex of an edge contact or the
    hand vertex of a tip contact."""
    body, kind, object_feature, hand_feature = key
    return (body, kind, object_feature if kind == EDGE else hand_feature)


def min_gap(
    pl: Placement, exclude: set[tuple[int, int, int]] = frozenset(), bodies: list[int] | None = None
) -> tuple[float, ContactKey | None]:
    """Smallest vertex-in-body gap over every vertex not pinned by a contact in ``exclude``
    (:func:`vertex_of` triples of the active contacts), over ``bodies`` (default all).

    Returns ``(gap, key)`` of the worst pair (:func:`grasp_env.sim.clearance.min_gap`), or
    ``(inf, None)`` when there is none.
    """
    local = pl.local
    gap, key = clearance.min_gap(
        pl.world,
        local.n_object,
        local.n_vertices,
        np.array((0, 1, 2, 3) if bodies is None else bodies, dtype=np.int64),
        np.array(sorted(exclude), dtype=np.int64).reshape(-1, 3),
    )
    return float(gap), (None if key[0] < 0 else ContactKey(*(int(k) for k in key)))
