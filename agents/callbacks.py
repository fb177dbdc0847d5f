"""stable-baselines3 callbacks of training: the episode sums of the reward terms
(:class:`RewardTermsCallback`, which ``configs/ppo.yml`` names, so zoo runs log them too), the
critic's warm-up before a cloned actor is fine-tuned (:class:`CriticWarmup`), a progress line
every so many steps and a wall-time limit (:mod:`agents.train_ppo`)."""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from agents.wrappers import reward_terms


class RewardTermsCallback(BaseCallback):
    """Logs to TensorBoard the mean over the last 100 episodes of each reward term's episode
    sum (``rollout/ep_reward_<term>_mean``, from ``info["reward_<term>"]``, shaping terms of
    wrappers such as ``reward_approach`` included), beside SB3's ``rollout/ep_rew_mean``."""

    def _on_training_start(self) -> None:
        self._sums: list[dict[str, float]] = [{} for _ in range(self.training_env.num_envs)]
        self._episodes: deque[dict[str, float]] = deque(maxlen=100)

    def _on_step(self) -> bool:
        for sums, info, done in zip(
            self._sums, self.locals["infos"], self.locals["dones"], strict=True
        ):
            for key, value in reward_terms(info).items():
                sums[key] = sums.get(key, 0.0) + float(value)
            if done:
                self._episodes.append(dict(sums))
                sums.clear()
        return True

    def _on_rollout_end(self) -> None:
        keys = sorted({key for episode in self._episodes for key in episode})
        for key in keys:
            values = [episode.get(key, 0.0) for episode in self._episodes]
            self.logger.record(f"rollout/ep_{key}_mean", float(np.mean(values)))


class CriticWarmup(BaseCallback):
    """Trains only the value function on the rollouts of the first ``steps`` env steps.

    A network cloned from an expert (:mod:`agents.imitation`) has a good actor and an
    untrained critic. PPO's advantages come from the critic, so its first updates would move
    the actor by noise, away from the expert's actions. Here the actor (its layers, its
    action head and its log standard deviation) is frozen in the updates of the rollouts that
    end by ``steps``, and the critic learns the cloned policy's values first. Named in a
    config entry's ``callback`` list, ``- agents.callbacks.CriticWarmup: {steps: 200000}``.
    """

    def __init__(self, steps: int):
        super().__init__()
        if (
            isinstance(steps, bool)
            or not isinstance(steps, int | float)
            or not 0 <= steps < math.inf
        ):
            raise ValueError(f"CriticWarmup steps must be a finite number >= 0, got {steps!r}")
        self.steps = int(steps)

    def _actor_parameters(self) -> list:
        policy = self.model.policy
        log_std = getattr(policy, "log_std", None)  # continuous actions only
        return [
            *policy.mlp_extractor.policy_net.parameters(),
            *policy.action_net.parameters(),
            *([] if log_std is None else [log_std]),
        ]

    def _freeze(self, frozen: bool) -> None:
        for parameter in self._actor_parameters():
            parameter.requires_grad_(not frozen)

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:  # before the update of the rollout just collected
        warming = self.num_timesteps <= self.steps
        self._freeze(warming)
        self.logger.record("train/critic_warmup", float(warming))


class ProgressLines(BaseCallback):
    """Prints one line every ``every`` env steps: steps done, rate, time left, mean return of
    the last 100 episodes."""

    def __init__(self, every: int, total: int):
        super().__init__()
        self.every, self.total = int(every), int(total)

    def _on_training_start(self) -> None:
        self.start, self.next = time.perf_counter(), self.every

    def _on_step(self) -> bool:
        if self.num_timesteps < self.next:
            return True
        while self.next <= self.num_timesteps:
            self.next += self.every
        elapsed = time.perf_counter() - self.start
        rate = self.num_timesteps / max(elapsed, 1e-9)
        left = max(self.total - self.num_timesteps, 0) / max(rate, 1e-9)
        returns = [episode["r"] for episode in self.model.ep_info_buffer]
        mean = f", mean return {np.mean(returns):.2f}" if returns else ""
        print(
            f"{self.num_timesteps:,}/{self.total:,} steps "
            f"({100 * self.num_timesteps / self.total:.0f}%), {rate:.1f} steps/s, "
            f"{_minutes(elapsed)} elapsed, ~{_minutes(left)} left{mean}",
            flush=True,
        )
        return True


class WallTimeLimit(BaseCallback):
    """Stops training once ``max_seconds`` of wall time have passed (None: never)."""

    def __init__(self, max_seconds: float | None):
        super().__init__()
        self.max_seconds = max_seconds

    def _on_training_start(self) -> None:
        self.deadline = time.perf_counter() + (self.max_seconds or math.inf)

    def _on_step(self) -> bool:
        return time.perf_counter() < self.deadline


def timed(callback: BaseCallback) -> list[float]:
    """Adds up the wall time of ``callback``'s steps (the periodic evaluation) in the list it
    returns, so that it can be kept out of the training steps/s."""
    seconds = [0.0]
    on_step = callback._on_step

    def timed_step() -> bool:
        start = time.perf_counter()
        try:
            return on_step()
        finally:
            seconds[0] += time.perf_counter() - start

    callback._on_step = timed_step
    return seconds


def _minutes(seconds: float) -> str:
    minutes = int(seconds // 60)
    return (
        f"{minutes // 60}h{minutes % 60:02d}m"
        if minutes >= 60
        else f"{minutes}m{int(seconds % 60):02d}s"
    )
