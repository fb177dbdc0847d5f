"""An independent check of a simulated state: geometry and mechanics recomputed here from
the conventions of docs/conventions.md, sharing no code with the simulator (no
:mod:`grasp_env.core.geometry`, :mod:`grasp_env.core.kinematics`,
:mod:`grasp_env.mechanics.contacts` or :mod:`grasp_env.sim`), the LP through scipy's HiGHS. The
tests and the soak (``benchmarks/soak.py``) check every state they make with :func:`check_state`:

* no NaN or infinity in the poses or the contacts;
* no penetration deeper than ``contact_tol`` between the object and the support, the palm or
  a finger (separating-axis test), and no hand vertex below the support;
* every contact force ``>= 0``; every listed contact has a unit normal, ``|gap| <=
  contact_tol`` and the normal of an edge through its point; every touching vertex-body pair
  is listed;
* the object's equilibrium residual ``|sum c_i n_i + m g| (+ moment / size)`` below
  :data:`EQ_RTOL` times its weight (plus the rounding of its terms; contacts dependent to
  tolerance exert no force along their free directions, :func:`free_rows`), and no admissible
  descent: gravity lies in the cone of the contact wrenches, to :data:`EQ_RTOL` times the
  weight, once contacts dependent to tolerance are made exactly dependent
  (:func:`free_rows`, docs/conventions.md, *Mechanics notes*), unless every descent is
  blocked at second order by the contacts' curvature (:func:`wedged`, docs/simulator.md,
  *Wedged*), with forces then the closest to balancing the object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any

import numpy as np
from scipy.optimize import nnls

#: Equilibrium residual and distance of gravity from the contact wrenches' cone allowed, as a
#: fraction of the object's weight.
EQ_RTOL = 1e-7
#: Rounding of a sum of terms, relative to the size of the terms: forces that hold a wedge
#: grow as one over its angle, and their sum is only as exact as its largest term.
TERM_ROUNDING = 64 * np.finfo(float).eps
#: Slack for floating-point rounding on top of ``contact_tol``, as a fraction of the palm width.
ROUNDING = 1e-13
#: Largest deviation of a contact normal from a unit vector (and of a support normal from
#: ``(0, 1)``): normals are unit vectors to rounding.
NORMAL_TOL = 1e-12


# ---------------------------------------------------------------------------------------
# Independent geometry (docs/conventions.md, "Frames")
# ---------------------------------------------------------------------------------------


def rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def object_polygon_W(scene: Any, pose: np.ndarray) -> np.ndarray:
    """Object vertices (n, 2) in the world: ``vertices_B`` turned by theta, then shifted."""
    return scene.object.vertices_B @ rot(float(pose[2])).T + np.asarray(pose[:2], float)


def hand_polygons_W(scene: Any, hand: np.ndarray) -> dict[str, np.ndarray]:
    """World polygons (4, 2) of the palm and fingers for ``hand = (x, y, th, q1, q2)``, built
    from docs/conventions.md: palm ``[-w/2, w/2] x [0, t]`` in P; finger i from its joint
    ``J_i = (-+w/2, 0)`` to its tip ``J_i + L_i u_i``, thickness on the side away from the
    inward normal (``u_1`` turned by +pi/2, ``u_2`` by -pi/2)."""
    xp, yp, thp, q1, q2 = (float(v) for v in hand)
    R, o = rot(thp), np.array([xp, yp])
    w, tp = scene.palm.width, scene.palm.thickness
    out = {"palm": np.array([[-w / 2, 0.0], [w / 2, 0.0], [w / 2, tp], [-w / 2, tp]]) @ R.T + o}
    for i, (q, turn) in enumerate(((q1, 1.0), (q2, -1.0)), start=1):
        f = scene.fingers[i - 1]
        J = np.array([-w / 2 if i == 1 else w / 2, 0.0])
        u = np.array([math.cos(q), math.sin(q)])
        n = turn * np.array([-u[1], u[0]])
        T = J + f.length * u
        out[f"finger{i}"] = np.array([J, T, T - f.thickness * n, J - f.thickness * n]) @ R.T + o
    return out


def edges(poly: np.ndarray):
    """``(a, b, outward unit normal)`` of every edge of a convex polygon of either orientation."""
    area2 = sum(poly[k - 1, 0] * poly[k, 1] - poly[k, 0] * poly[k - 1, 1] for k in range(len(poly)))
    sign = 1.0 if area2 > 0 else -1.0
    for k in range(len(poly)):
        a, b = poly[k], poly[(k + 1) % len(poly)]
        d = b - a
        yield a, b, sign * np.array([d[1], -d[0]]) / math.hypot(d[0], d[1])


def sat_depth(a: np.ndarray, b: np.ndarray) -> float:
    """Penetration depth of two convex polygons (separating axis theorem); < 0 when apart."""
    depth = math.inf
    for poly in (a, b):
        for _, _, n in edges(poly):
            pa, pb = a @ n, b @ n
            depth = min(depth, min(pa.max(), pb.max()) - max(pa.min(), pb.min()))
    return depth


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    d = b - a
    t = min(1.0, max(0.0, float((p - a) @ d) / float(d @ d)))
    return float(np.linalg.norm(p - a - t * d))


def boundary_distances(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point (m, 2) to the boundary of a polygon (its closed edge chain)."""
    a = poly
    d = np.roll(poly, -1, axis=0) - poly
    rel = points[:, None, :] - a[None, :, :]  # (m, k, 2)
    t = np.clip((rel * d[None]).sum(-1) / (d * d).sum(-1)[None], 0.0, 1.0)
    return np.linalg.norm(rel - t[..., None] * d[None], axis=-1).min(axis=1)


