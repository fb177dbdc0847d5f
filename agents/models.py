"""Trained models: the shipped ones (``agents/models/<name>``) and reading model directories
and zoo run folders.

A model directory holds ``model.zip``, ``config.yml`` (the entry it trained with, zoo
format, keyed by its env id), ``train_stats.json`` and, where the run normalized,
``vecnormalize.pkl`` (:func:`export_model` writes them). A zoo run folder
is what ``rl_zoo3.train`` and ``agents.train_ppo`` write (``<env id>.zip``, ``<env
id>/config.yml``, ``<env id>/args.yml``, checkpoints).
"""

from __future__ import annotations

import json
import os
import pickle
import re
import shutil
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml

from agents.config import REPO, config_path, load_config
from grasp_env.envs import ENV_ID, LIFT_ENV_ID, RANDOM_SHAPES_ENV_ID

MODEL_DIR = Path(__file__).resolve().parent / "models"
#: The shipped model directories ``agents/models/<name>`` that ``agents.train_ppo
#: --update-shipped`` writes, by the config file (relative to the repository) and env id
#: they train on.
SHIPPED = {
    ("configs/ppo.yml", ENV_ID): "fig13_fingers",
    ("configs/ppo.yml", RANDOM_SHAPES_ENV_ID): "random_shapes_palm",
    ("configs/ppo.yml", LIFT_ENV_ID): "lift_palm",
    ("configs/ppo_residual.yml", LIFT_ENV_ID): "lift_residual",
    ("configs/ppo_grip.yml", LIFT_ENV_ID): "lift_grip",
    ("configs/ppo_scene_starts_no_shaping.yml", LIFT_ENV_ID): "scene_starts",
}

#: What a policy calls at test time, from least to most: ``"network"``, its network alone on
#: the env's observation (or nothing at all, as a random policy); ``"planner"``, the scripted
#: planner (``agents.scripted.ScriptedPolicy``, which plans on the exact model of the scene,
#: its fallback searches included); ``"simulator"``, also the exact simulator on copies of
#: the env's state, beyond the env's own step (``simulate_action``). What a suite's env does
#: for every policy alike (e.g. the ``lift`` suite's start at the planner's placement) is
#: not counted.
TEST_TIMES = ("network", "planner", "simulator")


def entry_test_time(entry: dict[str, Any]) -> str:
    """What a model of a training entry calls at test time (one of :data:`TEST_TIMES`): what
    the agent its ``env_wrapper`` names declares (``PlannerAgent.test_time_of``), where it
    names one that plays beside the planner; else ``"network"`` (the other wrappers shape
    the reward or thin the info for training only, and no policy plays through them)."""
    from agents.planner_base import planner_wrapper

    wrapper = planner_wrapper(entry)
    return "network" if wrapper is None else wrapper[0].test_time_of(wrapper[1])


def shipped_name(conf_file: str | os.PathLike, env_id: str) -> str:
    """The shipped model directory's name of a config file and env id (ValueError where
    none is shipped)."""
    path = config_path(conf_file).resolve()
    key = (path.relative_to(REPO).as_posix() if path.is_relative_to(REPO) else str(path), env_id)
    if key not in SHIPPED:
        raise ValueError(f"--update-shipped: no shipped model of {key[0]} for {env_id!r}")
    return SHIPPED[key]


def load_agent(model_dir: str | os.PathLike):
    """Load a model: ``(model, vecnormalize or None, name, entry)``.

    ``model_dir`` is a model directory (``name`` is the directory's name) or a zoo run folder
    (``name`` is the folder's name). The entry has its ``env_id``, and its ``env_kwargs`` are
    complete: the env id's registered ones updated with the config's (and the zoo's
    ``--env-kwargs``).
    """
    from stable_baselines3 import PPO

    name, entry, model_file, norm_file = read_model_dir(model_dir)
    if not model_file.is_file():
        raise ValueError(
            f"model directory {str(model_dir)!r} has no model {model_file.name} (a run that "
            "has not finished?)"
        )
    return PPO.load(model_file, device="cpu"), load_norm(norm_file), name, entry


def read_model_dir(model_dir: str | os.PathLike) -> tuple[str, dict[str, Any], Path, Path]:
    """What :func:`load_agent` reads, without loading the model: ``(name, entry, model
    file, vecnormalize file)``; a zoo run folder needs only its ``<env id>/config.yml`` (its
    checkpoints can be read before the run ends, :func:`load_checkpoint`)."""
    model_dir = Path(model_dir)
    name = model_dir.resolve().name
    if (model_dir / "model.zip").is_file():
        ((env_id, entry),) = load_config(model_dir / "config.yml").items()
        model_file, norm_file = model_dir / "model.zip", model_dir / "vecnormalize.pkl"
    else:
        runs = sorted(p.parent for p in model_dir.glob("*/config.yml"))
        if len(runs) != 1:
            raise ValueError(
                f"model directory {str(model_dir)!r} has neither model.zip nor one zoo model "
                "(<env id>.zip beside <env id>/config.yml)"
            )
        params = runs[0]
        from rl_zoo3.utils import get_saved_hyperparams

        hyperparams, _ = get_saved_hyperparams(str(params))
        entry = {k: v for k, v in hyperparams.items() if k != "normalize_kwargs"}
        args = {}
        if (params / "args.yml").is_file():  # as rl_zoo3.enjoy reads it
            args = yaml.load((params / "args.yml").read_text(), Loader=yaml.UnsafeLoader)
        env_id = args.get("env") or params.name
        entry["env_kwargs"] = {**(entry.get("env_kwargs") or {}), **(args.get("env_kwargs") or {})}
        model_file, norm_file = model_dir / f"{params.name}.zip", params / "vecnormalize.pkl"
    registered = gym.spec(env_id).kwargs if env_id in gym.registry else {}
    env_kwargs = {**registered, **(entry.get("env_kwargs") or {})}
    return name, {**entry, "env_id": env_id, "env_kwargs": env_kwargs}, model_file, norm_file


