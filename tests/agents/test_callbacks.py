"""Training callbacks: the critic's warm-up freezes the actor, and only the actor, until its
step count, through the zoo's callback list as a config names it."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from rl_zoo3.utils import get_callback_list
from stable_baselines3 import PPO

from agents.callbacks import CriticWarmup


def _parameters(policy) -> dict[str, np.ndarray]:
    return {name: p.detach().numpy().copy() for name, p in policy.named_parameters()}


def _changed(before: dict, after: dict) -> set[str]:
    return {name for name in before if not np.array_equal(before[name], after[name])}


def _is_actor(name: str) -> bool:
    return name.startswith(("mlp_extractor.policy_net", "action_net")) or name == "log_std"


def test_critic_warmup_trains_the_critic_alone_until_its_steps():
    model = PPO(
        "MlpPolicy", "Pendulum-v1", n_steps=64, batch_size=32, n_epochs=2, seed=0,
        policy_kwargs={"net_arch": [8]},
    )  # fmt: skip
    names = set(_parameters(model.policy))
    actor = {name for name in names if _is_actor(name)}
    assert "log_std" in actor and actor != names  # the split covers both heads
    warmup = CriticWarmup(steps=128)
    start = _parameters(model.policy)
    model.learn(128, callback=warmup)  # two rollouts, ending by the warm-up's end
    warmed = _parameters(model.policy)
    assert _changed(start, warmed) == names - actor  # every critic parameter, no actor one
    model.learn(64, callback=warmup, reset_num_timesteps=False)  # past it: all train
    assert _changed(warmed, _parameters(model.policy)) == names
    assert all(p.requires_grad for p in model.policy.parameters())


def test_critic_warmup_of_zero_steps_freezes_nothing():
    model = PPO("MlpPolicy", "Pendulum-v1", n_steps=64, batch_size=32, n_epochs=1, seed=0)
    start = _parameters(model.policy)
    model.learn(64, callback=CriticWarmup(steps=0))
    assert _changed(start, _parameters(model.policy)) == set(start)


def test_critic_warmup_is_named_in_a_config_entry():
    (callback,) = get_callback_list({"callback": [{"agents.callbacks.CriticWarmup": {"steps": 5}}]})
    assert isinstance(callback, CriticWarmup) and callback.steps == 5


@pytest.mark.parametrize("steps", [-1, float("nan"), float("inf"), "10", True, None])
def test_critic_warmup_refuses_bad_steps(steps):
    message = f"CriticWarmup steps must be a finite number >= 0, got {steps!r}"
    with pytest.raises(ValueError, match=message):
        CriticWarmup(steps=steps)
