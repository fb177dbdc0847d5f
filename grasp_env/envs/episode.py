"""An episode of the env as the compiled kernel's arrays (:mod:`grasp_env.kernel.step`), and
Python's part of a step: where the kernel hands over (a move the compiled core could not
finish, a grip LP for the reference solver), the kernel's own functions finish the step, so
that the single env and the batched one compute the same bits on every path."""

from __future__ import annotations

import numpy as np

from grasp_env.core.scene import Scene
from grasp_env.core.state import State
from grasp_env.errors import ComputationError
from grasp_env.kernel import analysis
from grasp_env.kernel import step as kernel
from grasp_env.kernel.observation import (
    PALM_THETA_MAX,
    PALM_X_RANGE,
    PALM_Y_MAX,
    POSE_ENTRIES,
    contact_block_at,
    hand_block_at,
)
from grasp_env.mechanics.closure import reference_grip
from grasp_env.mechanics.friction import contact_edge_rows, jams_on_rows
from grasp_env.sim import move
from grasp_env.simulator import Simulator

#: The info keys of the reward terms, in the kernel's order (:data:`grasp_env.kernel.step.
#: REWARD_TERMS`).
REWARD_KEYS = tuple(f"reward_{term}" for term in kernel.REWARD_TERMS)


def env_settings(
    *, palm_control: bool, always_compute_grip: bool, hand_features: bool, gamma: float,
    time_limit: int | None, max_vertices: int, reward_weights: dict[str, float],
) -> np.ndarray:  # fmt: skip
    """The env's arguments as the kernel's ``settings`` array (:data:`grasp_env.kernel.step.
    SETTINGS`); ``reward_weights`` by term name."""
    out = np.zeros(kernel.SETTINGS)
    out[kernel.S_PALM_CONTROL] = palm_control
    out[kernel.S_ALWAYS_GRIP] = always_compute_grip
    out[kernel.S_HAND_FEATURES] = hand_features
    out[kernel.S_GAMMA] = gamma
    out[kernel.S_MAX_STEPS] = 0.0 if time_limit is None else time_limit
    out[kernel.S_CONTACTS_AT] = contact_block_at(max_vertices)
    out[kernel.S_HAND_AT] = hand_block_at(max_vertices)
    for i, term in enumerate(kernel.REWARD_TERMS):
        out[kernel.S_WEIGHTS + i] = reward_weights[term]
    return out


def episode_constants(
    scene: Scene, start: State, finger_step: float, palm_step: tuple, rho: float
) -> np.ndarray:
    """What the episode's scene and start state fix, as the kernel's ``consts`` array
    (:data:`grasp_env.kernel.step.CONSTS`): the finger step, the palm's workspace about the
    object's start ``x0`` and its step (palm widths and radians, as the env's arguments
    give them), the joint limits, ``x0``, the palm width, the weight, the start height, the
    radius of gyration ``rho``, the bodies' lengths and the grip LP's finger data."""
    w, x0 = scene.palm.width, scene.object.start_pose[0]
    out = np.empty(kernel.CONSTS)
    out[kernel.K_FINGER_STEP] = finger_step
    out[kernel.K_PALM_LOW : kernel.K_PALM_LOW + 3] = (x0 - PALM_X_RANGE * w, 0.0, -PALM_THETA_MAX)
    out[kernel.K_PALM_HIGH : kernel.K_PALM_HIGH + 3] = (
        x0 + PALM_X_RANGE * w, PALM_Y_MAX * w, PALM_THETA_MAX,
    )  # fmt: skip
    out[kernel.K_PALM_STEP : kernel.K_PALM_STEP + 3] = [
        float(m) * u for m, u in zip(palm_step, (w, w, 1.0), strict=True)
    ]
    limits = scene.joint_limits
    out[kernel.K_JOINT_LOW : kernel.K_JOINT_LOW + 2] = limits[:, 0]
    out[kernel.K_JOINT_HIGH : kernel.K_JOINT_HIGH + 2] = limits[:, 1]
    out[kernel.K_X0], out[kernel.K_WIDTH] = x0, w
    out[kernel.K_WEIGHT], out[kernel.K_Y0] = scene.object_weight, float(start.object_pose[1])
    out[kernel.K_RHO] = rho
    out[kernel.K_LENGTHS : kernel.K_LENGTHS + 3] = (w, *(f.length for f in scene.fingers))
    out[kernel.K_GRIP : kernel.CONSTS] = analysis.grip_constants(scene)
    return out


