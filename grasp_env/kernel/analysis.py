"""The analysis of a state the env reports at every step, compiled: form closure and the grip
objective ``y*`` of the contacts, from arrays.

:func:`grasp_env.is_form_closure` and :func:`grasp_env.grip_objective` use these functions
too (the public API and the env compute the same bits); the grip LP's reference solver
(HiGHS), for the rare answers that fail their checks, stays in Python
(:mod:`grasp_env.mechanics.closure`).

Notation as in :mod:`grasp_env.mechanics.closure`: contact points ``P`` and normals ``N``
(into the object) in the world, ``V_ob`` rows ``[n_i, r_i x n_i]`` about the centre of mass.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim.pose import constraint_matrix
from grasp_env.solvers import simplex, velocity_lp

#: Absolute tolerance of the grip LP, whose data are in units of the weight and palm width.
GRIP_LP_TOL = 1e-10
#: Largest constraint residual of an accepted fast grip LP answer (else HiGHS solves it).
GRIP_CHECK_TOL = 1e-9
#: Outcomes of :func:`grip_objective`: ``y*`` found, no grip holds the object (``inf``), the
#: fast answer failed its checks (the reference solver decides).
GRIP_FOUND, GRIP_NONE, GRIP_UNDECIDED = 0, 1, 2

#: Entries of the grip constants of a scene (:func:`grip_constants`): each finger's centroid
#: in its link frame ``(x, y)`` (0-3), its weight ``m_k g`` (4-5), its torque limits (min 6-7,
#: max 8-9).
GRIP_CONSTANTS = 10


def grip_constants(scene) -> np.ndarray:
    """The finger data of ``scene`` the grip LP needs, as one array (:data:`CENTROID` ...):
    the centroid of each finger rectangle in its link frame (where its weight acts,
    docs/conventions.md, "Bodies and masses"), ``m_k g`` and the joint torque limits."""
    out = np.empty(GRIP_CONSTANTS)
    for k, f in enumerate(scene.fingers):
        out[2 * k : 2 * k + 2] = f.polygon_local(k + 1).mean(axis=0)
        out[4 + k] = f.mass * scene.gravity
        out[6 + k], out[8 + k] = f.torque_limits
    return out


@njit(cache=CACHE)
def form_closure(P: np.ndarray, N: np.ndarray, com: np.ndarray, rho: float) -> bool:
    """Form closure (section 2.5) of contacts at points ``P`` with normals ``N``: ``V_ob dq >=
    0`` only for ``dq = 0``, decided exactly on the rows scaled by the radius of gyration
    ``rho`` (:func:`grasp_env.solvers.velocity_lp.form_closure`)."""
    V = constraint_matrix(P, N, com)
    scale = 1.0 / rho
    for i in range(V.shape[0]):
        V[i, 2] *= scale
    return velocity_lp.form_closure(V)


@njit(cache=CACHE)
def _finger_rows(P, N, bodies, hand, half, length):
    """``W_F / L`` (2, m) of eq. 16: the moment about finger k's joint of a unit contact force
    on the finger (``-n_i`` at ``p_i``), per palm width ``length``."""
    c, s = math.cos(hand[2]), math.sin(hand[2])
    joints = ((hand[0] - c * half, hand[1] - s * half), (hand[0] + c * half, hand[1] + s * half))
    out = np.zeros((2, P.shape[0]))
    for i in range(P.shape[0]):
        b = bodies[i]
        if b == 2 or b == 3:
            jx, jy = joints[b - 2]
            rx, ry = P[i, 0] - jx, P[i, 1] - jy
            out[b - 2, i] = -(rx * N[i, 1] - ry * N[i, 0]) / length
    return out


@njit(cache=CACHE)
def _finger_gravity(hand, constants, weight, length):
    """``s / (W L)`` of eq. 17: minus the moment of each finger's weight about its joint."""
    out = np.empty(2)
    for k in range(2):
        phi = hand[2] + hand[3 + k]
        x, y = constants[2 * k], constants[2 * k + 1]
        out[k] = constants[4 + k] * (math.cos(phi) * x - math.sin(phi) * y) / (weight * length)
    return out


