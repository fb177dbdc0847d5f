"""Deterministic actions from an RLlib PPO checkpoint of ``agents.train_rllib``.

The observation goes through the checkpoint's env-to-module connectors (the observation
filter frozen at its trained statistics), ``RLModule.forward_inference`` and the
module-to-env connectors (the distribution's deterministic action, unsquashed and clipped
to the action space), as RLlib's env runners do with ``explore=False``.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import numpy as np

from agents.config import load_config

#: The checkpoint's folder inside an ``agents.train_rllib`` run directory.
CHECKPOINT_DIR = "checkpoint"


def load_run(path: str | Path) -> tuple[Path, str, dict[str, Any]]:
    """``(checkpoint directory, env id, config entry)`` of a run directory or of its
    ``checkpoint/``; fails naming the path when either is missing."""
    path = Path(path)
    checkpoint = path / CHECKPOINT_DIR if (path / CHECKPOINT_DIR).is_dir() else path
    if not (checkpoint / "rllib_checkpoint.json").is_file():
        raise ValueError(f"{str(path)!r} is not an RLlib checkpoint or a run directory")
    config = checkpoint.parent / "config.yml"
    if not config.is_file():
        raise ValueError(f"{str(path)!r}: no config.yml beside the checkpoint")
    ((env_id, entry),) = load_config(config).items()
    if importlib.util.find_spec("ray") is None:
        raise ValueError(f"{str(path)!r}: evaluating an RLlib checkpoint needs ray[rllib]")
    return checkpoint, env_id, entry


class RLlibPolicy:
    """The trained module and connectors of a checkpoint; ``act(obs)`` is deterministic.

    Each observation is a fresh one-step episode: right for the stateless (MLP) modules
    that ``configs/rllib_ppo.yml`` builds.
    """

    def __init__(self, checkpoint: str | Path) -> None:
        from ray.rllib.connectors.env_to_module import EnvToModulePipeline, MeanStdFilter
        from ray.rllib.connectors.module_to_env import ModuleToEnvPipeline
        from ray.rllib.core import (
            COMPONENT_ENV_RUNNER,
            COMPONENT_ENV_TO_MODULE_CONNECTOR,
            COMPONENT_LEARNER,
            COMPONENT_LEARNER_GROUP,
            COMPONENT_MODULE_TO_ENV_CONNECTOR,
            COMPONENT_RL_MODULE,
            DEFAULT_MODULE_ID,
        )
        from ray.rllib.core.rl_module.rl_module import RLModule

        checkpoint = Path(checkpoint).resolve()
        learner = checkpoint / COMPONENT_LEARNER_GROUP / COMPONENT_LEARNER
        self.module = RLModule.from_checkpoint(learner / COMPONENT_RL_MODULE / DEFAULT_MODULE_ID)
        runner = checkpoint / COMPONENT_ENV_RUNNER
        self.env_to_module = EnvToModulePipeline.from_checkpoint(
            runner / COMPONENT_ENV_TO_MODULE_CONNECTOR
        )
        self.module_to_env = ModuleToEnvPipeline.from_checkpoint(
            runner / COMPONENT_MODULE_TO_ENV_CONNECTOR
        )
        for i, piece in enumerate(self.env_to_module.connectors):
            if isinstance(piece, MeanStdFilter):  # same statistics, no further updates
                frozen = MeanStdFilter(
                    de_mean_to_zero=piece.de_mean_to_zero,
                    de_std_to_one=piece.de_std_to_one,
                    clip_by_value=piece.clip_by_value,
                    update_stats=False,
                )
                # Spaces after construction: MeanStdFilter's constructor cannot take them.
                frozen.input_observation_space = piece.input_observation_space
                frozen.input_action_space = piece.input_action_space
                frozen.set_state(piece.get_state())
                self.env_to_module.connectors[i] = frozen
        self.observation_space = self.env_to_module.input_observation_space
        self.action_space = self.env_to_module.input_action_space

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The deterministic action for one observation."""
        import torch
        from ray.rllib.core.columns import Columns
        from ray.rllib.env.single_agent_episode import SingleAgentEpisode

        episode = SingleAgentEpisode(
            observation_space=self.observation_space, action_space=self.action_space
        )
        episode.add_env_reset(observation=obs)
        shared: dict[str, Any] = {}
        batch = self.env_to_module(
            rl_module=self.module, batch={}, episodes=[episode], explore=False, shared_data=shared
        )
        with torch.no_grad():
            out = self.module.forward_inference(batch)
        out = self.module_to_env(
            rl_module=self.module, batch=out, episodes=[episode], explore=False, shared_data=shared
        )
        actions = out.get(Columns.ACTIONS_FOR_ENV, out[Columns.ACTIONS])
        return np.asarray(actions[0], dtype=self.action_space.dtype)
