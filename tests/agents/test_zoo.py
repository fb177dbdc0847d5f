"""rl-baselines3-zoo runs configs/ppo.yml unchanged, on every registered env id."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("rl_zoo3")

from agents.models import load_agent
from agents.wrappers import ApproachShaping, TrainingInfo
from grasp_env.envs import ENV_KWARGS

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "configs" / "ppo.yml"
IDS = list(ENV_KWARGS)


@pytest.mark.parametrize("env_id", IDS, ids=IDS)
def test_zoo_reads_the_entry_of_each_id(env_id, tmp_path):
    from rl_zoo3.exp_manager import ExperimentManager

    manager = ExperimentManager(
        argparse.Namespace(), "ppo", env_id, str(tmp_path), config=str(CONFIG)
    )
    hyperparams, saved = manager.read_hyperparameters()
    assert saved["policy"] == "MlpPolicy"
    kwargs, wrapper, callbacks, _ = manager._preprocess_hyperparams(hyperparams)
    raw = yaml.safe_load(CONFIG.read_text())[env_id]
    assert manager.n_envs == 2 and manager.n_timesteps == raw["n_timesteps"] and manager.normalize
    assert manager.monitor_kwargs == {"info_keywords": ("is_success",)}
    assert manager.env_kwargs == raw["env_kwargs"]
    assert [type(c).__name__ for c in callbacks] == ["RewardTermsCallback"]
    assert callable(kwargs["learning_rate"]) and isinstance(kwargs["policy_kwargs"], dict)
    env = gym.make(env_id, **manager.env_kwargs)
    if wrapper is not None:
        env = wrapper(env)
    assert isinstance(env, TrainingInfo)  # last, so that the shaping sees the whole info
    assert isinstance(env.env, ApproachShaping) == (env_id == "FrictionlessGraspRandomShapes-v0")
    env.close()


@pytest.mark.slow
@pytest.mark.parametrize("env_id", IDS, ids=IDS)
def test_zoo_trains_each_id_from_the_readme_command(env_id, tmp_path):
    """``python -m rl_zoo3.train`` as the README gives it, for 2048 steps (two PPO updates of
    2 x 512 steps): it writes a model that loads and acts on the env id."""
    command = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        "ppo",
        "--env",
        env_id,
        "--gym-packages",
        "grasp_env",
        "--conf-file",
        "configs/ppo.yml",
        "--n-timesteps",
        "2048",
        "--seed",
        "0",
        "-f",
        str(tmp_path),
    ]
    done = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr[-3000:]
    run = tmp_path / "ppo" / f"{env_id}_1"
    assert (run / f"{env_id}.zip").is_file() and (run / env_id / "vecnormalize.pkl").is_file()
    assert "ep_reward_lift_mean" in done.stdout  # RewardTermsCallback, named in the config

    model, norm, name, entry = load_agent(run)
    assert name == f"{env_id}_1" and entry["env_id"] == env_id and norm is not None
    assert model.num_timesteps == 2048
    raw = yaml.safe_load(CONFIG.read_text())[env_id]
    assert entry["env_kwargs"] == {**ENV_KWARGS[env_id], **raw["env_kwargs"]}
    env = gym.make(env_id, **entry["env_kwargs"])
    obs, _ = env.reset(seed=0)
    for _ in range(3):
        action, _ = model.predict(norm.normalize_obs(obs), deterministic=True)
        assert env.action_space.contains(np.asarray(action, np.float32))
        obs, *_ = env.step(action)
    env.close()