def boundary_distance(p: np.ndarray, poly: np.ndarray) -> float:
    return float(boundary_distances(np.asarray(p, float)[None], poly)[0])


# ---------------------------------------------------------------------------------------
# Invariants of a state
# ---------------------------------------------------------------------------------------


@dataclass
class Check:
    """Figures of one state and the invariants it violates (empty: valid)."""

    penetration: float = -math.inf  # deepest overlap / palm width
    gap: float = 0.0  # worst |gap| of a listed contact / palm width
    residual: float = 0.0  # equilibrium residual / weight
    descent: float = 0.0  # minus gravity's distance from the wrenches' cone / weight
    min_force: float = math.inf
    wedged: bool = False  # held only at second order (:func:`wedged`)
    violations: list[str] = field(default_factory=list)


def _get(c: Any, name: str) -> Any:
    return c[name] if isinstance(c, dict) else getattr(c, name)


def check_state(
    scene: Any,
    object_pose: np.ndarray,
    hand: np.ndarray,
    contacts: list,
    tol: float,
    *,
    descent: bool = True,
) -> Check:
    """Check a state against geometry and mechanics computed here.

    Args:
        scene: the state's scene (its dimensions and the object's vertices in its frame).
        object_pose: object pose ``(x, y, theta)``, shape (3,).
        hand: hand configuration ``(x_p, y_p, theta_p, q1, q2)``, shape (5,).
        contacts: the listed contacts, :class:`grasp_env.Contact` or their ``as_dict()``.
        tol: the contact tolerance as a length (``contact_tol * palm width``).
        descent: also look for an admissible descent.
    """
    out = Check()
    object_pose = np.asarray(object_pose, float)
    hand = np.asarray(hand, float)
    if not (np.all(np.isfinite(object_pose)) and np.all(np.isfinite(hand))):
        out.violations.append(f"nan: object {object_pose.tolist()}, hand {hand.tolist()}")
        return out
    limit = tol + ROUNDING * scene.palm.width
    obj = object_polygon_W(scene, object_pose)
    bodies = hand_polygons_W(scene, hand)
    depths = _check_penetration(out, scene, obj, bodies, limit)
    P, N, C = _check_contacts(out, scene, obj, bodies, contacts, tol, limit)
    _check_listed(out, obj, bodies, depths, contacts, limit)
    if all(not v.startswith("nan") for v in out.violations):
        kinds = [_get(c, "kind") for c in contacts]
        _check_equilibrium(out, scene, object_pose[:2], P, N, C, kinds, descent, tol)
    return out


