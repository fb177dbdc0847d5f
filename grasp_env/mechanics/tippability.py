"""Tippability regions of an object resting on the support (paper section 2.4, Figs. 4-6).

Statics behind the regions
--------------------------
The object rests on the support ``y = 0`` on its *supporting edge*, whose ends are the left
and right support contacts ``p_WL = (x_L, 0)`` and ``p_WR = (x_R, 0)``, ``x_L <= x_R``; the
support pushes up on them with forces ``c_L, c_R >= 0`` (vertical, frictionless). Gravity
``-m g e_y`` acts at the centroid ``x_G``, with ``x_L < x_G < x_R`` for an object at rest.
A frictionless finger touches the exposed perimeter at ``p_W`` and pushes with ``c n_W``,
``c >= 0``, where ``n_W`` is the unit contact normal pointing into the object.

*Right region* (Fig. 4). The other fingertip sits at the right support contact and balances
the finger's horizontal push; its force passes through ``p_WR``, so it has no moment about
``p_WR``, and it can only push with a negative x component, so the finger needs
``n_x > 0``. Moments about ``p_WR`` (counter-clockwise positive) give

    c_L (x_L - x_R) + m g (x_R - x_G) + c * m_R = 0,   m_R = (p_W - p_WR) x n_W,

so ``c_L = (m g (x_R - x_G) + c m_R) / (x_R - x_L)`` falls to zero at a finite ``c`` exactly
when ``m_R < 0``: the moment of the finger force about the right support contact is
clockwise, the sense of the left support force's moment. For ``n_x > 0`` this says the
finger's line of action passes *above* ``p_WR``. The object then starts to rotate clockwise
about the right support contact. (The right support force cannot vanish first: for an
exposed point with ``n_x > 0`` and ``m_R < 0`` the line cannot also pass below ``p_WL``,
because ``p_W`` is extreme in the direction ``-n_W`` while ``p_WR`` is not.)

*Left region* (the mirror image). The holding fingertip sits at ``p_WL``, the finger needs
``n_x < 0`` and ``m_L = (p_W - p_WL) x n_W > 0`` (counter-clockwise, the sense of the right
support force's moment about ``p_WL``): the line of action passes above ``p_WL``, and the
object starts to rotate counter-clockwise about the left support contact.

Both conditions are strict: a contact whose line of action passes exactly through the
support contact is *not* tippable (``c_L`` then does not depend on ``c``), nor is one with a
vertical normal (the paper considers only normals with a positive x component; on the
exposed perimeter of a convex object a vertical normal points down and never tips it).

Geometry of the regions
-----------------------
Vertices are numbered CCW; edge ``i`` runs from ``v_i`` to ``v_{i+1}`` and has the inward
unit normal ``n_i`` (``d_i`` rotated by +pi/2, normalised). The supporting edge and its
vertices are excluded (the support obstructs them). If the object rests on a single vertex,
both support contacts are that vertex and no edge is excluded.

* Edge subregion (the paper's rays ``R_p_i``, Fig. 5). On edge ``i`` the normal is ``n_i`` and
  ``m(t) = (v_i - p_WC) x n_i + t |d_i|`` grows linearly along the edge (``p_WC`` is the
  region's support contact). The right subregion is ``{t : m(t) < 0} = [0, t*)`` with ``t*``
  the foot of the perpendicular from ``p_WR`` on the edge line (the paper: "the part of the
  ith edge between the ray R_p_i and the ith vertex"), valid only if ``n_i,x > 0``. The left
  subregion is ``(t*, 1]`` (foot from ``p_WL``), valid only if ``n_i,x < 0``.
* Vertex subregion (the paper's rays ``R_v_i``, Fig. 6). A flat finger edge touching vertex
  ``i`` can have any normal in the cone swept counter-clockwise from ``n_{i-1}`` to ``n_i``.
  The subregion is the part of that cone with ``n_x > 0`` and ``(v_i - p_WR) x n < 0``
  (right), or ``n_x < 0`` and ``(v_i - p_WL) x n > 0`` (left): an arc of normal angles.

Relation to the paper's formulas. The paper writes the right vertex subregion in *finger
angles* ``phi = angle(n) + pi/2`` as ``beta_i - pi/2 < phi < gamma_i``, with ``beta_i`` the angle
of the ray from ``p_WR`` through ``v_i`` and ``gamma_i = atan2(y_i - y_{i+1}, x_i - x_{i+1})``
(finger flush with edge ``i``), requiring ``0 < gamma_i < pi``. In normal angles that is
``angle(v_i - p_WR) - pi < angle(n) <= angle(n_i)``, which is what this module computes, but the
module also intersects with the rest of the cone (``angle(n) >= angle(n_{i-1})``, the finger
flush with edge ``i - 1``) and with ``n_x > 0`` at the lower end. The paper's interval omits
both; they matter for a vertex whose cone starts below the ray bound, and for a vertex that
overhangs beyond the right support contact (there the paper's interval contains normals with
``n_x < 0``).

Open and closed ends (what :meth:`TippabilityRegion.contains` does with ``tol``): ends
where the line of action passes through the support contact, or ``n_x = 0``, are *open*;
they are moved inwards by ``tol``. Ends of a vertex interval that are a cone edge (the finger
flush with an object edge) are *closed*; they are widened by ``tol``. Edge subregions are
about edge-interior points only; a point within ``tol`` of a vertex is a vertex point.
"""

