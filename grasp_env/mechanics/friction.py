"""How much friction a frictionless motion tolerates: the critical Coulomb coefficient.

With Coulomb friction ``mu`` at every contact (hand and support), the object can be held at
rest against a hand motion, and the position-controlled hand jams, exactly when some contact
forces inside the friction cones balance each other and resist that motion. The forces of
such a jam grow without bound as the hand presses on, so the object's weight drops out and
the test is homogeneous: at ``mu = tan(phi)`` the cone of contact ``i`` is spanned by its two
edges ``e = cos(phi) n_i +- sin(phi) t_i`` (``n_i`` into the object, ``t_i`` it turned by
+90 degrees), and the hand jams iff some ``y >= 0`` on the edges has::

    sum_j y_j (e_j, r_j x e_j) = 0          (the forces balance: no net wrench)
    sum_j y_j e_j . v_j > 0                 (they resist the hand: positive power)

with ``r_j`` the contact point from the centre of mass and ``v_j`` the velocity of the hand
body's material point at the contact (zero on the support). By Farkas' lemma this fails iff
some object twist ``u`` has ``e_j . (v_obj(p_j) - v_j) >= 0`` on every edge, i.e. every
contact's relative velocity lies in the cone's polar: that twist is how the object gets
out of the way. At ``mu = 0`` both edges are the normal and the test is the frictionless
simulator's jam (eqs. 19-21 infeasible). The cones grow with ``mu``, so the jams form an
interval ``[mu*, inf)`` and ``mu*`` follows by bisection on the cone's half-angle ``phi``.

Each test is the velocity LP's feasibility question on the ``2n`` edge rows, decided by the
compiled basis enumeration (:mod:`grasp_env.solvers.fastlp`: no BLAS, the same bits on
every machine) and, where rounding leaves it undecided, by HiGHS on the force side
(:func:`reference_jams`, also the tests' reference). Rows are scaled to be dimensionless
(moments over the radius of gyration, velocities over the fastest contact point's), so the
answer does not depend on the scene's units. The derivation and what the test does not cover
are in docs/friction.md.
"""

from __future__ import annotations

import math

import numpy as np

from grasp_env.arguments import number, real_vector
from grasp_env.core import kinematics as kin
from grasp_env.core.state import State, require_state
from grasp_env.errors import SolverError
from grasp_env.mechanics.closure import gyration_radius
from grasp_env.solvers import lp
from grasp_env.solvers.fastlp import FEAS_TOL, solve_velocity_lp

#: Largest coefficient :func:`critical_friction` resolves; a motion that no ``mu`` up to it
#: jams is reported ``inf`` (its cones are within 1e-6 rad of the half-plane).
MU_MAX = 1e6
#: Width in rad of the half-angle interval at which the bisection stops.
ANGLE_TOL = 1e-12

_NO_COST = np.zeros(3)


