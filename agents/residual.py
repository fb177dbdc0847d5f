"""A residual agent: a learned correction added to the scripted planner's actions.

:class:`PlannerResidual` wraps a palm-controlled env so that the agent's action is a
correction to :class:`agents.scripted.ScriptedPolicy`'s: the env receives ``clip(base +
scale * correction)``, and the agent observes the env's observation followed by the base
action. A zero correction is the planner itself, so training starts from the planner's
success and learns what to change (a lighter grip, a squeeze that does not jam).

Where the planner has to re-place the hand or explore with palm motion (its fallbacks, when
lifting from the env's placement gets stuck), it replays a path found by exact simulation
past tipping bifurcations, which any correction would break: the correction is ignored for
the rest of that episode (with ``after_plan``, until the path is played).
``correction_cost`` charges the reward for the size of the correction, so that the agent
leaves the planner's action where a change does not pay (the usual penalty of residual
learning). With ``after_plan`` the correction acts only once the
planner's plan, fallback or not, has been played to its end: the planner lifts and adjusts
the grip, and the agent then holds the object (the planner's palm stays fixed there; the
agent's may move, e.g. to a lighter grip).

With ``redraw`` (training), a shape whose lifting from the placement gets stuck is redrawn at
reset instead, and the planner runs without fallbacks: the corrections are learned where
they act, without the fallbacks' seconds of search.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from agents.scripted import ScriptedPolicy
from grasp_env.arguments import real_vector
from grasp_env.errors import ComputationError
from grasp_env.kernel.observation import GRIP_MAX
from grasp_env.planning.plan import grip_if_closed

#: Resets at most per episode with ``redraw`` before a shape is kept (here and in
#: :class:`agents.handover.PlannerHandover`).
MAX_REDRAWS = 20


class PlannerResidual(gym.Wrapper):
    """The env seen through a correction to the scripted planner's action.

    Observation: the env's, then the planner's next action (5 floats in [-1, 1]), then with
    ``last_step`` what the last step did (6 floats), then with ``probe_turns`` what a turn
    would do (2 floats; both below). Action:
    the correction, in [-1, 1] per entry (clipped there, as the env clips its actions; the
    palm's three with ``palm_only``), scaled by ``scale`` and added to the planner's action;
    the sum is clipped to the env's action bounds.

    Args:
        env: a ``FrictionlessGrasp-v0`` env with ``palm_control`` (five actions).
        scale: largest correction, as a fraction of an action's largest size, 1
            (0 < scale <= 1).
        redraw: at reset, redraw shapes whose lifting from the placement gets stuck (up to
            ``MAX_REDRAWS`` times) and run the planner without fallbacks; for training. A
            planning failure (``ComputationError``: a move the simulator cannot make) then
            counts as stuck at reset and makes the planner hold still mid-episode (reported
            once as ``info["planner_error"]``); without ``redraw`` it is raised, as by the
            planner alone.
        after_plan: the correction acts only once the planner's plan is done (after a
            fallback's path too), and then as it is (the planner holds still).
        correction_cost: the reward loses ``correction_cost * sum(c**2)`` for the correction
            ``c`` that acts (in [-1, 1] per entry; zero where it is ignored), reported as
            ``info["reward_correction"]`` when positive (0, the default, leaves the env's
            reward as it is).
        palm_only: the correction moves the palm only (three actions: ``dx``, ``dy``,
            ``dtheta``); the fingers follow the planner. Held in form closure with the
            fingers still, the object moves with the hand as one body (e.g. the palm turns
            the grasp so that the object's weight bears more directly on its contacts).
        last_step: the observation also holds the action the env received at the last step
            and y*/W before it (at most ``GRIP_MAX``, which also stands for no form closure;
            zeros and the reset's y*/W after a reset), so that with the env's own y*/W
            the agent sees what its last move did.
        grip_shaping: at a step where the correction acts, the reward gains
            ``grip_shaping`` times the fall of y*/W over the step (as ``last_step`` observes
            it), reported as ``info["reward_grip_shaping"]``: a difference of potentials, so
            over the steps it acts it adds up to ``grip_shaping`` times y*/W where they start
            less where they end, and it credits each move with the change it made.
        probe_turns: the observation also holds the change of y*/W (as ``last_step`` caps
            it) that the largest palm turn of the correction, each way (``dtheta`` correction
            +1, then -1, the rest zero), would make at this step, simulated on a copy with
            :meth:`~grasp_env.FrictionlessGraspEnv.simulate_action` (a move the simulator
            cannot follow counts as losing form closure); zeros where the correction does
            not act. Turning the palm turns a held grasp as one body, the move that lightens
            the planner's grips most; the probes let the agent see which way is lighter, as
            a search does by trying.

    Raises:
        ValueError: ``scale`` outside (0, 1], ``correction_cost`` or ``grip_shaping``
            negative or not finite, or an env without palm control.
    """

    def __init__(
        self,
        env: gym.Env,
        scale: float = 0.25,
        redraw: bool = False,
        after_plan: bool = False,
        correction_cost: float = 0.0,
        palm_only: bool = False,
        last_step: bool = False,
        grip_shaping: float = 0.0,
        probe_turns: bool = False,
    ) -> None:
        super().__init__(env)
        if isinstance(scale, bool) or not (isinstance(scale, (int, float)) and 0 < scale <= 1):
            raise ValueError(f"scale must be in (0, 1], got {scale!r}")
        for name, value in (("correction_cost", correction_cost), ("grip_shaping", grip_shaping)):
            if isinstance(value, bool) or not (
                isinstance(value, (int, float)) and 0 <= value < np.inf
            ):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if not env.unwrapped.palm_control:
            raise ValueError("PlannerResidual needs palm_control=True (five actions), got False")
        self.scale = float(scale)
        self.redraw = bool(redraw)
        self.after_plan = bool(after_plan)
        self.correction_cost = float(correction_cost)
        self.grip_shaping = float(grip_shaping)
        self.palm_only = bool(palm_only)
        self.last_step = bool(last_step)
        self.probe_turns = bool(probe_turns)
        self.policy = ScriptedPolicy(env, fallbacks=not redraw)
        inner = env.observation_space
        low, high = [inner.low, -np.ones(5, np.float32)], [inner.high, np.ones(5, np.float32)]
        if self.last_step:
            low += [-np.ones(5, np.float32), np.zeros(1, np.float32)]
            high += [np.ones(5, np.float32), np.full(1, GRIP_MAX, np.float32)]
        if self.probe_turns:
            low.append(np.full(2, -GRIP_MAX, np.float32))
            high.append(np.full(2, GRIP_MAX, np.float32))
        self.observation_space = gym.spaces.Box(
            np.concatenate(low), np.concatenate(high), dtype=np.float32
        )
        self._sent = np.zeros(5, np.float32)  # the last step's action
        self._grips = [GRIP_MAX, GRIP_MAX]  # y*/W before and after the last step
        self.action_space = gym.spaces.Box(-1.0, 1.0, (3 if self.palm_only else 5,), np.float32)
        self._base = np.zeros(5, np.float32)
        self._planner_error: str | None = None

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        redraws = MAX_REDRAWS if self.redraw else 0
        while not self._plan(obs, info) and redraws:
            redraws -= 1
            obs, info = self.env.reset(options=options)
        self._base = np.zeros(5, np.float32) if self._planner_error else self.policy.act(obs)
        self._sent[:] = 0.0
        self._grips = [self._grip(info)] * 2
        return self._observe(obs), info

    def _plan(self, obs, info) -> bool:
        """Plan the episode; whether lifting from the placement reaches form closure. With
        ``redraw`` a planning failure (a move the simulator cannot make) counts as stuck, and
        the planner holds still if the shape is kept; without, it is raised, as the planner
        alone raises it."""
        self._planner_error = None
        try:
            self.policy.reset(obs, info)
        except ComputationError as exc:
            if not self.redraw:
                raise
            self._planner_error = f"{type(exc).__name__}: {exc}"
            return False
        return self.policy.plan.success

    def step(self, action):
        size = self.action_space.shape[0]
        correction = np.zeros(5, np.float32)
        given = real_vector(action, "action (the correction)", size)
        correction[5 - size :] = np.clip(given, -1.0, 1.0)  # as the env clips
        acts = self._acts()
        if not acts:
            correction = np.zeros(5, np.float32)
        sent = self._send(correction)
        obs, reward, terminated, truncated, info = self.env.step(sent)
        self._sent, self._grips = sent, [self._grips[1], self._grip(info)]
        if self.correction_cost:
            cost = -self.correction_cost * float(np.dot(correction, correction))
            reward, info = reward + cost, {**info, "reward_correction": cost}
        if self.grip_shaping and acts:
            shaping = self.grip_shaping * (self._grips[0] - self._grips[1])
            reward, info = reward + shaping, {**info, "reward_grip_shaping": shaping}
        if not (terminated or truncated) and self._planner_error is None:
            try:
                self._base = self.policy.act(obs)
            except ComputationError as exc:  # a re-plan failed
                if not self.redraw:
                    raise
                self._planner_error = f"{type(exc).__name__}: {exc}"  # the planner holds still
                self._base = np.zeros(5, np.float32)
                info = {**info, "planner_error": self._planner_error}
        return self._observe(obs), reward, terminated, truncated, info

    def _acts(self) -> bool:
        """The correction acts at this step."""
        return self._plan_played() if self.after_plan else not self.policy.on_fallback

    def _send(self, correction: np.ndarray) -> np.ndarray:
        """The env's action for a correction (5 floats in [-1, 1]) at this step."""
        low, high = self.env.action_space.low, self.env.action_space.high
        return np.clip(self._base + self.scale * correction, low, high).astype(np.float32)

    def _probes(self) -> list[float]:
        """The change of y*/W that a full turn of the correction each way would make now."""
        if not self._acts():
            return [0.0, 0.0]
        env = self.unwrapped
        now = self._grips[1]
        changes = []
        for sign in (1.0, -1.0):
            try:
                state = env.simulate_action(env.state, self._send(np.array([0, 0, 0, 0, sign])))
            except ComputationError:
                changes.append(GRIP_MAX - now)
                continue
            changes.append(_capped(grip_if_closed(state) / state.scene.object_weight) - now)
        return changes

    def _plan_played(self) -> bool:
        """The planner has played its plan to the end (or failed) and holds still."""
        return (self._planner_error is not None or self.policy.done) and not self._base.any()

    def _grip(self, info: dict) -> float:
        """y*/W as the observation holds it: at most ``GRIP_MAX``, which also stands for no
        form closure."""
        return _capped(info["grip_force"] / self.unwrapped.scene.object_weight)

    def _observe(self, obs: np.ndarray) -> np.ndarray:
        parts = [obs, self._base]
        if self.last_step:
            parts += [self._sent, self._grips[:1]]
        if self.probe_turns:
            parts += [self._probes()]
        return np.concatenate(parts).astype(np.float32)


def _capped(grip: float) -> float:
    """y*/W as the residual observes it: at most ``GRIP_MAX``, which also stands for no form
    closure (``inf`` in the env's info, ``nan`` from ``grip_if_closed``)."""
    return min(grip, GRIP_MAX) if math.isfinite(grip) else GRIP_MAX


def planner_wrapper(entry: dict) -> tuple[type[gym.Wrapper], dict] | None:
    """The wrapper that plays a training entry's (``configs/*.yml``) policy beside the
    planner, :class:`PlannerResidual` or :class:`agents.handover.PlannerHandover` as its
    ``env_wrapper`` names, with the arguments for playing it (``redraw`` off: every shape is
    played as drawn, the planner with its fallbacks where it has them); None for an entry
    without one."""
    from agents.handover import PlannerHandover
    from agents.train_ppo import wrapper_specs

    for cls, kwargs in wrapper_specs(entry):
        if cls in (PlannerResidual, PlannerHandover):
            return cls, {**kwargs, "redraw": False}
    return None
