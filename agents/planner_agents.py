"""Agents that play beside the scripted planner (:class:`agents.scripted.ScriptedPolicy`),
each a wrapper of a palm-controlled lifting env that plans at every reset.

* :class:`PlannerResidual`: the agent's action is a correction added to the planner's
  (``clip(base + scale * correction)``), and the agent observes the env's observation
  followed by the planner's action. A zero correction is the planner itself, so training
  starts from the planner's success and learns what to change (a lighter grip, a squeeze
  that does not jam). Where the planner re-places the hand or explores with palm motion (its
  fallbacks, when lifting from the env's placement gets stuck), it replays a path found by
  exact simulation past tipping bifurcations, which any correction would break: the
  correction is ignored for the rest of that episode.
* :class:`PlannerGrip`: the correction acts only once the planner's plan, fallback or not,
  has been played to its end (the planner lifts and adjusts the grip; the agent then holds
  the object and may move the palm, e.g. to a lighter grip).
* :class:`PlannerHandover`: the planner plays where its lifting from the env's placement
  (palm fixed, no fallbacks) reaches form closure; where it gets stuck, the agent plays the
  whole episode, in place of the planner's re-placement and exploratory search (up to 20,000
  simulated moves, seconds of CPU a shape). Observation and action are the env's, so a
  model trained on the plain lifting env plays here too.

With ``redraw`` (training), each reset redraws the shapes the agent does not play (up to
``agents.planner_base.MAX_REDRAWS`` times): for the residual and grip agents the shapes
whose lifting from the placement gets stuck (the planner then runs without fallbacks, so no
episode spends seconds on its search), for the hand-over agent the shapes the planner lifts.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from agents.planner_base import PlannerAgent
from grasp_env.arguments import real_vector
from grasp_env.errors import ComputationError
from grasp_env.kernel.observation import GRIP_MAX
from grasp_env.planning.plan import grip_if_closed


class PlannerResidual(PlannerAgent):
    """The env seen through a correction to the planner's action.

    Observation: the env's, then the planner's next action (5 floats in [-1, 1]). Action: the
    correction, in [-1, 1] per entry (clipped there, as the env clips its actions), scaled by
    ``scale`` and added to the planner's action; the sum is clipped to the env's action
    bounds.

    Args:
        env: a ``FrictionlessGrasp-v0`` env with ``palm_control`` (five actions).
        scale: largest correction, as a fraction of an action's largest size, 1
            (0 < scale <= 1).
        redraw: at reset, redraw shapes whose lifting from the placement gets stuck and run
            the planner without fallbacks; for training. A planning failure then counts as
            stuck at reset and makes the planner hold still mid-episode (reported once as
            ``info["planner_error"]``); without ``redraw`` it is raised, as by the planner
            alone.
        correction_cost: the reward loses ``correction_cost * sum(c**2)`` for the correction
            ``c`` that acts (in [-1, 1] per entry; zero where it is ignored), reported as
            ``info["reward_correction"]`` when positive (0 leaves the env's reward as it is).

    Raises:
        ValueError: ``scale`` outside (0, 1], ``correction_cost`` negative or not finite, or
            an env without palm control.
    """

    def __init__(
        self,
        env: gym.Env,
        scale: float = 0.25,
        redraw: bool = False,
        correction_cost: float = 0.0,
    ) -> None:
        super().__init__(env, redraw, fallbacks=not redraw)
        if isinstance(scale, bool) or not (isinstance(scale, (int, float)) and 0 < scale <= 1):
            raise ValueError(f"scale must be in (0, 1], got {scale!r}")
        self.scale = float(scale)
        self.correction_cost = _cost(correction_cost, "correction_cost")
        self.observation_space = self._box(
            [env.observation_space.low, -np.ones(5, np.float32)],
            [env.observation_space.high, np.ones(5, np.float32)],
        )
        self.action_space = gym.spaces.Box(-1.0, 1.0, (5,), np.float32)
        self._base = np.zeros(5, np.float32)

    @staticmethod
    def _box(low: list, high: list) -> gym.spaces.Box:
        return gym.spaces.Box(np.concatenate(low), np.concatenate(high), dtype=np.float32)

    def _keeps(self, lifts: bool) -> bool:
        return lifts

    def _raises(self) -> bool:
        return not self.redraw

    def reset(self, *, seed=None, options=None):
        obs, info, _ = self._reset_planned(seed, options)
        self._base = np.zeros(5, np.float32) if self.planner_error else self.policy.act(obs)
        self._track(None, info)
        return self._observe(obs), info

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
        self._track(sent, info)
        if self.correction_cost:
            cost = -self.correction_cost * float(np.dot(correction, correction))
            reward, info = reward + cost, {**info, "reward_correction": cost}
        reward, info = self._shaped(reward, info, acts)
        if not (terminated or truncated) and self.planner_error is None:
            base = self._next_action(obs)
            if base is None:  # a re-plan failed: the planner holds still
                base = np.zeros(5, np.float32)
                info = {**info, "planner_error": self.planner_error}
            self._base = base
        return self._observe(obs), reward, terminated, truncated, info

    def _acts(self) -> bool:
        """The correction acts at this step."""
        return not self.policy.on_fallback

    def _send(self, correction: np.ndarray) -> np.ndarray:
        """The env's action for a correction (5 floats in [-1, 1]) at this step."""
        low, high = self.env.action_space.low, self.env.action_space.high
        return np.clip(self._base + self.scale * correction, low, high).astype(np.float32)

    def _track(self, sent: np.ndarray | None, info: dict) -> None:
        """Record a step's action and info (``sent`` None: a reset's info)."""

    def _shaped(self, reward: float, info: dict, acts: bool) -> tuple[float, dict]:
        """The reward and info of a step, with any shaping of the agent's own."""
        return reward, info

    def _observe(self, obs: np.ndarray) -> np.ndarray:
        return np.concatenate([obs, self._base]).astype(np.float32)


class PlannerGrip(PlannerResidual):
    """A :class:`PlannerResidual` whose correction acts only once the planner's plan is done
    (after a fallback's path too), and then as it is (the planner holds still).

    Observation: the env's, the planner's next action, then with ``last_step`` what the last
    step did (6 floats) and with ``probe_turns`` what a turn would do (2 floats; both below).

    Args:
        env, scale, redraw, correction_cost: as for :class:`PlannerResidual` (keywords after
            ``env``).
        palm_only: the correction moves the palm only (three actions: ``dx``, ``dy``,
            ``dtheta``); the fingers follow the planner. Held in form closure with the
            fingers still, the object moves with the hand as one body (e.g. the palm turns
            the grasp so that the object's weight bears more directly on its contacts).
        last_step: the observation also holds the action the env received at the last step
            and y*/W before it (at most ``GRIP_MAX``, which also stands for no form closure;
            zeros and the reset's y*/W after a reset), so that with the env's own y*/W the
            agent sees what its last move did.
        grip_shaping: at a step where the correction acts, the reward gains ``grip_shaping``
            times the fall of y*/W over the step (as ``last_step`` observes it), reported as
            ``info["reward_grip_shaping"]``: a difference of potentials, so over the steps it
            acts it adds up to ``grip_shaping`` times y*/W where they start less where they
            end, and it credits each move with the change it made.
        probe_turns: the observation also holds the change of y*/W (as ``last_step`` caps it)
            that the largest palm turn of the correction, each way (``dtheta`` correction +1,
            then -1, the rest zero), would make at this step, simulated on a copy with
            :meth:`~grasp_env.FrictionlessGraspEnv.simulate_action` (a move the simulator
            cannot follow counts as losing form closure); zeros where the correction does not
            act. Turning the palm turns a held grasp as one body, the move that lightens the
            planner's grips most; the probes let the agent see which way is lighter, as a
            search does by trying.

    Raises:
        ValueError: as :class:`PlannerResidual`, and ``grip_shaping`` negative or not finite.
    """

    simulator_options = ("probe_turns",)  # simulate_action on a copy, twice a step

    def __init__(
        self,
        env: gym.Env,
        *,
        palm_only: bool = False,
        last_step: bool = False,
        grip_shaping: float = 0.0,
        probe_turns: bool = False,
        **residual: Any,
    ) -> None:
        super().__init__(env, **residual)
        self.grip_shaping = _cost(grip_shaping, "grip_shaping")
        self.palm_only = bool(palm_only)
        self.last_step = bool(last_step)
        self.probe_turns = bool(probe_turns)
        space = self.observation_space
        low, high = [space.low], [space.high]
        if self.last_step:
            low += [-np.ones(5, np.float32), np.zeros(1, np.float32)]
            high += [np.ones(5, np.float32), np.full(1, GRIP_MAX, np.float32)]
        if self.probe_turns:
            low.append(np.full(2, -GRIP_MAX, np.float32))
            high.append(np.full(2, GRIP_MAX, np.float32))
        self.observation_space = self._box(low, high)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (3 if self.palm_only else 5,), np.float32)
        self._sent = np.zeros(5, np.float32)  # the last step's action
        self._grips = [GRIP_MAX, GRIP_MAX]  # y*/W before and after the last step

    def _acts(self) -> bool:
        """The planner has played its plan to the end (or failed) and holds still."""
        return (self.planner_error is not None or self.policy.done) and not self._base.any()

    def _track(self, sent: np.ndarray | None, info: dict) -> None:
        if sent is None:
            self._sent[:] = 0.0
            self._grips = [self._grip(info)] * 2
        else:
            self._sent, self._grips = sent, [self._grips[1], self._grip(info)]

    def _shaped(self, reward: float, info: dict, acts: bool) -> tuple[float, dict]:
        if self.grip_shaping and acts:
            shaping = self.grip_shaping * (self._grips[0] - self._grips[1])
            reward, info = reward + shaping, {**info, "reward_grip_shaping": shaping}
        return reward, info

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

    def _grip(self, info: dict) -> float:
        """y*/W as the observation holds it."""
        return _capped(info["grip_force"] / self.unwrapped.scene.object_weight)

    def _observe(self, obs: np.ndarray) -> np.ndarray:
        parts = [obs, self._base]
        if self.last_step:
            parts += [self._sent, self._grips[:1]]
        if self.probe_turns:
            parts += [self._probes()]
        return np.concatenate(parts).astype(np.float32)