def _check_penetration(out: Check, scene: Any, obj, bodies: dict, limit: float) -> dict:
    """No overlap of the object with the support or a hand body, and no hand vertex below the
    support; returns each body's separating-axis depth."""
    w = scene.palm.width
    depth = -float(obj[:, 1].min())
    out.penetration = depth / w
    if depth > limit:
        out.violations.append(f"penetration: object {depth:.3e} below the support")
    depths = {}
    for name, poly in bodies.items():
        d = depths[name] = sat_depth(obj, poly)
        out.penetration = max(out.penetration, d / w)
        if d > limit:
            out.violations.append(f"penetration: object and {name} overlap by {d:.3e}")
        low = float(poly[:, 1].min())
        if low < -limit:
            out.violations.append(f"penetration: {name} vertex at y = {low:.3e} below the support")
    return depths


def _check_contacts(out: Check, scene: Any, obj, bodies: dict, contacts: list, tol, limit):
    """Every listed contact is real: finite, a non-negative force, a unit normal, the point on
    both boundaries and a vertex of the side its kind names, the normal that of an edge
    through the point, ``|gap| <= tol``. Returns the points, normals and forces."""
    bad = out.violations
    w = scene.palm.width
    P = np.zeros((len(contacts), 2))
    N = np.zeros((len(contacts), 2))
    C = np.zeros(len(contacts))
    for i, c in enumerate(contacts):
        body, kind = _get(c, "body"), _get(c, "kind")
        p = np.asarray(_get(c, "point"), float)
        n = np.asarray(_get(c, "normal"), float)
        f = float(_get(c, "force"))
        P[i], N[i], C[i] = p, n, f
        where = f"contact {body}/{kind} at {p.tolist()}"
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n)) and math.isfinite(f)):
            bad.append(f"nan: {where}: normal {n.tolist()}, force {f}")
            continue
        out.min_force = min(out.min_force, f)
        if f < 0.0:
            bad.append(f"force: {where}: negative force {f:.3e}")
        if abs(float(np.linalg.norm(n)) - 1.0) > NORMAL_TOL:
            bad.append(f"contact: {where}: normal {n.tolist()} is not a unit vector")
            continue
        if boundary_distance(p, obj) > limit:
            bad.append(f"contact: {where}: point off the object boundary")
        if body == "support":
            gap = float(p[1])
            if np.abs(n - (0.0, 1.0)).max() > NORMAL_TOL:
                bad.append(f"contact: {where}: support normal {n.tolist()}")
        elif body in bodies:
            gap = _hand_contact_gap(bad, where, obj, bodies[body], body, kind, p, n, limit)
            if gap is None:
                continue
        else:
            bad.append(f"contact: unknown body {body!r}")
            continue
        out.gap = max(out.gap, abs(gap) / w)
        if abs(gap) > limit:
            bad.append(f"contact: {where}: |gap| {abs(gap):.3e} > tol {tol:.1e}")
    return P, N, C


