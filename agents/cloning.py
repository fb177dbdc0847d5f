"""Behaviour cloning of the expert into a stable-baselines3 PPO policy: the model and its
observation normalization (the data's statistics), the actor's mean fitted to the expert's
actions by weighted mean squared error, and the saved model directory (the training entry
that ``agents.evaluate`` and ``agents.train_ppo -i`` read)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.expert import ENV_ID, make_env

#: Floor of the saved observation variance: entries that hardly vary in the data (padding,
#: flags) are not blown up where they do vary.
MIN_VAR = 1e-4
#: The model's training entry (zoo format; the lifting entry's reward and PPO settings, for
#: a PPO fine-tune with ``agents.train_ppo -i``).
ENTRY: dict[str, Any] = {
    "env_kwargs": {
        "hand_features": True,
        "reward_form_closure_weight": 1.0,
        "reward_hold_weight": 1.0,
        "reward_grip_weight": 0.5,
        "reward_lift_weight": 10.0,
    },
    "env_wrapper": ["agents.wrappers.TrainingInfo"],
    "n_envs": 2,
    "n_timesteps": 0,
    "policy": "MlpPolicy",
    "normalize": "dict(norm_obs=True, norm_reward=True)",
    "n_steps": 1024,
    "batch_size": 256,
    "n_epochs": 10,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "learning_rate": 1e-4,
    "ent_coef": 0.0,
    "clip_range": 0.2,
    "monitor_kwargs": "dict(info_keywords=('is_success',))",
    "callback": ["agents.callbacks.RewardTermsCallback"],
}


def new_model(net_arch: list[int], log_std_init: float = -1.0, seed: int = 0):
    """A fresh PPO model on the training env (``MlpPolicy``, separate actor and critic
    networks of ``net_arch``) and its ``VecNormalize`` (statistics set by
    :func:`set_normalization`)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: make_env("scene")]), gamma=ENTRY["gamma"])
    kwargs = {k: ENTRY[k] for k in ("n_steps", "batch_size", "n_epochs", "gamma", "gae_lambda")}
    kwargs.update(learning_rate=ENTRY["learning_rate"], ent_coef=0.0, clip_range=0.2)
    policy_kwargs = {
        "net_arch": {"pi": list(net_arch), "vf": list(net_arch)},
        "log_std_init": log_std_init,
    }
    model = PPO("MlpPolicy", venv, policy_kwargs=policy_kwargs, seed=seed, device="cpu", **kwargs)
    return model, venv


def set_normalization(norm, obs: np.ndarray) -> None:
    """``norm``'s observation statistics from the data (variance floored at ``MIN_VAR``);
    frozen."""
    norm.obs_rms.mean = obs.mean(axis=0).astype(np.float64)
    norm.obs_rms.var = np.maximum(obs.var(axis=0), MIN_VAR).astype(np.float64)
    norm.obs_rms.count = float(len(obs))
    norm.training = False


def actor_mean(policy, x):
    """The actor's mean action (before clipping) for normalized observations ``x``."""
    features = policy.extract_features(x, policy.pi_features_extractor)
    return policy.action_net(policy.mlp_extractor.forward_actor(features))


def behaviour_clone(
    model,
    norm,
    obs: np.ndarray,
    act: np.ndarray,
    epochs: int,
    batch_size: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
    val_fraction: float = 0.1,
    log=None,
    weights: np.ndarray | None = None,
) -> list[dict[str, float]]:
    """Fit the actor's mean to ``act`` by mean squared error (Adam, a cosine-decayed
    learning rate); returns per epoch ``{"epoch", "train_loss", "val_loss"}`` (the loss
    over a held-out ``val_fraction`` of the samples, nan without one); ``weights``: each
    sample's weight in the training loss (default: all 1)."""
    import torch

    policy = model.policy
    x_all = torch.as_tensor(norm.normalize_obs(obs), dtype=torch.float32)
    y_all = torch.as_tensor(act, dtype=torch.float32)
    w_all = torch.as_tensor(np.ones(len(act)) if weights is None else weights, dtype=torch.float32)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(obs))
    n_val = int(len(obs) * val_fraction) if len(obs) >= 20 else 0
    val, train = order[:n_val], order[n_val:]
    params = [
        *policy.features_extractor.parameters(),
        *policy.mlp_extractor.policy_net.parameters(),
        *policy.action_net.parameters(),
    ]
    params = list(dict.fromkeys(params))
    optimizer = torch.optim.Adam(params, lr=lr)
    steps = epochs * max(1, math.ceil(len(train) / batch_size))
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, steps)
    torch.manual_seed(seed)
    history = []
    policy.train()
    for epoch in range(1, epochs + 1):
        perm = rng.permutation(train)
        total = 0.0
        for i in range(0, len(perm), batch_size):
            idx = torch.as_tensor(perm[i : i + batch_size])
            err = ((actor_mean(policy, x_all[idx]) - y_all[idx]) ** 2).mean(dim=1)
            loss = (w_all[idx] * err).sum() / w_all[idx].sum()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
            total += loss.item() * len(idx)
        with torch.no_grad():
            val_loss = (
                float(((actor_mean(policy, x_all[val]) - y_all[val]) ** 2).mean())
                if n_val
                else math.nan
            )
        row = {"epoch": epoch, "train_loss": total / max(1, len(train)), "val_loss": val_loss}
        history.append(row)
        if log is not None:
            log(f"  epoch {epoch}/{epochs}: train loss {row['train_loss']:.4f}, val {val_loss:.4f}")
    policy.eval()
    return history


def mse(model, norm, obs: np.ndarray, act: np.ndarray) -> float:
    """Mean squared error of the actor's mean on ``(obs, act)``."""
    import torch

    with torch.no_grad():
        x = torch.as_tensor(norm.normalize_obs(obs), dtype=torch.float32)
        return float(((actor_mean(model.policy, x) - torch.as_tensor(act)) ** 2).mean())


def save_model(model, norm, out: Path, stats: dict[str, Any], net_arch: list[int]) -> None:
    """Write the model directory: ``model.zip``, ``vecnormalize.pkl``, ``config.yml`` (the
    entry of :data:`ENV_ID`) and ``train_stats.json``."""
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    norm.save(str(out / "vecnormalize.pkl"))
    entry = dict(ENTRY)
    entry["policy_kwargs"] = (
        f"dict(net_arch=dict(pi={list(net_arch)}, vf={list(net_arch)}), "
        f"log_std_init={model.policy.log_std.mean().item():.3g})"
    )
    (out / "config.yml").write_text(yaml.safe_dump({ENV_ID: entry}, sort_keys=False))
    (out / "train_stats.json").write_text(json.dumps(stats, indent=1) + "\n")


def sample_weights(data: dict[str, np.ndarray], dagger_weight: float) -> np.ndarray:
    """Each sample's loss weight: 1 for the expert's episodes (round 0), ``dagger_weight``
    for the DAgger labels."""
    return np.where(data["round"] > 0, dagger_weight, 1.0)