class PlannerHandover(PlannerAgent):
    """The planner plays where its lifting from the env's placement reaches form closure, the
    agent everywhere else (``info["planner_plays"]`` says which, at reset and every step).

    Args:
        env: a ``FrictionlessGrasp-v0`` env with ``palm_control`` (five actions).
        redraw: at reset, redraw shapes the planner lifts; for training. A planning failure
            at reset counts as stuck, and one mid-episode (a re-plan) hands the rest of the
            episode to the agent (reported once as ``info["planner_error"]``).

    Raises:
        ValueError: an env without palm control.
    """

    def __init__(self, env: gym.Env, redraw: bool = False) -> None:
        super().__init__(env, redraw, fallbacks=False)
        self.planner_plays = False
        self._next = np.zeros(5, np.float32)

    def _keeps(self, lifts: bool) -> bool:
        return not lifts

    def reset(self, *, seed=None, options=None):
        obs, info, self.planner_plays = self._reset_planned(seed, options)
        if self.planner_plays:
            self._next = self.policy.act(obs)
        return obs, {**info, "planner_plays": self.planner_plays}

    def step(self, action):
        sent = action
        if self.planner_plays:
            real_vector(action, "action", 5)  # ignored, but checked as the env would
            sent = self._next
        obs, reward, terminated, truncated, info = self.env.step(sent)
        info = {**info, "planner_plays": self.planner_plays}
        if self.planner_plays and not (terminated or truncated):
            action = self._next_action(obs)
            if action is None:  # a re-plan failed: the agent goes on
                self.planner_plays = False
                info["planner_error"] = self.planner_error
            else:
                self._next = action
        return obs, reward, terminated, truncated, info


def _cost(value: Any, name: str) -> float:
    if isinstance(value, bool) or not (isinstance(value, (int, float)) and 0 <= value < np.inf):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


def _capped(grip: float) -> float:
    """y*/W as the agents observe it: at most ``GRIP_MAX``, which also stands for no form
    closure (``inf`` in the env's info, ``nan`` from ``grip_if_closed``)."""
    return min(grip, GRIP_MAX) if math.isfinite(grip) else GRIP_MAX
