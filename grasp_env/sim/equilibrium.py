"""Whether contacts hold the object against gravity, and with which forces.

Forces are in units of the object's weight ``W`` and moments in ``W`` times the palm width
(``model.per_length``), so that every tolerance here is unit-free.

Contacts dependent to tolerance (:mod:`grasp_env.sim.dependence`) exert no force along
their free directions: the object is held only if gravity has no component along one. No
bound on the forces decides whether the object is held.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.sim import contact_sets
from grasp_env.sim.curvature import wedged
from grasp_env.sim.dependence import free_rows
from grasp_env.sim.motion import motion_lp
from grasp_env.sim.placement import contact_rows
from grasp_env.sim.pose import constraint_matrix, independent_forces
from grasp_env.solvers import dense
from grasp_env.solvers.velocity_lp import OPTIMAL

#: Residual of an equilibrium that is rounding, relative to the size of the forces' terms
#: (``|V^T| lam``): at a fold the forces that hold the object grow without bound, and their
#: rounding alone leaves a residual above any fixed tolerance.
ROUNDING = 16.0 * dense.EPS


@njit(cache=CACHE)
def wrench_rows(model, world: np.ndarray, com: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """``V_ob`` (m, 3) of the contacts ``keys``, free directions taken out
    (:func:`grasp_env.sim.dependence.free_rows`), with moments per palm width."""
    P, N, _, _, _ = contact_rows(world, model.n_object, model.n_vertices, keys)
    return free_rows(model, constraint_matrix(P, N, com)) * model.per_length


@njit(cache=CACHE)
def held(
    model, world: np.ndarray, com: np.ndarray, keys: np.ndarray, ftol: float, rounding: float
) -> bool:
    """True when the contacts ``keys`` hold the object against gravity: non-negative forces
    balance it to ``ftol`` plus ``rounding`` times the size of their terms (0, or
    :data:`ROUNDING` for a state the hand stops at, whose forces may be large), with the
    directions free to tolerance taken out (:func:`~grasp_env.sim.dependence.free_rows`:
    gravity along one is not balanced). At a vertex-vertex touch the object may move along
    either candidate's edge: it is held only if every choice of candidates holds it."""
    if keys.shape[0] == 0:
        return False
    for choice in contact_sets.choices(model, world, keys):
        if not _balanced(model, world, com, choice, ftol, rounding)[0]:
            return False
    return True


@njit(cache=CACHE)
def held_or_wedged(
    model, world: np.ndarray, com: np.ndarray, keys: np.ndarray, ftol: float, rounding: float
) -> bool:
    """:func:`held`, or every way down left is blocked at second order
    (:func:`grasp_env.sim.curvature.wedged`): the object stays where the hand keeps it."""
    if keys.shape[0] == 0:
        return False
    for choice in contact_sets.choices(model, world, keys):
        ok, bound = _balanced(model, world, com, choice, ftol, rounding)
        if not ok and not wedged(model, world, com, choice, bound / model.weight):
            return False
    return True


@njit(cache=CACHE)
def _balanced(model, world, com, keys, ftol: float, rounding: float) -> tuple[bool, float]:
    """Whether non-negative forces of ``keys`` balance the object to ``ftol`` plus
    ``rounding`` times the size of their terms, and that bound."""
    W = wrench_rows(model, world, com, keys).T.copy()
    lam, res = dense.nnls(W, model.gravity)
    bound = ftol + rounding * _term_size(W, lam)
    return res <= bound, bound


@njit(cache=CACHE)
def _term_size(W: np.ndarray, lam: np.ndarray) -> float:
    """``| |W| lam |``: the size of the terms summed in ``W lam``, which sets its rounding."""
    total = 0.0
    for i in range(W.shape[0]):
        row = 0.0
        for j in range(W.shape[1]):
            row += abs(W[i, j]) * lam[j]
        total += row * row
    return math.sqrt(total)


@njit(cache=CACHE)
def rest_forces(model, world: np.ndarray, com: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """Contact forces holding the object once the hand stops: the least total force in
    equilibrium (a position-controlled hand adds no preload, section 3.2)."""
    m = keys.shape[0]
    if m == 0:
        return np.zeros(0)
    V = wrench_rows(model, world, com, keys)
    g = model.gravity
    W = V.T.copy()
    if m <= 3:
        # independent wrenches: the only forces in equilibrium, if non-negative
        lam, ok = independent_forces(W, g)
        if ok and lam.min() >= 0.0 and np.abs(dense.matvec(W, lam) - g).max() <= model.ftol:
            return lam
    # min 1^T lam s.t. V^T lam = (0, W, 0), lam >= 0: the force LP with xi = -1, solved
    # through its primal (min W v_y s.t. V v >= -1) by the same motion LP as the steps.
    status, _, lam, _ = motion_lp(model, V, -np.ones(m))
    if status != OPTIMAL:
        lam, res = dense.nnls(W, g)
        if res <= model.ftol:
            return lam  # held only to within the fall's tolerance: the closest forces
        # wedged (the rest is carried by the contacts' curvature): the closest forces in the
        # wrenches of displacements d = (v_x, v_y, size omega), as the wedge is measured
        Wd = W.copy()
        for j in range(m):
            Wd[2, j] *= model.length / model.size
        return dense.nnls(Wd, g)[0]
    return np.maximum(lam, 0.0)


@njit(cache=CACHE)
def determined(model, world: np.ndarray, q: np.ndarray, E: np.ndarray) -> bool:
    """True when ``E`` cannot change before an event: three independent contacts holding the
    object with forces all clearly positive, or the object resting on the support."""
    if contact_sets.all_on_support(E):
        return True  # resting on the support: only a new contact changes that
    if E.shape[0] != 3:
        return False
    P, N, _, _, _ = contact_rows(world, model.n_object, model.n_vertices, E)
    W = constraint_matrix(P, N, q[:2]).T.copy()
    Ws = W.copy()
    for k in range(3):
        for j in range(3):
            Ws[k, j] *= model.scale[k]
    volume, lam, ok = dense.det_and_solve(Ws, W, model.gravity)
    if abs(volume) < 1e-8:
        return False
    return ok and lam.min() > 1e-6 * model.weight
