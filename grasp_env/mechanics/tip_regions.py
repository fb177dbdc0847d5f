"""The records of tippability regions (:class:`TippabilityRegion`, its edge and vertex
subregions) and whether a finger contact lies in one (:meth:`TippabilityRegion.contains`),
with the tolerance they share.

Apart from :mod:`grasp_env.mechanics.tippability`, which derives the regions of an object at
rest (the statics, the sets and their open and closed ends are in its docstring), so that the
planner and the analysis can hold and query regions without that derivation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from grasp_env.arguments import number, real_vector
from grasp_env.core import geometry as geo

__all__ = [
    "DEFAULT_TOL",
    "MAX_TOL",
    "EdgeSubregion",
    "TippabilityRegion",
    "VertexSubregion",
]

Side = Literal["left", "right"]

#: Default tolerance: lengths relative to the object's size, angles and normals absolute.
DEFAULT_TOL = 1e-9
#: Bound on ``tol`` (exclusive): a hundredth of the object's size, or 0.01 rad. Beyond it the
#: tolerance rather than the object decides the regions (at ``tol >= 1`` every vertex counts
#: as on the support and both regions are empty).
MAX_TOL = 1e-2


def _tolerance(tol: Any) -> float:
    """``tol`` as a float in ``[0, MAX_TOL)``: TypeError for a non-number (a bool too),
    ValueError for NaN or a value outside, each naming ``tol``."""
    return number(tol, "tol", 0.0, MAX_TOL, lo_open=False, hi_open=True)


def _vector2(value: Any, name: str) -> np.ndarray:
    """``value`` as 2 finite floats: a finite float array of shape (2,) as it is (the fast
    path of the planner's calls), anything else through :func:`real_vector`, which refuses
    malformed input with a ValueError naming ``name``."""
    if (
        type(value) is np.ndarray  # not a subclass: a masked array goes to real_vector
        and value.shape == (2,)
        and value.dtype.kind == "f"
        and math.isfinite(value[0])
        and math.isfinite(value[1])
    ):
        return value
    return real_vector(value, name, 2)


@dataclass(frozen=True)
class EdgeSubregion:
    """The part of object edge ``edge`` (from ``v_edge`` to ``v_{edge+1}``) in a region.

    Attributes:
        edge: edge index ``i`` (edge ``i`` runs from vertex ``i`` to vertex ``i + 1``, CCW).
        t_start: start parameter along ``v_i -> v_{i+1}``, in ``[0, 1]``.
        t_end: end parameter, ``t_start < t_end <= 1``. Edge-interior points with
            ``t_start < t < t_end`` are in the region; an end strictly inside ``(0, 1)`` is a
            point whose line of action passes through the support contact (open).
        start_W: the point at ``t_start``, shape (2,), world frame at the scene placement.
        end_W: the point at ``t_end``, shape (2,), world frame.
    """

    edge: int
    t_start: float
    t_end: float
    start_W: np.ndarray = field(compare=False)
    end_W: np.ndarray = field(compare=False)


@dataclass(frozen=True)
class VertexSubregion:
    """The contact normals at object vertex ``vertex`` that are in a region.

    The admissible normals are those of unit vectors ``n_W`` (into the object) whose angle
    ``atan2(n_y, n_x)``, measured CCW from +x, lies on the CCW arc from ``angle_min`` to
    ``angle_max``.

    Attributes:
        vertex: vertex index.
        angle_min: start of the arc, radians, in ``(-pi, pi]``.
        angle_max: end of the arc, ``angle_min < angle_max < angle_min + pi`` (it may exceed
            ``pi`` when the arc crosses the -x direction, as left-region arcs can).
        min_closed: whether ``angle_min`` belongs to the set (True when it is the normal of
            the adjacent edge ``vertex - 1``, i.e. a finger flush with that edge).
        max_closed: whether ``angle_max`` belongs to the set (True when it is the normal of
            edge ``vertex``).
    """

    vertex: int
    angle_min: float
    angle_max: float
    min_closed: bool = True
    max_closed: bool = True


@dataclass(frozen=True)
class TippabilityRegion:
    """The left or right tippability region of an object at rest (paper section 2.4).

    Attributes:
        side: ``"right"`` (contacts that unload the left support contact, normals with
            positive x component, Fig. 4) or ``"left"`` (the mirror image).
        edges: edge subregions, by increasing edge index; edges not listed are empty.
        vertices: vertex subregions, by increasing vertex index.
        contact_W: the support contact the region refers to, shape (2,): the right support
            contact for the right region (where the holding fingertip goes and about which
            the object tips), the left one for the left region.
        vertices_W: the object's vertices at the scene placement, shape (n, 2), world frame.
        support: indices of the vertices on the support (one or two).
    """

    side: Side
    edges: tuple[EdgeSubregion, ...]
    vertices: tuple[VertexSubregion, ...]
    contact_W: np.ndarray = field(compare=False, repr=False)
    vertices_W: np.ndarray = field(compare=False, repr=False)
    support: tuple[int, ...] = ()

    @property
    def is_empty(self) -> bool:
        """True when no edge point and no vertex normal is in the region."""
        return not self.edges and not self.vertices

    def contains(self, point_W: np.ndarray, normal_W: np.ndarray, tol: float = DEFAULT_TOL) -> bool:
        """Whether a finger contact at ``point_W`` with normal ``normal_W`` is in the region.

        Args:
            point_W: contact point on the object's perimeter at its scene placement, shape
                (2,), world frame. Points farther than ``tol`` times the object's size from
                the perimeter, and points on the supporting edge, give False.
            normal_W: contact normal into the object, shape (2,), world frame (normalised
                here). At an edge-interior point it must equal that edge's inward normal to
                within ``tol``; at a vertex (within ``tol`` times the object's size) its angle
                must lie in the vertex's interval.
            tol: tolerance, in ``[0, MAX_TOL)``; open ends of the region shrink by it,
                closed ends grow by it (:mod:`grasp_env.mechanics.tippability`).

        Returns:
            True when the contact is in the region.

        Raises:
            ValueError: ``point_W`` or ``normal_W`` is not 2 real, finite numbers, or the
                normal is zero; ``tol`` is out of range (TypeError if not a number).
        """
        tol = _tolerance(tol)
        p_W = _vector2(point_W, "point_W")
        n_W = _vector2(normal_W, "normal_W")
        norm = float(np.hypot(n_W[0], n_W[1]))
        if not norm > 0.0:
            raise ValueError(f"normal_W must be a non-zero vector, got {normal_W!r}")
        n_W = n_W / norm
        v = self.vertices_W
        tol_len = tol * _size(v)

        dist_v = np.hypot(*(v - p_W).T)
        k = int(np.argmin(dist_v))
        if dist_v[k] <= tol_len:
            if k in self.support:
                return False
            phi = math.atan2(n_W[1], n_W[0])
            return any(s.vertex == k and _in_arc(phi, s, tol) for s in self.vertices)

        d = geo.edge_vectors(v)
        length = np.hypot(d[:, 0], d[:, 1])
        t = np.clip(np.sum((p_W - v) * d, axis=1) / length**2, 0.0, 1.0)
        gap = np.hypot(*(v + t[:, None] * d - p_W).T)
        i = int(np.argmin(gap))
        if gap[i] > tol_len:
            return False
        if np.hypot(*(n_W - _inward_normals(v)[i])) > tol:
            return False
        tol_t = tol_len / length[i]
        for s in self.edges:
            if s.edge != i:
                continue
            above = t[i] >= -tol_t if s.t_start <= 0.0 else t[i] > s.t_start + tol_t
            below = t[i] <= 1.0 + tol_t if s.t_end >= 1.0 else t[i] < s.t_end - tol_t
            return bool(above and below)
        return False


def _in_arc(phi: float, s: VertexSubregion, tol: float) -> bool:
    """Whether normal angle ``phi`` lies on the arc of ``s`` (open ends shrunk, closed grown)."""
    delta = math.remainder(phi - s.angle_min, 2.0 * math.pi)  # in [-pi, pi]
    width = s.angle_max - s.angle_min
    lo_ok = delta >= -tol if s.min_closed else delta > tol
    hi_ok = delta <= width + tol if s.max_closed else delta < width - tol
    return lo_ok and hi_ok


def _size(vertices_W: np.ndarray) -> float:
    return float(np.ptp(vertices_W, axis=0).max())


def _inward_normals(vertices_W: np.ndarray) -> np.ndarray:
    """Inward unit normals ``n_i`` of the edges ``v_i -> v_{i+1}``, shape (n, 2)."""
    return -geo.edge_normals(vertices_W)
