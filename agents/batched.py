"""The batched env (:class:`grasp_env.envs.vector.FrictionlessGraspVectorEnv`) as a
stable-baselines3 ``VecEnv``: ``n_envs`` episodes stepped by one compiled call, for SB3's
algorithms and wrappers (``VecNormalize``, ``VecMonitor``).

SB3's conventions: ``reset()`` returns the observations alone, ``step`` returns ``dones``
(terminated or truncated) and a list of info dicts, and a finished episode is reset at once,
its last observation in ``infos[i]["terminal_observation"]`` and
``infos[i]["TimeLimit.truncated"]`` set where the time limit ended it. Every info has
``is_success`` (form closure with the object off the support), and the reward's terms.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from grasp_env.arguments import integer
from grasp_env.envs import VECTOR_ENTRY_POINT
from grasp_env.envs.vector import INFO_FLAGS, INFO_VALUES, MAX_ENVS, FrictionlessGraspVectorEnv


class BatchedVecEnv(VecEnv):
    """An SB3 ``VecEnv`` over a :class:`FrictionlessGraspVectorEnv` (``venv``)."""

    def __init__(self, venv: FrictionlessGraspVectorEnv) -> None:
        self.venv = venv
        self.render_mode = venv.render_mode
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        seeds = self._seeds if any(s is not None for s in self._seeds) else None
        options = self._options[0] if self._options and self._options[0] else None
        try:
            obs, _ = self.venv.reset(seed=seeds, options=options)
        finally:  # used once, even by a reset that refuses them: the next one can go on
            self._reset_seeds()
            self._reset_options()
        return obs

    def seed(self, seed: int | None = None) -> list[int | None]:
        """SB3's seeding (sub-env ``i`` gets ``seed + i`` at the next reset), ``seed`` None
        or an integer >= 0 (``ValueError`` otherwise)."""
        return super().seed(None if seed is None else integer(seed, "seed", 0))

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        out = [{} for _ in range(self.num_envs)]
        final = infos.get("final_info", infos)
        keys = [k for k in (*INFO_FLAGS, *INFO_VALUES) if k in final]
        columns = {k: final[k].tolist() for k in keys}
        for i, info in enumerate(out):
            for k in keys:
                info[k] = columns[k][i]
        errors = final.get("sim_error")
        if errors is not None:
            for i in np.flatnonzero(final["_sim_error"]):
                out[i]["sim_error"] = errors[i]
        for i in np.flatnonzero(dones):
            out[i]["terminal_observation"] = infos["final_obs"][i]
            out[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, rewards.astype(np.float32), dones, out

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> list[np.ndarray]:
        frames = self.venv.render()
        return [] if frames is None else list(frames)

    def _indices(self, indices) -> list[int]:
        """The sub-envs ``indices`` names (None: all), each checked to be one."""
        if indices is None:
            return list(range(self.num_envs))
        try:
            chosen = [indices] if isinstance(indices, int | np.integer) else list(indices)
        except TypeError:  # neither an index nor a sequence of them
            chosen = [indices]
        return [integer(i, "indices", 0, most=self.num_envs - 1) for i in chosen]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.venv.sub_env(i), attr_name) for i in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for i in self._indices(indices):
            setattr(self.venv.envs[i], attr_name, value)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        return [
            getattr(self.venv.sub_env(i), method_name)(*args, **kwargs)
            for i in self._indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type, indices=None) -> list[bool]:
        return [False for _ in self._indices(indices)]


def make_vec_env(
    env_id: str, n_envs: int = 1, seed: int | None = 0, threads: int | None = None,
    **env_kwargs: Any,
) -> BatchedVecEnv:  # fmt: skip
    """``n_envs`` episodes of ``env_id`` (``gymnasium.make_vec``'s batched env, with
    ``env_kwargs`` over the registered ones) as an SB3 ``VecEnv``, its sub-env ``i`` seeded
    with ``seed + i`` at the first reset (SB3's ``make_vec_env`` convention). ``ValueError``
    names ``n_envs`` below 1, ``seed`` other than None or an integer >= 0, and an ``env_id``
    that has no batched env."""
    n_envs = integer(n_envs, "n_envs", 1, most=MAX_ENVS)  # named as the caller named it
    seed = None if seed is None else integer(seed, "seed", 0)
    if "num_envs" in env_kwargs:
        raise TypeError("make_vec_env takes the number of envs as n_envs, not num_envs")
    try:
        spec = gym.spec(env_id) if isinstance(env_id, str) else None
    except gym.error.Error:
        spec = None
    if spec is None or spec.vector_entry_point != VECTOR_ENTRY_POINT:
        raise ValueError(f"env_id {env_id!r} has no batched env (not one of grasp_env's ids)")
    venv = gym.make_vec(env_id, num_envs=n_envs, threads=threads, **env_kwargs)
    vec = BatchedVecEnv(venv)
    if seed is not None:
        vec.seed(seed)
    return vec