from __future__ import annotations

import math

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core.scene import Scene
from grasp_env.mechanics import tip_regions
from grasp_env.mechanics.tip_regions import *  # noqa: F403 (re-exported, see __all__)
from grasp_env.mechanics.tip_regions import (
    DEFAULT_TOL,
    EdgeSubregion,
    Side,
    TippabilityRegion,
    VertexSubregion,
    _inward_normals,
    _size,
    _tolerance,
)
from grasp_env.mechanics.width import object_vertices_W

#: The region records and tolerances of :mod:`grasp_env.mechanics.tip_regions` are re-exported.
__all__ = [*tip_regions.__all__, "support_contacts", "tippability_regions"]


def _wrap(angle: float) -> float:
    """Angle wrapped to ``(-pi, pi]``."""
    a = math.remainder(angle, 2.0 * math.pi)
    return math.pi if a == -math.pi else a


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def support_contacts(
    scene_or_vertices: Scene | np.ndarray, tol: float = DEFAULT_TOL
) -> tuple[tuple[int, ...], np.ndarray, np.ndarray]:
    """The vertices on the support and the left and right support contacts.

    The support line is taken at the lowest vertex height ``y_min`` (0 for an object resting
    on the support); vertices within ``tol`` times the object's size of it are on the support.

    Args:
        scene_or_vertices: a scene or an ``(n, 2)`` CCW convex polygon in the world frame.
        tol: relative height tolerance, in ``[0, MAX_TOL)``.

    Returns:
        ``(support, p_WL, p_WR)``: the support vertex indices (increasing; one or two), and
        the left and right support contacts, each shape (2,) (the same point when the object
        rests on a single vertex).
    """
    tol = _tolerance(tol)
    return _support(object_vertices_W(scene_or_vertices), tol)


def _support(v: np.ndarray, tol: float) -> tuple[tuple[int, ...], np.ndarray, np.ndarray]:
    low = np.flatnonzero(v[:, 1] <= v[:, 1].min() + tol * _size(v))
    i_L = low[np.argmin(v[low, 0])]
    i_R = low[np.argmax(v[low, 0])]
    return tuple(int(i) for i in low), v[i_L].copy(), v[i_R].copy()


def _arc_intersect(
    lo: float, hi: float, lo_closed: bool, hi_closed: bool, centre: float, tol: float
) -> tuple[float, float, bool, bool] | None:
    """Intersect the arc ``[lo, hi]`` (``hi - lo < pi``) with the open arc ``centre -+ pi/2``.

    Angles are relative to the cone start; the open arc is taken modulo 2 pi. An end within
    ``tol`` of the open arc's end is that end, open: which of two angles that agree to
    rounding is the larger is not a decision. Returns the intersection ``(lo, hi,
    lo_closed, hi_closed)`` or None when it is empty.
    """
    for shift in (-2.0 * math.pi, 0.0, 2.0 * math.pi):
        a, b = centre + shift - math.pi / 2, centre + shift + math.pi / 2
        new_lo, new_lo_closed = (lo, lo_closed) if lo > a + tol else (a, False)
        new_hi, new_hi_closed = (hi, hi_closed) if hi < b - tol else (b, False)
        if new_hi > new_lo:
            return new_lo, new_hi, new_lo_closed, new_hi_closed
    return None