def _hand_contact_gap(bad: list, where: str, obj, poly, body: str, kind: str, p, n, limit):
    """The gap of a contact with a hand body, or None (and a violation) if it is not one:
    an edge contact is an object vertex on a hand edge whose outward normal is ``n``; a tip
    contact a hand vertex on an object edge whose inward normal is ``n``."""
    if boundary_distance(p, poly) > limit:
        bad.append(f"contact: {where}: point off the {body} boundary")
    vert, feature, sign = (obj, poly, 1.0) if kind == "edge" else (poly, obj, -1.0)
    v = vert[int(np.argmin(np.linalg.norm(vert - p, axis=1)))]
    if np.linalg.norm(v - p) > limit:
        bad.append(f"contact: {where}: point is not a vertex of the {kind} side")
    gaps = [
        float(m @ (v - a))
        for a, b, m in edges(feature)
        if np.abs(sign * m - n).max() < 1e-9 and segment_distance(p, a, b) <= limit
    ]
    if not gaps:
        bad.append(f"contact: {where}: normal {n.tolist()} is not an edge's normal there")
        return None
    return min(gaps, key=abs)


def _check_listed(out: Check, obj, bodies: dict, depths: dict, contacts: list, limit) -> None:
    """Every touching vertex-body pair is listed (a contact of that body at that point)."""

    def listed(body: str, p: np.ndarray) -> bool:
        return any(
            _get(c, "body") == body and np.abs(np.asarray(_get(c, "point")) - p).max() <= 4 * limit
            for c in contacts
        )

    bad = out.violations
    for p in obj:
        if p[1] <= limit and not listed("support", p):
            bad.append(f"unlisted: object vertex {p.tolist()} touches the support")
    for name, poly in bodies.items():
        if depths[name] < -2 * limit:
            continue  # apart: nothing touches
        for p, dist in zip(obj, boundary_distances(obj, poly), strict=True):
            if dist <= limit and not listed(name, p):
                bad.append(f"unlisted: object vertex {p.tolist()} touches the {name}")
        for p, dist in zip(poly, boundary_distances(poly, obj), strict=True):
            if dist <= limit and not listed(name, p):
                bad.append(f"unlisted: {name} vertex {p.tolist()} touches the object")


def dependences(V: np.ndarray, eta: float) -> list[tuple[np.ndarray, set[int]]]:
    """The dependences to tolerance of rows ``V`` (twists as ``(v_x, v_y, size omega)``),
    as ``(direction, rows)``: a pair of rows whose second singular value, or a triple whose
    third, is at most ``eta`` is dependent along that singular vector; sets whose vectors
    agree to 1e-6 rad share one dependence, whose direction is that of all their rows
    together."""

    def telling(rows: list[int]) -> tuple[float, np.ndarray]:
        k = min(len(rows), 3) - 1  # a pair's third singular value is always zero
        _, sv, vt = np.linalg.svd(V[rows])
        return sv[k], vt[k]

    groups: list[tuple[np.ndarray, set[int]]] = []
    for subset in [*combinations(range(len(V)), 2), *combinations(range(len(V)), 3)]:
        value, z = telling(list(subset))
        if value > eta:
            continue
        for w, rows in groups:
            if np.linalg.norm(np.cross(z, w)) <= 1e-6:
                rows.update(subset)
                break
        else:
            groups.append((z, set(subset)))
    return [(telling(sorted(rows))[1], rows) for _, rows in groups]


def free_rows(V: np.ndarray, eta: float) -> np.ndarray:
    """Rows ``V`` with the directions free to tolerance (:func:`dependences`) taken out:
    each row of a dependence is projected onto the complement of its dependences'
    directions."""
    groups = dependences(V, eta)
    out = V.copy()
    for i in range(len(V)):
        basis: list[np.ndarray] = []
        for z, rows in groups:
            if i not in rows:
                continue
            z = z - sum((z @ u) * u for u in basis)
            if np.linalg.norm(z) > 1e-6 and len(basis) < 2:
                basis.append(z / np.linalg.norm(z))
        for u in basis:
            out[i] -= (out[i] @ u) * u
    return out


