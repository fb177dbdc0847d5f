"""The paper's grasp mechanics (section 2): velocity constraints, equilibrium, LPs and closure.

Notation (paper -> code): contact normals ``o_Ci`` -> ``n_W`` (into the object); the object's
constraint matrix ``V_ob`` (eq. 9) has rows ``[n_i^T, r_i x n_i]`` with ``r_i`` the contact
point relative to the object's centre of mass; ``W_O = V_ob^T`` (eq. 14, moments about the
centre of mass, so the gravity wrench ``w`` of eq. 15 has no moment); ``W_F`` and ``s`` are
the finger rows of eq. 13 (eqs. 16-17) with moments about each finger's joint.

Object velocities are twists ``(vx, vy, omega)`` of the centre of mass; hand velocities are
``dh = (dx_p, dy_p, dtheta_p, dq1, dq2)``.
"""

from __future__ import annotations

import math

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.scene import Scene
from grasp_env.core.state import State, require_state
from grasp_env.errors import SolverError
from grasp_env.kernel import analysis
from grasp_env.sim.pose import constraint_matrix
from grasp_env.solvers import dense, lp


def V_ob(points_W: np.ndarray, normals_W: np.ndarray, com_W: np.ndarray) -> np.ndarray:
    """Object velocity-constraint matrix (eq. 9), shape (n, 3).

    Row i maps an object twist to the normal velocity of the object's material point at
    contact i: ``n_i . (v + omega k x r_i) = [n_i, r_i x n_i] . (v, omega)``.
    """
    return constraint_matrix(  # copies: the compiled function takes writeable arrays
        np.array(points_W, dtype=float).reshape(-1, 2),
        np.array(normals_W, dtype=float).reshape(-1, 2),
        np.array(com_W, dtype=float),
    )


def xi(
    scene: Scene,
    h: np.ndarray,
    dh: np.ndarray,
    bodies: np.ndarray,
    points_W: np.ndarray,
    normals_W: np.ndarray,
) -> np.ndarray:
    """Right-hand side of eq. 20: ``xi_i = n_i . v_hand(p_i)``, shape (n,).

    ``v_hand(p_i)`` is the velocity of the hand body's material point at contact i for hand
    velocity ``dh`` (eqs. 18, 20: ``xi = -[V_theta V_p] [dtheta; dq_p]``); zero on the support.
    """
    out = np.zeros(len(bodies))
    if len(bodies) == 0:
        return out
    poses = kin.body_poses_W(scene, h)
    tw = kin.body_twists_W(scene, h, dh)
    for i, b in enumerate(bodies):
        if b == geo.SUPPORT:
            continue
        r = points_W[i] - poses[b - 1, :2]
        t = tw[b - 1]
        out[i] = normals_W[i, 0] * (t[0] - t[2] * r[1]) + normals_W[i, 1] * (t[1] + t[2] * r[0])
    return out


def W_O(points_W: np.ndarray, normals_W: np.ndarray, com_W: np.ndarray) -> np.ndarray:
    """Object wrench matrix (eq. 14), shape (3, n): column i is the wrench of a unit force
    along ``n_i`` at ``p_i``, moments about the centre of mass (``= V_ob^T``)."""
    return V_ob(points_W, normals_W, com_W).T


#: ``w / W``: the gravity wrench in units of the object's weight.
_UNIT_GRAVITY = np.array([0.0, 1.0, 0.0])


def gravity_wrench(scene: Scene) -> np.ndarray:
    """``w`` of eq. 15 about the centre of mass: the wrench the contacts must supply, (3,)."""
    return np.array([0.0, scene.object_weight, 0.0])


def W_F(
    scene: Scene, h: np.ndarray, bodies: np.ndarray, points_W: np.ndarray, normals_W: np.ndarray
) -> np.ndarray:
    """Finger wrench matrix (eq. 16), shape (2, n).

    Entry (k, i) is the moment about finger k's joint of a unit contact force on the finger
    (``-n_i`` at ``p_i``) for contacts on finger k, else 0. Finger k is in equilibrium when
    ``(W_F c)_k + tau_k = s_k`` (eq. 13, bottom rows).
    """
    out = np.zeros((2, len(bodies)))
    poses = kin.body_poses_W(scene, h)
    for i, b in enumerate(bodies):
        if b in (geo.FINGER1, geo.FINGER2):
            r = points_W[i] - poses[b - 1, :2]
            out[b - 2, i] = -float(geo.cross2(r, normals_W[i]))
    return out