@njit(cache=CACHE)
def grip_objective(
    P: np.ndarray, N: np.ndarray, bodies: np.ndarray, com: np.ndarray, hand: np.ndarray,
    half: float, length: float, weight: float, constants: np.ndarray,
) -> tuple[int, float]:  # fmt: skip
    """``(outcome, y*)`` of eqs. 31-36 for contacts on ``bodies`` (0 support, 1 palm, 2-3 the
    fingers): the least total contact force holding the object, each finger balanced by a
    joint torque within its limits (``constants``, :func:`grip_constants`).

    Solved directly in the forces ``c`` with ``tau = s - W_F c`` substituted, in units of the
    weight and the palm width, by the compiled simplex method; an answer that is not optimal
    or fails its checks (the constraints to :data:`GRIP_CHECK_TOL`, the optimum at least its
    lower bound ``W / max |n_i|``, the force rows summing unit normals) is
    :data:`GRIP_UNDECIDED`, for the reference solver. ``y*`` is ``inf`` where nothing holds
    the object: :data:`GRIP_NONE`."""
    m = P.shape[0]
    if m == 0:
        return GRIP_NONE, np.inf
    WF = _finger_rows(P, N, bodies, hand, half, length)
    s = _finger_gravity(hand, constants, weight, length)
    scale = weight * length
    # tau_min <= s - W_F c <= tau_max  <=>  -W_F c <= tau_max - s  and  W_F c <= s - tau_min
    A_ub = np.empty((4, m))
    b_ub = np.empty(4)
    rows = 0
    for k in range(2):
        tmax = constants[8 + k] / scale
        tmin = constants[6 + k] / scale
        if math.isfinite(tmax):
            for i in range(m):
                A_ub[rows, i] = -WF[k, i]
            b_ub[rows] = tmax - s[k]
            rows += 1
        if math.isfinite(tmin):
            for i in range(m):
                A_ub[rows, i] = WF[k, i]
            b_ub[rows] = s[k] - tmin
            rows += 1
    A_ub, b_ub = A_ub[:rows].copy(), b_ub[:rows].copy()
    A_eq = constraint_matrix(P, N, com).T.copy()
    for i in range(m):
        A_eq[2, i] /= length
    unit = np.array([0.0, 1.0, 0.0])
    # |sum c_i n_i| = 1 (in units of W) bounds the optimum below, whatever the solver
    most = 0.0
    for i in range(m):
        most = max(most, math.sqrt(N[i, 0] * N[i, 0] + N[i, 1] * N[i, 1]))
    bound = 1.0 / most
    status, x, value = simplex.solve(np.ones(m), A_eq, unit, A_ub, b_ub, GRIP_LP_TOL)
    if status != simplex.OPTIMAL or not _grip_checks(A_eq, unit, A_ub, b_ub, x, value, bound):
        return GRIP_UNDECIDED, np.nan
    # within the LP's tolerance of the bound: rounding, clamped to it
    return GRIP_FOUND, weight * max(value, bound)


@njit(cache=CACHE)
def _grip_checks(A_eq, b_eq, A_ub, b_ub, x, value: float, bound: float) -> bool:
    """Whether a grip LP answer satisfies its constraints to :data:`GRIP_CHECK_TOL` and
    respects the lower bound on the optimum."""
    for r in range(A_eq.shape[0]):
        total = 0.0
        for i in range(x.shape[0]):
            total += A_eq[r, i] * x[i]
        if abs(total - b_eq[r]) > GRIP_CHECK_TOL:
            return False
    for r in range(A_ub.shape[0]):
        total = 0.0
        for i in range(x.shape[0]):
            total += A_ub[r, i] * x[i]
        if total - b_ub[r] > GRIP_CHECK_TOL:
            return False
    return value >= bound * (1.0 - 1e-6)