def _region(v: np.ndarray, side: Side, tol: float) -> TippabilityRegion:
    support, p_WL, p_WR = _support(v, tol)
    sgn = 1.0 if side == "right" else -1.0
    p_WC = p_WR if side == "right" else p_WL
    n_edges = len(v)
    n_W = _inward_normals(v)
    d = geo.edge_vectors(v)
    length = np.hypot(d[:, 0], d[:, 1])
    tol_len = tol * _size(v)
    # Edges with both ends on the support (the supporting edge; one edge for a strictly
    # convex polygon, none when the object rests on a single vertex).
    supporting = {i for i in support if (i + 1) % n_edges in support}

    edges: list[EdgeSubregion] = []
    for i in range(n_edges):
        if i in supporting or sgn * n_W[i, 0] <= tol:
            continue
        # Moment of the unit force along n_i about p_WC: m(t) = m0 + t |d_i|, with the
        # region being sgn * m(t) < 0; t_star is the foot of the perpendicular from p_WC.
        m0 = float(geo.cross2(v[i] - p_WC, n_W[i]))
        t_star = -m0 / length[i]
        tol_t = tol_len / length[i]
        if abs(t_star) <= tol_t:
            t_star = 0.0
        elif abs(t_star - 1.0) <= tol_t:
            t_star = 1.0
        t0, t1 = (0.0, min(float(t_star), 1.0)) if sgn > 0 else (max(float(t_star), 0.0), 1.0)
        if t1 - t0 > tol_t:
            edges.append(
                EdgeSubregion(i, t0, t1, _frozen(v[i] + t0 * d[i]), _frozen(v[i] + t1 * d[i]))
            )

    vertices: list[VertexSubregion] = []
    for i in range(n_edges):
        if i in support:
            continue
        theta_in = math.atan2(n_W[i - 1, 1], n_W[i - 1, 0])  # cone start: flush with edge i-1
        cone = _wrap(math.atan2(n_W[i, 1], n_W[i, 0]) - theta_in)  # exterior angle, (0, pi)
        # Both conditions are half-planes n . w > 0 for a fixed w: the x-component sign
        # (w = sgn e_x) and the moment sign (sgn (v_i - p_WC) x n < 0 <=> n . w > 0 with
        # w = -sgn perp(v_i - p_WC)).
        r = v[i] - p_WC
        arc: tuple[float, float, bool, bool] | None = (0.0, cone, True, True)
        for w in ((sgn, 0.0), (sgn * r[1], -sgn * r[0])):
            if arc is None:
                break
            arc = _arc_intersect(*arc, centre=math.atan2(w[1], w[0]) - theta_in, tol=tol)
        if arc is None or arc[1] - arc[0] <= tol:
            continue
        lo, hi, lo_closed, hi_closed = arc
        a_min = _wrap(theta_in + lo)
        vertices.append(VertexSubregion(i, a_min, a_min + (hi - lo), lo_closed, hi_closed))

    return TippabilityRegion(
        side=side,
        edges=tuple(edges),
        vertices=tuple(vertices),
        contact_W=_frozen(p_WC),
        vertices_W=_frozen(v),
        support=support,
    )


def tippability_regions(
    scene_or_vertices: Scene | np.ndarray, tol: float = DEFAULT_TOL
) -> tuple[TippabilityRegion, TippabilityRegion]:
    """Left and right tippability regions of the object at rest (paper section 2.4).

    A finger contact in the right region, squeezed against a fingertip at the right support
    contact, drives the left support force to zero at a finite force (the object tips
    clockwise about the right support contact); the left region is the mirror image. If
    both are empty the object cannot be lifted quasi-statically without friction. The
    statics and the exact sets are in the module docstring.

    Args:
        scene_or_vertices: a :class:`~grasp_env.core.scene.Scene` (``scene.object.vertices_W0``
            is used) or an ``(n, 2)`` array of the object's CCW vertices in the world frame,
            resting on the support (its lowest vertices define the supporting edge).
        tol: lengths relative to the object's size and angles (radians) below which a
            subregion counts as empty or a vertex counts as on the support; a real number in
            ``[0, MAX_TOL)`` = ``[0, 0.01)``: larger ones would blur the regions away.

    Returns:
        ``(left, right)`` :class:`TippabilityRegion` objects.

    Raises:
        SceneError: a ``ValueError``: ``scene_or_vertices`` is not a valid polygon (see
            :func:`~grasp_env.mechanics.width.object_vertices_W`).
        ValueError: ``tol`` is NaN, negative or at least ``MAX_TOL``.
        TypeError: ``tol`` is not a real number (a bool, a string, None).
    """
    tol = _tolerance(tol)
    v = object_vertices_W(scene_or_vertices)
    return _region(v, "left", tol), _region(v, "right", tol)
