"""An entry of ``configs/rllib_ppo.yml`` as RLlib sees it: the entry checked, the env every
env runner builds from it (:class:`EntryEnv`), the observation filter and success-rate
callback, the ``PPOConfig`` of the entry, and the simulator compiled once before Ray starts."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import gymnasium as gym

from agents.config import wrapper_specs

if TYPE_CHECKING:
    from ray.rllib.algorithms.ppo import PPOConfig

#: PPOConfig methods whose keyword arguments an entry may set, section by section.
SECTIONS = ("env_runners", "training", "rl_module")
#: Keys of an entry besides the sections.
ENTRY_KEYS = ("env_kwargs", "env_wrapper", "n_timesteps", "normalize_obs")
#: Settings the command line owns.
COMMAND_LINE_KEYS = ("num_env_runners",)
#: Episodes over which the success rate is averaged (RLlib's window for episode returns).
SUCCESS_WINDOW = 100


def get_entry(config: dict[str, dict[str, Any]], env_id: str) -> dict[str, Any]:
    """The entry of ``env_id`` in a config that :func:`agents.config.load_config` read,
    checked; fails naming the bad key."""
    if env_id not in config:
        raise ValueError(f"--env {env_id!r} is not in the config; choose from {sorted(config)}")
    entry = config[env_id]
    unknown = set(entry) - set(ENTRY_KEYS) - set(SECTIONS)
    if unknown:
        raise ValueError(
            f"entry {env_id!r}: unknown keys {sorted(unknown)}; "
            f"expected {list(ENTRY_KEYS)} and the sections {list(SECTIONS)}"
        )
    for section in SECTIONS:
        if not isinstance(entry.get(section, {}), dict):
            raise ValueError(f"entry {env_id!r}: {section} must be a mapping")
        for key in COMMAND_LINE_KEYS:
            if key in entry.get(section, {}):
                raise ValueError(f"entry {env_id!r}: {section}.{key} is set on the command line")
    return entry


def env_config(entry: dict[str, Any], env_id: str) -> dict[str, Any]:
    """What every env runner needs to build the env of an entry."""
    return {
        "env_id": env_id,
        "env_kwargs": dict(entry.get("env_kwargs") or {}),
        "env_wrapper": entry.get("env_wrapper") or [],
    }


class EntryEnv(gym.Wrapper):
    """The env RLlib builds on every env runner: ``EntryEnv(env_config)`` makes
    ``config["env_id"]`` with its kwargs and wrappers. Importing ``grasp_env`` registers its
    ids in the env runner's process, wherever it runs. RLlib gets this class rather than a
    ``register_env`` name: a checkpoint refers to it by import path, so
    ``Algorithm.from_checkpoint`` also works in a later Ray session (a name registered with
    ``register_env`` lives only in the session that registered it)."""

    def __init__(self, config: dict[str, Any]) -> None:
        import grasp_env  # noqa: F401

        env = gym.make(config["env_id"], **config["env_kwargs"])
        for cls, kwargs in wrapper_specs({"env_wrapper": config["env_wrapper"]}):
            env = cls(env, **kwargs)
        super().__init__(env)


def observation_filter(env=None, spaces=None, device=None):
    """Env-to-module connector: running mean/std of the observations (VecNormalize's
    ``norm_obs``, clipped to +-10 like it), merged over the env runners each iteration."""
    from ray.rllib.connectors.env_to_module import MeanStdFilter

    return MeanStdFilter()


def record_success(*, episode, metrics_logger, **kwargs) -> None:
    """``on_episode_end`` callback: the success rate over the last episodes (from the last
    step's ``info["is_success"]``, when the env reports it)."""
    info = episode.get_infos(-1)
    if "is_success" in info:
        value = float(info["is_success"])
        metrics_logger.log_value("success_rate", value, reduce="mean", window=SUCCESS_WINDOW)


def build_config(
    entry: dict[str, Any], env_id: str, num_env_runners: int, seed: int | None
) -> PPOConfig:
    """The ``PPOConfig`` of an entry; fails naming the section of a bad setting."""
    from ray.rllib.algorithms.ppo import PPOConfig

    config = (
        PPOConfig()
        .api_stack(enable_rl_module_and_learner=True, enable_env_runner_and_connector_v2=True)
        .framework("torch")
        .environment(EntryEnv, env_config=env_config(entry, env_id))
        .env_runners(num_env_runners=num_env_runners)
        .callbacks(on_episode_end=record_success)
        .debugging(seed=seed)
    )
    if entry.get("normalize_obs", False):
        config.env_runners(env_to_module_connector=observation_filter)
    for section in SECTIONS:
        try:
            getattr(config, section)(**entry.get(section, {}))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{section}: {exc}") from None
    return config


def compile_env(entry: dict[str, Any], env_id: str, seed: int) -> float:
    """Reset the entry's env and take one step in this process; returns the seconds taken.

    The first step after an install compiles the simulator (numba) and caches the machine
    code on disk (``grasp_env.compiled``), which takes minutes on two cores. Done here, before
    Ray starts, the env runners of this machine load it from the cache: compiling it in every
    runner at once outlasts the time RLlib waits for their samples."""
    start = time.perf_counter()
    env = EntryEnv(env_config(entry, env_id))
    try:
        env.reset(seed=seed)
        env.action_space.seed(seed)
        env.step(env.action_space.sample())
    finally:
        env.close()
    return time.perf_counter() - start