def load_checkpoint(model_file: Path):
    """A model file of a zoo run folder: ``(model, vecnormalize or None)``; a checkpoint
    ``rl_model_<n>_steps.zip`` with the statistics saved beside it
    (``rl_model_vecnormalize_<n>_steps.pkl``), the final ``<env id>.zip`` with
    ``<env id>/vecnormalize.pkl``."""
    from stable_baselines3 import PPO

    return PPO.load(model_file, device="cpu"), load_norm(norm_file_of(model_file))


#: A checkpoint's file name in a zoo run folder (the zoo's ``CheckpointCallback``), which
#: holds its env steps.
CHECKPOINT = re.compile(r"rl_model_(\d+)_steps\.zip")


def checkpoint_steps(model_file: Path) -> int | None:
    """The env steps of a checkpoint file, or None for another file (a final model)."""
    match = CHECKPOINT.fullmatch(model_file.name)
    return None if match is None else int(match.group(1))


def norm_file_of(model_file: Path) -> Path:
    """The ``VecNormalize`` statistics saved with a model file of a zoo run folder."""
    name = model_file.name
    if name.startswith("rl_model_"):
        return model_file.with_name(
            name.replace("rl_model_", "rl_model_vecnormalize_")
        ).with_suffix(".pkl")
    return model_file.with_suffix("") / "vecnormalize.pkl"


def network_action(model, norm, obs, sampled: bool = False):
    """A model's action on one observation (normalized with ``norm`` where the run
    normalized): the mean of its policy's distribution, or with ``sampled`` a draw from it
    (torch's generator: :func:`seed_sampling` makes an episode's draws reproducible)."""
    x = norm.normalize_obs(obs) if norm is not None else obs
    return model.predict(x, deterministic=not sampled)[0]


def seed_sampling(seed: int) -> None:
    """Seed the draws of sampled play (torch's generator, which ``predict`` draws from)."""
    import torch

    torch.manual_seed(seed)


def load_norm(path: Path):
    """Saved ``VecNormalize`` statistics for inference (frozen, rewards left alone), or None
    where the run did not normalize. (``VecNormalize.load`` needs a vector env; the agents
    normalize single observations.)"""
    if not path.is_file():
        return None
    with open(path, "rb") as f:
        norm = pickle.load(f)
    norm.training, norm.norm_reward = False, False
    return norm


def export_model(run: str | os.PathLike, out: str | os.PathLike, config: dict) -> Path:
    """Write the model directory ``out`` from a zoo run folder: ``model.zip``,
    ``vecnormalize.pkl`` (if the run normalizes), ``config.yml`` (``config``: ``{env id:
    entry}``) and ``train_stats.json``."""
    run = Path(run)
    ((env_id, _),) = config.items()
    stats = json.loads((run / "train_stats.json").read_text())
    return _write_model_dir(run / f"{env_id}.zip", Path(out), config, stats)


def export_checkpoint(model_file: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Write the model directory ``out`` from a model file of a finished zoo run folder, a
    checkpoint (``<run>/rl_model_<n>_steps.zip``) or the final model (``<run>/<env
    id>.zip``): the file and its statistics, the run's entry with ``n_timesteps`` the file's
    steps, and the run's ``train_stats.json``; for a checkpoint with ``timesteps`` the
    checkpoint's and ``checkpoint`` its file name (the rest, wall time and throughput
    included, are the whole run's)."""
    model_file = Path(model_file)
    run = model_file.parent
    _, entry, _, _ = read_model_dir(run)
    stats = json.loads((run / "train_stats.json").read_text())
    steps = checkpoint_steps(model_file)
    if steps is not None:
        stats |= {"timesteps": steps, "checkpoint": model_file.name}
    saved = yaml.load((run / entry["env_id"] / "config.yml").read_text(), Loader=yaml.UnsafeLoader)
    config = {entry["env_id"]: {**dict(saved), "n_timesteps": stats["timesteps"]}}
    return _write_model_dir(model_file, Path(out), config, stats)


def _write_model_dir(model_file: Path, out: Path, config: dict, stats: dict) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(model_file, out / "model.zip")
    norm = norm_file_of(model_file)
    if norm.is_file():
        shutil.copyfile(norm, out / "vecnormalize.pkl")
    else:
        (out / "vecnormalize.pkl").unlink(missing_ok=True)
    (out / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
    (out / "train_stats.json").write_text(json.dumps(stats, indent=2) + "\n")
    return out