def gap_hessians(P: np.ndarray, N: np.ndarray, kinds: list[str], com, size: float) -> np.ndarray:
    """Second derivatives (m, 3, 3) of the contacts' gaps in the pose ``(x, y, theta)``,
    in twists as displacements ``(v_x, v_y, size omega)`` and times ``size`` (unit-free).

    Edge contact (object vertex ``x + R(theta) a`` on a hand edge or the support, inward
    normal ``n`` fixed): ``phi = n . (x + R a - A)``, whose only second derivative is
    ``d2/dtheta2 = -n . R a``. Tip contact (hand vertex ``T`` on the object edge of outward
    normal ``R m`` through ``x + R e``; ``n = -R m``): ``phi = (R m) . (T - x) - m . e``, so
    ``d2/dx dtheta = -R' m = J n`` (``J`` the quarter turn) and ``d2/dtheta2 = -(R m) . (T -
    x) = n . (T - x)``."""
    H = np.zeros((len(P), 3, 3))
    for i, (p, n, kind) in enumerate(zip(P, N, kinds, strict=True)):
        r = p - com
        if kind == "tip":
            H[i, 0, 2] = H[i, 2, 0] = -n[1] / size
            H[i, 1, 2] = H[i, 2, 1] = n[0] / size
            H[i, 2, 2] = (n @ r) / size**2
        else:
            H[i, 2, 2] = -(n @ r) / size**2
    return H * size


def self_stresses(V: np.ndarray, groups: list, eta: float) -> list[np.ndarray]:
    """The non-negative self-stresses ``mu`` (``mu @ V = 0``, summing to 1) of pairs and
    triples of one dependence that are minimal (no dependent pair inside a triple); only
    these can block a first-order motion at second order (a self-stress spanning all three
    twist directions leaves no motion at all)."""
    out: list[np.ndarray] = []
    for _, rows in groups:
        for k in (2, 3):
            for sub in combinations(sorted(rows), k):
                A = V[list(sub)].T
                _, sv, vt = np.linalg.svd(A)
                if sv[-1] > eta * sv[0] or (k == 3 and sv[-2] <= eta * sv[0]):
                    continue
                mu = vt[-1] * np.sign(vt[-1].sum())
                if mu.min() <= eta * mu.max():
                    continue  # not a non-negative minimal self-stress
                full = np.zeros(len(V))
                full[list(sub)] = mu / mu.sum()
                if not any(np.array_equal(full, m) for m in out):
                    out.append(full)
    return out


def wedged(V: np.ndarray, groups: list, H: np.ndarray, eta: float, eps: float) -> bool:
    """Whether every first-order descent of rows ``V`` (free directions taken out) steeper
    than ``eps`` (``d`` unit, ``V d >= 0``, ``-d_y > eps``) is blocked at second order:
    some non-negative self-stress ``mu`` (:func:`self_stresses`) has ``mu . kappa(d) < -2
    eta`` (``kappa_i = d' H_i d``: over the object's size the gaps weighted by ``mu`` would
    close by more than the tolerance, so no second-order correction keeps them open).

    Every admissible ``d`` is tight on the self-stresses' rows, so ``d`` lies in their null
    space; in it the descents form a ray or an arc, on which the worst ``d`` is an end of
    the arc, an eigenvector of one ``mu``'s quadratic form or a direction where two of them
    are equal (numpy's eigendecomposition)."""
    stresses = self_stresses(V, groups, eta)
    if not stresses:
        return False
    rows = sorted({int(i) for mu in stresses for i in np.flatnonzero(mu)})
    _, sv, vt = np.linalg.svd(V[rows])
    basis = vt[int(np.sum(sv > eta * sv[0])) :]  # the null space of those rows
    others = V[[i for i in range(len(V)) if i not in rows]] @ basis.T
    down = -basis[:, 1]
    if len(basis) == 0:
        return True
    forms = [basis @ np.einsum("i,ijk->jk", mu, H) @ basis.T + 2 * eta * np.eye(len(basis))
             for mu in stresses]  # fmt: skip
    if len(basis) == 1:
        candidates = [np.array([1.0]), np.array([-1.0])]
    else:
        candidates = []
        for c in others[np.linalg.norm(others, axis=1) > eta]:
            candidates += [np.array([-c[1], c[0]]), np.array([c[1], -c[0]])]
        rho = float(np.linalg.norm(down))
        if rho > eps:  # where -d_y = eps on the circle
            u, t = down / rho, np.array([-down[1], down[0]]) / rho
            along = math.sqrt(1.0 - (eps / rho) ** 2)
            candidates += [eps / rho * u + along * t, eps / rho * u - along * t]
        for j, F in enumerate(forms):
            candidates += list(np.linalg.eigh(F)[1].T)
            for G in forms[j + 1 :]:
                lam, vec = np.linalg.eigh(F - G)
                if lam[0] * lam[1] < 0:  # isotropic directions of F - G
                    a, b = math.sqrt(-lam[0]), math.sqrt(lam[1])
                    candidates += [b * vec[:, 0] + a * vec[:, 1], b * vec[:, 0] - a * vec[:, 1]]
        candidates += [-c for c in candidates]
    for u in candidates:
        u = u / np.linalg.norm(u)
        if u @ down < eps - 1e-12 or np.any(others @ u < -1e-12):
            continue  # not a descent
        if min(u @ F @ u for F in forms) >= 0.0:
            return False  # not blocked
    return True