def finger_gravity_moments(scene: Scene, h: np.ndarray) -> np.ndarray:
    """``s`` of eq. 17, shape (2,): minus the moment of each finger's weight about its joint.

    The weight acts at the finger rectangle's centroid (docs/conventions.md, "Bodies and
    masses").
    """
    poses = kin.body_poses_W(scene, h)
    out = np.empty(2)
    for k in range(2):
        f = scene.fingers[k]
        c_local = f.polygon_local(k + 1).mean(axis=0)
        c_W = geo.rotate(c_local, poses[k + 1, 2])
        out[k] = f.mass * scene.gravity * c_W[0]  # -(r x (0, -m g)) = m g r_x
    return out


def _state_arrays(state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    require_state(state)
    p, n, b = state.contact_arrays()
    return p, n, b, V_ob(p, n, state.object_pose[:2])


def gyration_radius(scene: Scene) -> float:
    """Radius of gyration ``sqrt(I / m)`` of the object: the length that makes a rotation
    rate comparable with a translation rate in the mass metric."""
    return math.sqrt(scene.object.inertia / scene.object.mass)


def escape_direction(state: State) -> np.ndarray | None:
    """An object twist allowed by the contacts with the hand fixed, or None in form closure.

    Solves ``max 1^T V u  s.t.  V u >= 0, -1 <= u <= 1`` in scaled twists ``u = (vx, vy,
    rho omega)`` (``rho`` the radius of gyration). If ``V`` has rank < 3 a null-space twist
    escapes; otherwise ``V u >= 0`` has a nonzero solution iff the optimum is positive (section
    2.5: form closure iff ``V_ob dq >= 0`` admits only ``dq = 0``). The scaled rows
    ``[n_i, r_i x n_i / rho]`` are dimensionless, so the tolerances do not depend on the
    scene's units. Returned with unit norm in the scaled metric, as ``(vx, vy, omega)``.
    """
    _, _, _, V = _state_arrays(state)
    rho = gyration_radius(state.scene)
    Vs = V * np.array([1.0, 1.0, 1.0 / rho])
    if len(Vs) == 0 or dense.rank(Vs, 1e-10) < 3:
        u = dense.svd(np.vstack([Vs, np.zeros((1, 3))]))[2][:, -1]  # least singular vector
        return u * np.array([1.0, 1.0, 1.0 / rho])
    res = lp.solve(-Vs.sum(axis=0), A_ub=-Vs, b_ub=np.zeros(len(Vs)), bounds=(-1, 1))
    if res.status != "optimal" or -res.value <= 1e-9 * len(Vs):
        return None
    u = res.x / float(geo.norms(res.x))
    return u * np.array([1.0, 1.0, 1.0 / rho])


def is_form_closure(state: State) -> bool:
    """Form closure (section 2.5): with the hand fixed, ``V_ob dq >= 0`` only for ``dq = 0``.

    Decided exactly on the scaled rows ``[n_i, r_i x n_i / rho]`` (the rows positively span
    R^3) by :func:`grasp_env.kernel.analysis.form_closure`, which the env runs too;
    :func:`escape_direction` (HiGHS) gives the same answer and, when there is one, the twist
    that escapes.
    """
    require_state(state)
    points, normals, _ = state.contact_arrays()
    com = state.object_pose.copy()  # V_ob reads its x and y (a state's arrays are read-only)
    return analysis.form_closure(points, normals, com, gyration_radius(state.scene))


def _equilibrium_rows(V: np.ndarray, length: float) -> np.ndarray:
    """``W_O = V^T`` (3, n) in dimensionless units: the moment row divided by ``length``.

    With forces in units of the object's weight and moments in units of weight x ``length``
    the analysis LPs have data of order one whatever the scene's units, so HiGHS's absolute
    tolerances (1e-7) act as relative ones.
    """
    A = V.T.copy()
    A[2] /= length
    return A


def is_force_closure(state: State) -> bool:
    """Force closure (section 2.5): gravity is balanced by the contacts, ``W_O c = w, c >= 0``.

    Solved for ``c / weight`` with moments in units of weight x palm width (dimensionless).
    """
    _, _, _, V = _state_arrays(state)
    if len(V) == 0:
        return False  # nothing holds the object up
    A = _equilibrium_rows(V, state.scene.palm.width)
    res = lp.solve(np.zeros(len(V)), A_eq=A, b_eq=_UNIT_GRAVITY, bounds=(0, None))
    return res.status == "optimal"


def grip_objective(state: State) -> float:
    """Minimum total contact force ``y*`` of eqs. 31-36, ``inf`` if no grip holds the object.

    Solves, over contact forces ``c`` (all contacts, support and palm included, eq. 31) and
    joint torques ``tau``::

        min 1^T c   s.t.   W_O c = w                 (object equilibrium, eq. 13 top)
                           W_F c + tau = s           (finger moment balance, eq. 13 bottom)
                           tau_min <= tau <= tau_max (eqs. 35-36),  c >= 0 (eq. 34)

    as a direct LP in ``c`` with ``tau = s - W_F c`` substituted, by the compiled simplex
    method (:func:`grasp_env.kernel.analysis.grip_objective`, which the env runs too; the
    tests compare it with HiGHS and with the paper's null-space form, eqs. 29-33); an answer
    that is not optimal, or fails its checks, is decided again by HiGHS
    (:func:`grasp_env.solvers.lp.solve`). The LP is solved in units of the object's weight
    ``W`` (forces) and ``W`` x palm width (moments, torques), so its answer does not depend
    on the scene's units.

    Since the force rows of ``W_O c = w`` sum unit normals, ``y* >= |w| / max_i |n_i| = W``:
    a positive grip never reads as free.
    """
    p, n, b, _ = _state_arrays(state)
    scene = state.scene
    W, L = scene.object_weight, scene.palm.width
    outcome, value = analysis.grip_objective(
        p, n, b, state.object_pose.copy(), state.hand.copy(), L / 2.0, L, W,
        analysis.grip_constants(scene),
    )  # fmt: skip
    if outcome == analysis.GRIP_FOUND:
        return value
    if outcome == analysis.GRIP_NONE:
        return math.inf
    return reference_grip(state)


def reference_grip(state: State) -> float:
    """``y*`` of :func:`grip_objective` by HiGHS (:func:`grasp_env.solvers.lp.solve`), from
    :func:`W_F` and :func:`finger_gravity_moments`: the reference for near-degenerate
    contact sets (several contacts at one point), where the compiled simplex method can
    pivot on rounding and its answer fails its checks."""
    p, n, b, V = _state_arrays(state)
    scene = state.scene
    if len(n) == 0:
        return math.inf
    W, L = scene.object_weight, scene.palm.width
    WF = W_F(scene, state.hand, b, p, n) / L
    s = finger_gravity_moments(scene, state.hand) / (W * L)
    tmin = np.array([f.torque_limits[0] for f in scene.fingers]) / (W * L)
    tmax = np.array([f.torque_limits[1] for f in scene.fingers]) / (W * L)
    # tau_min <= s - W_F c <= tau_max  <=>  -W_F c <= tau_max - s  and  W_F c <= s - tau_min
    rows, rhs = [], []
    for k in range(2):
        if np.isfinite(tmax[k]):
            rows.append(-WF[k])
            rhs.append(tmax[k] - s[k])
        if np.isfinite(tmin[k]):
            rows.append(WF[k])
            rhs.append(s[k] - tmin[k])
    A_ub = np.array(rows).reshape(-1, len(n))
    b_ub = np.array(rhs, dtype=float)
    A_eq = _equilibrium_rows(V, L)
    bound = 1.0 / float(geo.norms(n).max())
    res = lp.solve(
        np.ones(len(n)), A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=_UNIT_GRAVITY, bounds=(0, None)
    )
    if res.status == "infeasible":
        return math.inf
    if res.status != "optimal":
        raise SolverError(f"grip LP: {res.status}", status=res.status)
    if res.value < bound * (1.0 - 1e-6):
        raise SolverError(
            f"grip LP optimum {res.value!r} W is below its lower bound {bound!r} W",
            status="inconsistent",
        )
    # Within the LP's tolerance of the bound: rounding, clamp to it.
    return W * max(res.value, bound)
