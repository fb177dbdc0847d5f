"""The batched env against single envs in lockstep, shared by the tests of the env's
arguments (friction, uncertainty)."""

from __future__ import annotations

from collections.abc import Iterator

import gymnasium as gym
import numpy as np


def lockstep(env_id: str, n: int, steps: int, **kwargs) -> Iterator[tuple[int, dict, dict, bool]]:
    """Step ``make_vec``'s batched env of ``n`` sub-envs and ``n`` single envs (sub-env ``i``
    reset with seed ``5 + i``, a single env again without one after an end) with the same
    random actions, the fingers closing. Checks that every reset observation, reward and
    observation is the single env's; yields each single env's step as ``(i, its info, the
    batch's infos, whether its episode ended)`` for the caller's checks."""
    vec = gym.make_vec(env_id, num_envs=n, **kwargs)
    singles = [gym.make(env_id, **kwargs) for _ in range(n)]
    observations, _ = vec.reset(seed=5)
    for i, env in enumerate(singles):
        np.testing.assert_array_equal(env.reset(seed=5 + i)[0], observations[i])
    rng = np.random.default_rng(1)
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (n, 5)).astype(np.float32)
        actions[:, :2] = np.abs(actions[:, :2])
        observations, rewards, _, _, infos = vec.step(actions)
        for i, env in enumerate(singles):
            obs, reward, term, trunc, info = env.step(actions[i])
            assert reward == rewards[i]
            if term or trunc:
                obs, _ = env.reset()
            np.testing.assert_array_equal(obs, observations[i])
            yield i, info, infos, term or trunc
