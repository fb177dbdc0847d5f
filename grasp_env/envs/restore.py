"""The wrapper ``gymnasium.make`` puts outermost on ``FrictionlessGrasp-v0``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym

#: Wrappers (``module.qualname``) whose ``step`` passes the call on before it changes any
#: attribute of its own, so that a step refused inside leaves them as they were: gymnasium's
#: ``OrderEnforcing`` and ``TimeLimit`` (it counts a step once the step returns), and the
#: ``TimeLimit`` rl_zoo3 puts in its place.
STEP_FORWARDS_FIRST = frozenset({
    "gymnasium.wrappers.common.OrderEnforcing",
    "gymnasium.wrappers.common.TimeLimit",
    "rl_zoo3.gym_patches.PatchedTimeLimit",
})  # fmt: skip
_ENV_CHECKER = "gymnasium.wrappers.common.PassiveEnvChecker"


def step_forwards_first(wrapper: gym.Wrapper) -> bool:
    """Whether ``wrapper``'s next ``step`` changes nothing of its own before it passes the
    call on: one of :data:`STEP_FORWARDS_FIRST`, or gymnasium's ``PassiveEnvChecker`` once
    it has checked a first step (it marks that check done before running it)."""
    cls = type(wrapper)
    name = f"{cls.__module__}.{cls.__qualname__}"
    if name == _ENV_CHECKER:
        return bool(wrapper.checked_step)
    return name in STEP_FORWARDS_FIRST


class RestoreOnError(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The outermost wrapper ``gymnasium.make`` puts on ``FrictionlessGrasp-v0``: a ``reset``
    or ``step`` that raises (refused input) leaves the wrappers inside it as they were.

    gymnasium's wrappers note a call before passing it on: ``PassiveEnvChecker`` marks its
    first-reset check done, ``TimeLimit`` zeroes its step count, ``OrderEnforcing`` marks the
    env reset. After a refused first reset the checker has no reset data for its first-step
    check (a ``TypeError`` at every step); after a refused reset mid-episode the time limit
    starts over. The env changes nothing on a refused call; this restores the attributes of
    the wrappers in between.

    Steps pass straight through once every wrapper inside passes a step on before it changes
    anything of its own (:func:`step_forwards_first`): a refused step then changes nothing
    anywhere, and saving the attributes would cost about a tenth of a free step.
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        self._inner = []  # the wrappers between this one and the env, fixed once made
        inner = env
        while isinstance(inner, gym.Wrapper):
            self._inner.append(inner)
            inner = inner.env
        self._steps_pass_through = False  # set once no wrapper inside needs saving for a step

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        return self._restoring(self.env.reset, seed=seed, options=options)

    def step(self, action: Any):
        if self._steps_pass_through:
            return self.env.step(action)
        result = self._restoring(self.env.step, action)
        self._steps_pass_through = all(step_forwards_first(w) for w in self._inner)
        return result

    def _restoring(self, call: Callable, *args: Any, **kwargs: Any) -> Any:
        saved = [(wrapper, vars(wrapper).copy()) for wrapper in self._inner]
        try:
            return call(*args, **kwargs)
        except Exception:
            for wrapper, attributes in saved:
                vars(wrapper).clear()
                vars(wrapper).update(attributes)
            raise
