"""One env step, compiled: the hand target an action asks for, the simulator's move there, the
analysis of the state it reaches (form closure, ``y*``), the drop, the reward and the
observation.

An episode lives in a few arrays (the env's docstring defines what they mean):

* ``consts`` (:data:`CONSTS`): what the episode's scene fixes (:func:`episode_constants`);
* ``settings`` (:data:`SETTINGS`): the env's arguments (:func:`env_settings`);
* the state: object pose ``q`` (3), hand ``h`` (5), ``keys`` (the contacts, rows of
  :mod:`grasp_env.sim.placement`) and their ``rows`` (point, normal, gap, force,
  :mod:`grasp_env.sim.move`);
* ``an`` (:data:`ANALYSIS`): the analysis of the current state;
* ``ep`` (:data:`EPISODE`): what the episode has done so far (left the support, paid the
  grasp bonus, the lift potential, steps);
* ``obs``: the observation buffer, whose vertex block is set at reset and whose contact block
  holds the current contacts'.

:func:`step_env` advances them by one action and writes the observation, reward and info; it
returns a status other than :data:`OK` (and changes nothing of the episode) where Python must
take over: a move the compiled core could not finish (retried on the reference path by
:meth:`grasp_env.Simulator.move_arrays`), or a grip LP for the reference solver. Python then
finishes the step with the same :func:`finish_step` and :func:`conclude`, so every path
computes the same bits.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.kernel import analysis
from grasp_env.kernel.observation import (
    CONTACT_ENTRIES,
    GRIP_MAX,
    POSITION_ENTRIES,
    REACH,
    contact_positions,
    finish_observation,
    in_palm_frame,
)
from grasp_env.sim import move
from grasp_env.sim.proximity import hand_features

#: Statuses of :func:`step_env` (and of a batch whose buffers a state's contacts overflow).
OK, MOVE_FAILED, GRIP_UNDECIDED, TOO_MANY_CONTACTS = 0, 1, 2, 3

# ``consts``: the episode's scene and start.
K_FINGER_STEP = 0
K_PALM_LOW, K_PALM_HIGH, K_PALM_STEP = 1, 4, 7  # 3 entries each: x, y, theta
K_JOINT_LOW, K_JOINT_HIGH = 10, 12  # 2 entries each
K_X0, K_WIDTH, K_WEIGHT, K_Y0, K_RHO = 14, 15, 16, 17, 18
K_LENGTHS = 19  # palm width, finger 1 and finger 2 lengths
K_GRIP = 22  # analysis.GRIP_CONSTANTS entries
CONSTS = K_GRIP + analysis.GRIP_CONSTANTS

# ``settings``: the env's arguments.
S_PALM_CONTROL, S_ALWAYS_GRIP, S_HAND_FEATURES, S_GAMMA, S_MAX_STEPS = 0, 1, 2, 3, 4
S_CONTACTS_AT, S_HAND_AT = 5, 6  # where the contact and hand blocks start in the observation
S_WEIGHTS = 7  # reward weights, in REWARD_TERMS order
REWARD_TERMS = ("form_closure", "hold", "grip", "lift", "drop", "ctrl")
SETTINGS = S_WEIGHTS + len(REWARD_TERMS)

# ``an``: the analysis of the current state.
A_ON_SUPPORT, A_CLOSURE, A_GRIP, A_SUCCESS = 0, 1, 2, 3
ANALYSIS = 4

# ``ep``: the episode so far.
E_LEFT_SUPPORT, E_REWARDED, E_PHI, E_STEPS = 0, 1, 2, 3
EPISODE = 4

# ``info``: what a step reports besides observation and reward.
I_SUCCESS, I_CLOSURE, I_GRIP_FORCE, I_GRIP, I_JAMMED, I_BLOCKED, I_DROPPED = range(7)
I_JOINT_LIMIT, I_UNTOUCHED, I_TERMINATED, I_TRUNCATED, I_REWARD = 7, 8, 9, 10, 11
I_TERMS = 12  # the reward terms, in REWARD_TERMS order
INFO = I_TERMS + len(REWARD_TERMS)


@njit(cache=CACHE)
def target_of(consts, settings, h: np.ndarray, action: np.ndarray):
    """The hand target of an action (each entry clipped into [-1, 1]): the fingers close by
    ``action[:2]`` finger steps, the palm (with palm control) moves by ``action[2:]`` palm
    steps within its workspace, the fingers are clipped to their joint limits.
    ``(target, a, joint_limit)`` with the clipped action and whether a finger was clipped."""
    a = np.empty(action.shape[0])
    for i in range(action.shape[0]):
        a[i] = min(max(float(action[i]), -1.0), 1.0)
    target = h.copy()
    step = consts[K_FINGER_STEP]
    target[3] += step * a[0]  # both fingers close for a > 0
    target[4] -= step * a[1]
    if settings[S_PALM_CONTROL] != 0.0:
        for k in range(3):
            moved = target[k] + consts[K_PALM_STEP + k] * a[2 + k]
            target[k] = min(max(moved, consts[K_PALM_LOW + k]), consts[K_PALM_HIGH + k])
    f1, f2 = target[3], target[4]
    target[3] = min(max(f1, consts[K_JOINT_LOW]), consts[K_JOINT_HIGH])
    target[4] = min(max(f2, consts[K_JOINT_LOW + 1]), consts[K_JOINT_HIGH + 1])
    return target, a, target[3] != f1 or target[4] != f2


@njit(cache=CACHE)
def try_move(model, q, h, keys, target):
    """The simulator's move of the hand from ``h`` to ``target`` (:func:`grasp_env.sim.move.
    run`, the first attempt of :meth:`grasp_env.Simulator.move_arrays`): ``(ok, out, log,
    keys, rows)``; not ok where the compiled core raised (Python retries it)."""
    solves = np.zeros(1, dtype=np.int64)
    try:
        out, log, new_keys, rows = move.run(model, q, h, target, keys, True, solves)
        return True, out, log, new_keys, rows
    except Exception:  # whatever it was, Python moves again and reports it
        return False, np.zeros(move.OUT_SIZE), move.new_log(), keys, np.zeros((0, move.ROW_SIZE))


@njit(cache=CACHE)
def analyse(consts, settings, q, h, keys, rows, an):
    """The analysis of the state ``(q, h)`` with contacts ``keys`` and their ``rows`` into
    ``an``: on the support, form closure, ``y*`` (where in form closure, or always with
    ``always_compute_grip``; NaN otherwise) and success. Returns whether ``y*`` is decided
    (else the reference solver decides it, and :func:`conclude` gets it in ``an``)."""
    m = keys.shape[0]
    on_support = False
    for i in range(m):
        on_support = on_support or keys[i, 0] == 0
    P = rows[:, move.ROW_POINT].copy()
    N = rows[:, move.ROW_NORMAL].copy()
    # planar form closure needs at least four frictionless contacts: skip the LP below
    closure = m >= 4 and analysis.form_closure(P, N, q, consts[K_RHO])
    an[A_ON_SUPPORT] = on_support
    an[A_CLOSURE] = closure
    an[A_SUCCESS] = closure and not on_support
    an[A_GRIP] = np.nan
    if closure or settings[S_ALWAYS_GRIP] != 0.0:
        bodies = keys[:, 0].copy()
        w = consts[K_WIDTH]
        outcome, value = analysis.grip_objective(
            P, N, bodies, q, h, w / 2.0, w, consts[K_WEIGHT], consts[K_GRIP:CONSTS]
        )
        if outcome == analysis.GRIP_UNDECIDED:
            return False
        an[A_GRIP] = value
    return True


@njit(cache=CACHE)
def observe_contacts(model, consts, settings, q, h, keys, rows, an, obs) -> None:
    """Write the contact block of the observation: per body the contact count and total force
    (in weights), form closure, ``y* / W`` (``y_max`` outside form closure), the object's
    height above its start, and with ``hand_features`` the contact positions."""
    at = int(settings[S_CONTACTS_AT])
    weight, w = consts[K_WEIGHT], consts[K_WIDTH]
    block = np.zeros(CONTACT_ENTRIES + POSITION_ENTRIES)
    for i in range(keys.shape[0]):
        k = 2 * keys[i, 0]
        block[k] += 1.0
        block[k + 1] += rows[i, move.ROW_FORCE] / weight
    grip = an[A_GRIP] / weight if an[A_CLOSURE] != 0.0 else GRIP_MAX
    block[8] = an[A_CLOSURE]
    block[9] = grip if math.isfinite(grip) else GRIP_MAX
    block[10] = (q[1] - consts[K_Y0]) / w
    n = CONTACT_ENTRIES
    if settings[S_HAND_FEATURES] != 0.0:
        positions = np.empty(3)
        P = rows[:, move.ROW_POINT].copy()
        bodies = keys[:, 0].copy()
        contact_positions(h, P, bodies, model.half, consts[K_LENGTHS : K_LENGTHS + 3], positions)
        block[n : n + 3] = positions
        n += POSITION_ENTRIES
    for j in range(n):
        obs[at + j] = block[j]


@njit(cache=CACHE)
def observation(model, consts, settings, q, h, obs, low, high):
    """The observation (a clipped copy of ``obs``) after writing its pose block and, with
    ``hand_features``, the fingertips and hand-object distances."""
    w = consts[K_WIDTH]
    if settings[S_HAND_FEATURES] != 0.0:
        features = hand_features(
            model.points, model.body, model.n_object, model.n_vertices, model.half, q, h
        )
        at = int(settings[S_HAND_AT])
        for j in range(features.shape[0]):
            obs[at + j] = features[j] / w
    return finish_observation(obs, h, q, in_palm_frame(h, q), consts[K_X0], w, low, high)


@njit(cache=CACHE)
def conclude(model, consts, settings, q, h, keys, rows, an, ep, obs, low, high, a, new, info):
    """The rest of a step once the state ``(q, h, keys, rows)`` and its analysis ``an`` are
    known: the drop, the reward and its terms, the episode's end, and the observation
    (returned). ``new``: the contacts changed (else the observation's contact block is kept);
    ``info`` gets :data:`I_SUCCESS` ... :data:`INFO`, ``ep`` moves on."""
    weight, w = consts[K_WEIGHT], consts[K_WIDTH]
    p = in_palm_frame(h, q)
    out_of_reach = max(abs(p[0]), abs(p[1])) > REACH * w
    on_support = an[A_ON_SUPPORT] != 0.0
    success = an[A_SUCCESS] != 0.0
    dropped = (on_support and ep[E_LEFT_SUPPORT] != 0.0) or out_of_reach
    if not on_support:
        ep[E_LEFT_SUPPORT] = 1.0
    weights = settings[S_WEIGHTS:SETTINGS]
    bonus = 0.0
    if success and ep[E_REWARDED] == 0.0:
        bonus = weights[0]
        ep[E_REWARDED] = 1.0
    hold = weights[1] if success else 0.0
    grip = 0.0
    if success and math.isfinite(an[A_GRIP]):
        y = min(an[A_GRIP] / weight, GRIP_MAX)
        grip = weights[2] * (1.0 - y / GRIP_MAX)
    phi = 0.0 if dropped else weights[3] * ((q[1] - consts[K_Y0]) / w)
    lift = settings[S_GAMMA] * phi - ep[E_PHI]
    ep[E_PHI] = phi
    drop = -weights[4] if dropped else 0.0
    effort = 0.0
    for x in a:
        effort += x * x
    ctrl = -weights[5] * effort
    terms = (bonus, hold, grip, lift, drop, ctrl)
    reward = 0.0
    for j in range(len(terms)):
        reward += terms[j]
        info[I_TERMS + j] = terms[j]
    ep[E_STEPS] += 1.0
    steps = settings[S_MAX_STEPS]
    info[I_SUCCESS] = success
    info[I_CLOSURE] = an[A_CLOSURE]
    info[I_GRIP_FORCE] = an[A_GRIP] if an[A_CLOSURE] != 0.0 else np.inf
    info[I_GRIP] = an[A_GRIP]
    info[I_DROPPED] = dropped
    info[I_TERMINATED] = dropped
    info[I_TRUNCATED] = steps > 0.0 and ep[E_STEPS] >= steps
    info[I_REWARD] = reward
    if new:
        observe_contacts(model, consts, settings, q, h, keys, rows, an, obs)
    return observation(model, consts, settings, q, h, obs, low, high)


@njit(cache=CACHE, inline="always")
def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.all(a == b)`` for 1-D arrays of one length, without its arrays."""
    for i in range(a.shape[0]):
        if a[i] != b[i]:
            return False
    return True


@njit(cache=CACHE)
def finish_step(model, consts, settings, state, moved, a, an, ep, obs, low, high, info):
    """The step after the move: ``moved = (out, keys, rows)`` of the move from ``state = (q,
    h, keys, rows)``. Returns ``(status, observation, q, h, keys, rows, analysis)`` with the
    state reached and its analysis; :data:`OK` with ``an`` and ``ep`` moved on and ``info``
    filled, or :data:`GRIP_UNDECIDED` with nothing of the episode changed and the analysis
    waiting for ``y*`` (Python's reference solver, then :func:`conclude`)."""
    q, h, keys, rows = state
    out, new_keys, new_rows = moved
    s_reached, s_end = out[move.OUT_S], out[move.OUT_S_END]
    jammed, untouched = out[move.OUT_JAMMED] != 0.0, out[move.OUT_UNTOUCHED] != 0.0
    # the hand is blocked by the support only if it got there (a jam may stop it first)
    info[I_BLOCKED] = out[move.OUT_BLOCKED] != 0.0 and not (jammed and s_reached < s_end)
    info[I_JAMMED] = jammed
    info[I_UNTOUCHED] = untouched
    q_new, h_new = out[move.OUT_Q].copy(), out[move.OUT_H].copy()
    if untouched:  # the object and its contacts are as they were
        new_keys, new_rows = keys, rows
    new_an = an.copy()
    same = untouched or (_same(q_new, q) and _same(h_new, h))
    if not same and not analyse(consts, settings, q_new, h_new, new_keys, new_rows, new_an):
        return GRIP_UNDECIDED, obs, q_new, h_new, new_keys, new_rows, new_an
    an[:] = new_an
    seen = conclude(
        model, consts, settings, q_new, h_new, new_keys, new_rows, an, ep, obs, low, high, a,
        not same, info,
    )  # fmt: skip
    return OK, seen, q_new, h_new, new_keys, new_rows, new_an


@njit(cache=CACHE)
def step_env(model, consts, settings, state, an, ep, obs, low, high, action, info):
    """Advance one episode by ``action`` from ``state = (q, h, keys, rows)``: ``(status,
    observation, log, out, q, h, keys, rows, analysis)`` as :func:`finish_step` says, with
    the move's event log and ``out`` (:func:`grasp_env.sim.move.run`);
    :data:`MOVE_FAILED` where the compiled move raised (nothing changed: Python moves again
    with :meth:`grasp_env.Simulator.move_arrays`, and finishes the step with
    :func:`finish_step`)."""
    q, h, keys, rows = state
    target, a, joint_limit = target_of(consts, settings, h, action)
    info[I_JOINT_LIMIT] = joint_limit
    ok, out, log, new_keys, new_rows = try_move(model, q, h, keys, target)
    if not ok:
        return MOVE_FAILED, obs, log, out, q, h, keys, rows, an.copy()
    status, seen, q_new, h_new, k, r, new_an = finish_step(
        model, consts, settings, state, (out, new_keys, new_rows), a, an, ep, obs, low, high,
        info,
    )  # fmt: skip
    return status, seen, log, out, q_new, h_new, k, r, new_an