def edge_rows(
    state: State, hand_velocity
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The contacts' normal and tangent rows for the hand velocity ``hand_velocity``.

    Returns ``(N, T, xn, xt)``: rows ``(n_i, r_i x n_i / rho)`` and ``(t_i, r_i x t_i / rho)``
    (n, 3) and the hand points' velocities along them, ``n_i . v_i / s`` and ``t_i . v_i /
    s`` (n,), with ``rho`` the radius of gyration and ``s`` the largest contact-point speed.
    The edge rows at ``mu = tan(phi)`` are ``cos(phi) N +- sin(phi) T`` with right-hand sides
    ``cos(phi) xn +- sin(phi) xt``. None where the motion moves no contact point (nothing
    pushes on the object) or there is no contact.
    """
    require_state(state)
    dh = real_vector(hand_velocity, "hand_velocity", 5)
    points, normals, bodies = state.contact_arrays()
    return contact_edge_rows(
        state.scene, state.object_pose, state.hand, points, normals, bodies, dh
    )


def contact_edge_rows(scene, pose, hand, points, normals, bodies, dh):
    """:func:`edge_rows` from arrays: the object's pose (3,), the hand (5,), contact points
    and normals (n, 2), body indices (n,) and the hand velocity ``dh`` (5,)."""
    size = float(np.max(np.abs(dh)))
    if len(bodies) == 0 or size == 0.0:
        return None
    dh = dh / size  # only the direction matters; so no magnitude overflows
    velocities = np.array(
        [kin.point_velocity_W(scene, hand, dh, b, p) for b, p in zip(bodies, points, strict=True)]
    )
    speed = float(np.max(np.hypot(velocities[:, 0], velocities[:, 1])))
    if speed == 0.0:
        return None
    tangents = np.column_stack([-normals[:, 1], normals[:, 0]])
    rho = gyration_radius(scene)
    r = points - np.asarray(pose[:2], dtype=float)
    rows = []
    for d in (normals, tangents):
        moment = (r[:, 0] * d[:, 1] - r[:, 1] * d[:, 0]) / rho
        rows.append(np.column_stack([d, moment]))
    v = velocities / speed
    xn = normals[:, 0] * v[:, 0] + normals[:, 1] * v[:, 1]
    xt = tangents[:, 0] * v[:, 0] + tangents[:, 1] * v[:, 1]
    return rows[0], rows[1], xn, xt


def cone_edges(
    rows: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], mu: float
) -> tuple[np.ndarray, np.ndarray]:
    """The friction cones' edge rows (2n, 3) and right-hand sides (2n,) at ``mu``
    (:func:`edge_rows`); at ``mu = 0`` the normal rows alone."""
    N, T, xn, xt = rows
    if mu == 0.0:
        return N, xn
    c, s = 1.0 / math.hypot(1.0, mu), mu / math.hypot(1.0, mu)
    return np.vstack([c * N + s * T, c * N - s * T]), np.concatenate(
        [c * xn + s * xt, c * xn - s * xt]
    )


def reference_jams(E: np.ndarray, xi: np.ndarray) -> bool:
    """Whether forces on the edge rows ``E`` balance and resist the motion ``xi`` (HiGHS):
    ``max xi . y  s.t.  E^T y = 0, 1^T y = 1, y >= 0`` exceeds the velocity LP's Farkas
    tolerance, on unit rows as :mod:`grasp_env.solvers.fastlp` scales them."""
    size = np.linalg.norm(E, axis=1)
    E, xi = E / size[:, None], xi / size
    A_eq = np.vstack([E.T, np.ones(len(E))])
    b_eq = np.array([0.0, 0.0, 0.0, 1.0])
    res = lp.solve(-xi, A_eq=A_eq, b_eq=b_eq, bounds=(0, None))
    if res.status != "optimal":
        return False
    return -res.value > FEAS_TOL * float(np.max(np.abs(xi)))


def jams_on_rows(rows, mu: float) -> bool:
    """The jam test at ``mu`` on :func:`edge_rows`' rows (None: nothing to jam):
    compiled, HiGHS where undecided."""
    if rows is None:
        return False
    E, xi = cone_edges(rows, mu)
    try:
        return solve_velocity_lp(E, xi, _NO_COST).status == "infeasible"
    except SolverError:
        return reference_jams(E, xi)


def jams_with_friction(state: State, hand_velocity, mu: float) -> bool:
    """Whether Coulomb friction ``mu`` at every contact can hold the object at rest against
    the hand velocity ``hand_velocity`` (5 numbers in :attr:`State.hand`'s order), so that
    the hand jams: ``critical_friction(state, hand_velocity) <= mu`` decided by one test.

    Raises:
        TypeError: ``mu`` is not a real number.
        ValueError: ``mu`` outside ``[0, MU_MAX]`` or a malformed ``hand_velocity``.
    """
    mu = number(mu, "mu", 0.0, MU_MAX, lo_open=False)
    rows = edge_rows(state, hand_velocity)
    return jams_on_rows(rows, mu)


def critical_friction(state: State, hand_velocity) -> float:
    """The smallest Coulomb coefficient ``mu``, the same at every contact (hand and support),
    at which the contacts can hold the object at rest against the hand velocity
    ``hand_velocity`` (5 numbers in :attr:`State.hand`'s order: palm x, palm y, palm angle,
    finger 1, finger 2): a jam with friction. Below it the object cannot be held still and
    moves; at or above it the hand can jam.

    Returns ``0.0`` where the motion jams without friction, ``inf`` where no ``mu`` up to
    :data:`MU_MAX` jams it (no contact, a motion that moves no contact point, or one the
    object can always give way to), else ``tan(phi)`` for the least half-angle ``phi`` found
    to jam, to :data:`ANGLE_TOL` rad (relative accuracy about 1e-12 (1 + mu^2) / mu). The
    magnitude of ``hand_velocity`` does not matter, only its direction.
    """
    rows = edge_rows(state, hand_velocity)
    if not jams_on_rows(rows, MU_MAX):
        return math.inf
    if jams_on_rows(rows, 0.0):
        return 0.0
    low, high = 0.0, math.atan(MU_MAX)
    while high - low > ANGLE_TOL:
        mid = 0.5 * (low + high)
        if jams_on_rows(rows, math.tan(mid)):
            high = mid
        else:
            low = mid
    return math.tan(high)


__all__ = [
    "ANGLE_TOL",
    "MU_MAX",
    "cone_edges",
    "contact_edge_rows",
    "critical_friction",
    "edge_rows",
    "jams_on_rows",
    "jams_with_friction",
    "reference_jams",
]
