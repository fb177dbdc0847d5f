"""The wrapper ``gymnasium.make`` puts outermost on ``FrictionlessGrasp-v0``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym


class RestoreOnError(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The outermost wrapper ``gymnasium.make`` puts on ``FrictionlessGrasp-v0``: a ``reset``
    or ``step`` that raises (refused input) leaves the wrappers inside it as they were.

    gymnasium's wrappers note a call before passing it on: ``PassiveEnvChecker`` marks its
    first-reset check done, ``TimeLimit`` zeroes its step count, ``OrderEnforcing`` marks the
    env reset. After a refused first reset the checker has no reset data for its first-step
    check (a ``TypeError`` at every step); after a refused reset mid-episode the time limit
    starts over. The env changes nothing on a refused call; this restores the attributes of
    the wrappers in between.
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        self._inner = []  # the wrappers between this one and the env, fixed once made
        inner = env
        while isinstance(inner, gym.Wrapper):
            self._inner.append(inner)
            inner = inner.env

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        return self._restoring(self.env.reset, seed=seed, options=options)

    def step(self, action: Any):
        return self._restoring(self.env.step, action)

    def _restoring(self, call: Callable, *args: Any, **kwargs: Any) -> Any:
        saved = [(wrapper, vars(wrapper).copy()) for wrapper in self._inner]
        try:
            return call(*args, **kwargs)
        except Exception:
            for wrapper, attributes in saved:
                vars(wrapper).clear()
                vars(wrapper).update(attributes)
            raise