def _check_equilibrium(out: Check, scene: Any, com, P, N, C, kinds, descent: bool, tol) -> None:
    """``sum c_i n_i + m g = 0`` with the moment about the centre of mass, and (``descent``)
    no admissible descent: gravity within :data:`EQ_RTOL` of the cone of the contact
    wrenches (free directions taken out, :func:`free_rows`), by non-negative least squares
    in units of the weight. Its distance from the cone is minus the optimum of ``min g . v
    s.t. V v >= 0, |v| <= 1``, the steepest admissible descent. An object whose every
    descent is blocked at second order (:func:`wedged`) is held where it is by forces the
    first-order balance does not fix: its listed forces must be the closest to balancing it
    (the residual at most gravity's distance from the cone)."""
    bad = out.violations
    W = scene.object_weight
    size = float(np.linalg.norm(scene.object.vertices_B, axis=1).max())
    moments = np.array([cross(pi - com, ni) for pi, ni in zip(P, N, strict=True)])
    # the wrenches, with the directions free to tolerance taken out: dependent contacts
    # exert no force along them, and their forces balance the object without it
    raw = np.column_stack([N, moments / size]) if len(C) else np.zeros((0, 3))
    groups = dependences(raw, tol / size)
    V = free_rows(raw, tol / size)
    residual = C @ V - np.array([0.0, W, 0.0])
    out.residual = math.hypot(*residual) / W
    terms = float(C @ (1.0 + np.abs(moments) / size)) / W if len(C) else 0.0
    limit = EQ_RTOL + TERM_ROUNDING * terms
    if len(C):
        lam, dist = nnls(V.T, np.array([0.0, 1.0, 0.0]))
        allowed = EQ_RTOL + TERM_ROUNDING * float(lam @ np.linalg.norm(V, axis=1))
        if dist > allowed:
            H = gap_hessians(P, N, kinds, com, size)
            out.wedged = wedged(V, groups, H, tol / size, allowed)
        if out.wedged:
            limit += float(dist)
    if not out.residual <= limit:
        bad.append(f"equilibrium: residual {out.residual:.3e} x weight")
    if not descent:
        return
    if not len(C):
        bad.append("equilibrium: no contacts (nothing holds the object)")
        return
    out.descent = -float(dist)
    if dist > allowed and not out.wedged:
        way = np.array([0.0, -1.0, 0.0]) + V.T @ lam  # minus the residual: the way down
        bad.append(
            f"equilibrium: admissible descent: gravity {dist:.3e} W from the contacts' cone, "
            f"down along (vx, vy, size w) = {(way / np.linalg.norm(way)).tolist()}"
        )
