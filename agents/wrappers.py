"""Training-only wrappers that ``configs/ppo.yml`` names (``env_wrapper``), and the reward
terms they and :mod:`agents.callbacks` read from an info.

The evaluation commands and the policies' own envs see the env's own reward and whole info;
these wrappers shape the reward (:class:`ApproachShaping`) or thin the info (:class:`TrainingInfo`)
for training only.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

#: Prefix of the info keys that hold a reward term (the env's, and shaping terms of wrappers).
REWARD_PREFIX = "reward_"
#: Info keys :class:`TrainingInfo` passes on where a step has them.
PASSED_ON = ("sim_error", "episode")


def reward_terms(info: dict) -> dict[str, float]:
    """The reward terms of a step's info: ``{"reward_<term>": value}``."""
    return {key: value for key, value in info.items() if key.startswith(REWARD_PREFIX)}


class ApproachShaping(gym.Wrapper):
    """Potential-based shaping toward a grasp (training only; the optimal policy is unchanged).

    Adds ``gamma * Phi(s') - Phi(s)`` to the reward, with ``Phi = -approach * |p_P| / w +
    touch * (hand bodies touching the object)``: ``p_P`` is the object's centre in the palm
    frame (observation entries 9-10), so the palm is drawn toward the object and contacts
    are encouraged. ``Phi = 0`` at a terminal state, as for the env's lift term. The term is
    reported as ``info["reward_approach"]``.
    """

    def __init__(self, env: gym.Env, approach: float = 1.0, touch: float = 0.2, gamma=0.99):
        super().__init__(env)
        self.approach, self.touch, self.gamma = float(approach), float(touch), float(gamma)

    def _potential(self, obs: np.ndarray, info: dict) -> float:
        touching = {c["body"] for c in info["contacts"]} - {"support"}
        return -self.approach * float(np.hypot(obs[9], obs[10])) + self.touch * len(touching)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._phi = self._potential(obs, info)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        phi = 0.0 if terminated else self._potential(obs, info)
        shaping = self.gamma * phi - self._phi
        self._phi = phi
        return obs, reward + shaping, terminated, truncated, {**info, "reward_approach": shaping}


class TrainingInfo(gym.Wrapper):
    """Keeps of each step's info only what training reads: ``is_success``, the reward terms
    (shaping terms of inner wrappers included), and where present ``sim_error`` and
    ``Monitor``'s ``episode`` (the zoo puts ``env_wrapper`` outside the Monitor; SB3's episode
    statistics and its evaluation count episodes by it). SB3's vector envs copy every info at
    every step (DummyVecEnv deep-copies them, SubprocVecEnv pickles them); the env's whole
    info (poses, contacts with their points and normals, events) made that copy about a fifth
    of PPO's time. Named last in ``env_wrapper``, so that the wrappers inside it still see
    everything."""

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        kept = reward_terms(info)
        kept["is_success"] = info["is_success"]
        for key in PASSED_ON:
            if key in info:
                kept[key] = info[key]
        return obs, reward, terminated, truncated, kept
