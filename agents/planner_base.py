"""The base of the agents that play beside the scripted planner
(:class:`agents.scripted.ScriptedPolicy`; the agents are in :mod:`agents.planner_agents`): a
wrapper of a palm-controlled lifting env that plans at every reset, redrawing with
``redraw`` the shapes its agent does not play, and what an agent of a kind calls at test
time; and the agent a training entry's ``env_wrapper`` names."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from agents.config import wrapper_specs
from agents.scripted import ScriptedPolicy
from grasp_env.errors import ComputationError

#: Resets at most per episode with ``redraw`` before a shape is kept.
MAX_REDRAWS = 20


class PlannerAgent(gym.Wrapper):
    """The planner on a palm-controlled env, planned at every reset (the shared part of the
    agents that play beside it).

    Args:
        env: a ``FrictionlessGrasp-v0`` env with ``palm_control`` (five actions).
        redraw: at reset, redraw the shapes :meth:`_keeps` refuses (up to ``MAX_REDRAWS``
            times); for training.
        fallbacks: whether the planner uses its fallbacks where lifting gets stuck.

    Raises:
        ValueError: an env without palm control.
    """

    #: What an agent of this kind calls at test time beyond its network and the env's own
    #: step (one of ``agents.models.TEST_TIMES``): the planner, which plans at every reset.
    test_time = "planner"
    #: Arguments that, when true, make the agent also call the exact simulator on copies of
    #: the env's state at test time (test time ``"simulator"``).
    simulator_options: tuple[str, ...] = ()

    @classmethod
    def test_time_of(cls, kwargs: dict[str, Any]) -> str:
        """What an agent of this kind made with ``kwargs`` calls at test time: ``"simulator"``
        where one of its :attr:`simulator_options` is set, else :attr:`test_time`."""
        return "simulator" if any(kwargs.get(k) for k in cls.simulator_options) else cls.test_time

    def __init__(self, env: gym.Env, redraw: bool, fallbacks: bool) -> None:
        super().__init__(env)
        if not env.unwrapped.palm_control:
            raise ValueError(
                f"{type(self).__name__} needs palm_control=True (five actions), got False"
            )
        self.redraw = bool(redraw)
        self.policy = ScriptedPolicy(env, fallbacks=fallbacks)
        #: The planner's failure (``ComputationError``: a move the simulator cannot make) in
        #: this episode, if it failed.
        self.planner_error: str | None = None

    def _keeps(self, lifts: bool) -> bool:
        """Whether ``redraw`` keeps a shape whose lifting from the placement does (``lifts``)
        or does not reach form closure."""
        raise NotImplementedError

    def _raises(self) -> bool:
        """Whether a planner failure is raised (else recorded in ``planner_error``)."""
        return False

    def _reset_planned(self, seed, options) -> tuple[np.ndarray, dict, bool]:
        """Reset and plan (redrawing with ``redraw``): ``(obs, info, lifts)``."""
        obs, info = self.env.reset(seed=seed, options=options)
        redraws = MAX_REDRAWS if self.redraw else 0
        while True:
            lifts = self._plan(obs, info)
            if self._keeps(lifts) or not redraws:
                return obs, info, lifts
            redraws -= 1
            obs, info = self.env.reset(options=options)

    def _plan(self, obs, info) -> bool:
        """Plan the episode; whether lifting from the placement reaches form closure (a
        planner failure counts as not)."""
        self.planner_error = None
        try:
            self.policy.reset(obs, info)
        except ComputationError as exc:
            if self._raises():
                raise
            self.planner_error = f"{type(exc).__name__}: {exc}"
            return False
        return bool(self.policy.plan.success)

    def _next_action(self, obs: np.ndarray) -> np.ndarray | None:
        """The planner's next action; None where it fails (a re-plan), recorded in
        ``planner_error``."""
        try:
            return self.policy.act(obs)
        except ComputationError as exc:
            if self._raises():
                raise
            self.planner_error = f"{type(exc).__name__}: {exc}"
            return None


def planner_wrapper(entry: dict[str, Any]) -> tuple[type[PlannerAgent], dict] | None:
    """The wrapper that plays a training entry's policy beside the planner (the
    :class:`PlannerAgent` its ``env_wrapper`` names), with the arguments for playing it
    (``redraw`` off: every shape is played as drawn, the planner with its fallbacks where it
    has them); None for an entry without one."""
    for cls, kwargs in wrapper_specs(entry):
        if issubclass(cls, PlannerAgent):
            return cls, {**kwargs, "redraw": False}
    return None