def state_arrays(state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(q, h, keys, rows)`` of a state, as the kernel takes them."""
    m = len(state.contacts)
    keys = np.array([c.key for c in state.contacts], dtype=np.int64).reshape(m, 4)
    rows = np.empty((m, move.ROW_SIZE))
    for i, c in enumerate(state.contacts):
        rows[i, 0:2], rows[i, 2:4] = c.point, c.normal
        rows[i, 4], rows[i, 5] = c.gap, c.force
    return state.object_pose.copy(), state.hand.copy(), keys, rows


class Episode:
    """One episode: its simulator and scene, the nominal simulator whose object the
    observation shows (``sim`` itself unless the env's ``uncertainty`` perturbs the simulated
    object), the kernel's arrays (``consts``, the state ``q``, ``h``, ``keys``, ``rows``, the
    analysis ``an``, the episode so far ``ep``, the observation buffer ``obs``) and the
    current :class:`grasp_env.State`."""

    __slots__ = ("an", "consts", "ep", "h", "keys", "nominal", "obs", "q", "rows", "sim", "state")

    def __init__(self, sim: Simulator, state: State, consts: np.ndarray, settings: np.ndarray,
                 obs_size: int, nominal: Simulator | None = None) -> None:  # fmt: skip
        """The episode starting at ``state``: its analysis (the reference solver deciding a
        grip the compiled one cannot, which may raise ``SolverError``), the lift potential
        and the observation buffer's vertex block (the nominal object's, object frame, palm
        widths, padded, with its mask)."""
        self.sim, self.state, self.consts = sim, state, consts
        self.nominal = sim if nominal is None else nominal
        self.q, self.h, self.keys, self.rows = state_arrays(state)
        self.an = np.zeros(kernel.ANALYSIS)
        if not kernel.analyse(consts, settings, self.q, self.h, self.keys, self.rows, self.an):
            self.an[kernel.A_GRIP] = reference_grip(state)
        self.ep = np.zeros(kernel.EPISODE)
        self.ep[kernel.E_LEFT_SUPPORT] = self.an[kernel.A_ON_SUPPORT] == 0.0
        w = consts[kernel.K_WIDTH]
        lift = settings[kernel.S_WEIGHTS + kernel.REWARD_TERMS.index("lift")]
        self.ep[kernel.E_PHI] = lift * ((self.q[1] - consts[kernel.K_Y0]) / w)
        self.obs = np.zeros(obs_size, dtype=np.float32)
        v = self.nominal.scene.object.vertices_B / w
        n = (int(settings[kernel.S_CONTACTS_AT]) - POSE_ENTRIES) // 3
        self.obs[POSE_ENTRIES : POSE_ENTRIES + v.size] = v.ravel()
        self.obs[POSE_ENTRIES + 2 * n : POSE_ENTRIES + 2 * n + len(v)] = 1.0
        model = sim.compiled_model
        kernel.observe_contacts(
            model, consts, settings, self.q, self.h, self.keys, self.rows, self.an, self.obs
        )

    def fresh(self) -> Episode:
        """A copy whose arrays are its own (the simulators, the state and the constants,
        which nothing changes, shared): an episode to step from where this one stands."""
        out = object.__new__(Episode)
        for name in ("sim", "nominal", "state", "consts"):
            setattr(out, name, getattr(self, name))
        for name in ("q", "h", "keys", "rows", "an", "ep", "obs"):
            setattr(out, name, getattr(self, name).copy())
        return out

    def observation(self, settings: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        """The observation of the current state."""
        return self.observe(self.q, self.h, self.obs, settings, low, high)

    def observe(self, q, h, obs, settings, low, high) -> np.ndarray:
        """:func:`grasp_env.kernel.step.observation` of the state ``(q, h)`` into the buffer
        ``obs``, the hand-object distances to the nominal object at the simulated one's
        pose."""
        return kernel.observation(
            self.nominal.compiled_model, self.consts, settings, q, h, obs, low, high
        )

    def shows_nominal(self, settings: np.ndarray) -> bool:
        """Whether the kernel's step observes another object than the one the observation
        shows: it does with ``uncertainty`` and ``hand_features`` (the hand-object
        distances), and the step's observation is then made again by :meth:`observe`."""
        return self.nominal is not self.sim and settings[kernel.S_HAND_FEATURES] != 0.0

    def step(self, action: np.ndarray, settings, low, high) -> tuple[np.ndarray, np.ndarray]:
        """Advance by ``action`` (float64): ``(observation, info)`` with ``info`` the kernel's
        (:data:`grasp_env.kernel.step.INFO`), the episode moved on. A
        :class:`grasp_env.errors.ComputationError` (the move failed on the reference path
        too, or the reference grip LP did) leaves the episode as it was."""
        info = np.zeros(kernel.INFO)
        state = (self.q, self.h, self.keys, self.rows)
        model = self.sim.compiled_model
        status, seen, log, out, q, h, keys, rows, an = kernel.step_env(
            model, self.consts, settings, state, self.an, self.ep, self.obs, low, high, action,
            info,
        )  # fmt: skip
        if status != kernel.OK:
            target, a, _ = kernel.target_of(self.consts, settings, self.h, action)
        if status == kernel.MOVE_FAILED:
            out, log, moved_keys, moved_rows = self.sim.move_arrays(
                self.q, self.h, target, self.keys
            )
            status, seen, q, h, keys, rows, an = kernel.finish_step(
                model, self.consts, settings, state, (out, moved_keys, moved_rows), a, self.an,
                self.ep, self.obs, low, high, info,
            )  # fmt: skip
        joint_limit = info[kernel.I_JOINT_LIMIT] != 0.0
        new = self.sim.state_from_move(self.state, out, log, keys, rows, joint_limit)
        if status == kernel.GRIP_UNDECIDED:
            an[kernel.A_GRIP] = reference_grip(new)
            self.an[:] = an
            seen = kernel.conclude(
                model, self.consts, settings, q, h, keys, rows, self.an, self.ep,
                self.obs, low, high, a, True, info,
            )  # fmt: skip
        self.q, self.h, self.keys, self.rows, self.state = q, h, keys, rows, new
        if self.shows_nominal(settings):
            seen = self.observation(settings, low, high)
        return seen, info

    def friction_jams(self, arrays: tuple, action: np.ndarray, settings, mu: float) -> bool:
        """Whether friction ``mu`` at every contact jams the hand motion ``action`` asks for
        from the state ``(q, h, keys, rows)`` (:func:`grasp_env.mechanics.friction.
        jams_with_friction`)."""
        q, h, keys, rows = arrays
        target, _, _ = kernel.target_of(self.consts, settings, h, action)
        edges = contact_edge_rows(
            self.sim.scene, q, h, rows[:, 0:2], rows[:, 2:4], keys[:, 0], target - h
        )
        return jams_on_rows(edges, mu)

    def simulate(self, state: State, action: np.ndarray, settings: np.ndarray) -> State:
        """The state ``action`` leads to from ``state`` (of this episode's scene), as
        :meth:`step` moves; the episode is unchanged."""
        q, h, keys, _ = state_arrays(state)
        target, _, joint_limit = kernel.target_of(self.consts, settings, h, action)
        model = self.sim.compiled_model
        ok, out, log, moved_keys, rows = kernel.try_move(model, q, h, keys, target)
        if not ok:
            out, log, moved_keys, rows = self.sim.move_arrays(q, h, target, keys)
        return self.sim.state_from_move(state, out, log, moved_keys, rows, joint_limit)

    def advance(self, action, settings, low, high) -> tuple[np.ndarray, np.ndarray, str | None]:
        """:meth:`step`, and where the simulator or the analysis cannot compute the step
        (a :class:`grasp_env.errors.ComputationError`), the end of the episode where it is:
        ``(observation, info, error)``, the error's message in ``error`` and ``info`` holding
        the reward that undoes the lift potential (zero at a terminal state), the step
        counted."""
        try:
            obs, info = self.step(action, settings, low, high)
            return obs, info, None
        except ComputationError as exc:
            info = np.zeros(kernel.INFO)
            info[kernel.I_REWARD] = info[kernel.I_TERMS + 3] = -self.ep[kernel.E_PHI]
            self.ep[kernel.E_PHI] = 0.0
            self.ep[kernel.E_STEPS] += 1.0
            limit = settings[kernel.S_MAX_STEPS]
            info[kernel.I_TERMINATED] = True
            info[kernel.I_TRUNCATED] = limit > 0.0 and self.ep[kernel.E_STEPS] >= limit
            return self.observation(settings, low, high), info, f"{type(exc).__name__}: {exc}"
