"""A hand-over agent: the scripted planner where its lifting works, a learned policy where
it gets stuck.

:class:`PlannerHandover` wraps a palm-controlled lifting env. At reset the planner plans
lifting from the env's placement with the palm fixed (:class:`agents.scripted.ScriptedPolicy`
without fallbacks, a few hundredths of a second). Where that plan reaches form closure, the
planner plays the episode and the agent's actions are ignored; where it gets stuck, the agent
plays the whole episode, in place of the planner's re-placement and exploratory search (a
search of up to 20,000 simulated moves, seconds of CPU a shape). The question it answers: can
a policy trained on the stuck shapes replace that search?

Observation and action are the env's, so a model trained on the plain lifting env plays
here too. With ``redraw`` (training), shapes the planner lifts are redrawn at reset: the
agent trains only on the shapes it plays.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from agents.residual import MAX_REDRAWS
from agents.scripted import ScriptedPolicy
from grasp_env.arguments import real_vector
from grasp_env.errors import ComputationError


class PlannerHandover(gym.Wrapper):
    """The planner plays where its lifting from the env's placement reaches form closure, the
    agent everywhere else (``info["planner_plays"]`` says which, at reset and every step).

    Args:
        env: a ``FrictionlessGrasp-v0`` env with ``palm_control`` (five actions).
        redraw: at reset, redraw shapes the planner lifts (up to ``MAX_REDRAWS`` times); for
            training. A planning failure (``ComputationError``) at reset counts as stuck, and
            one mid-episode (a re-plan) hands the rest of the episode to the agent (reported
            once as ``info["planner_error"]``).

    Raises:
        ValueError: an env without palm control.
    """

    def __init__(self, env: gym.Env, redraw: bool = False) -> None:
        super().__init__(env)
        if not env.unwrapped.palm_control:
            raise ValueError("PlannerHandover needs palm_control=True (five actions), got False")
        self.redraw = bool(redraw)
        self.policy = ScriptedPolicy(env, fallbacks=False)
        self.planner_plays = False
        self._next = np.zeros(5, np.float32)

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        redraws = MAX_REDRAWS if self.redraw else 0
        while self._planner_lifts(obs, info) and redraws:
            redraws -= 1
            obs, info = self.env.reset(options=options)
        if self.planner_plays:
            self._next = self.policy.act(obs)
        return obs, {**info, "planner_plays": self.planner_plays}

    def _planner_lifts(self, obs, info) -> bool:
        """Plan lifting from the placement; whether it reaches form closure (sets
        ``planner_plays``)."""
        try:
            self.policy.reset(obs, info)
            self.planner_plays = bool(self.policy.plan.success)
        except ComputationError:
            self.planner_plays = False
        return self.planner_plays

    def step(self, action):
        sent = action
        if self.planner_plays:
            real_vector(action, "action", 5)  # ignored, but checked as the env would
            sent = self._next
        obs, reward, terminated, truncated, info = self.env.step(sent)
        info = {**info, "planner_plays": self.planner_plays}
        if self.planner_plays and not (terminated or truncated):
            try:
                self._next = self.policy.act(obs)
            except ComputationError as exc:  # a re-plan failed: the agent goes on
                self.planner_plays = False
                info["planner_error"] = f"{type(exc).__name__}: {exc}"
        return obs, reward, terminated, truncated, info
