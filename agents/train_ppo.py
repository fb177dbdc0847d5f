"""Train a PPO agent (stable-baselines3, CPU) on one entry of ``configs/ppo.yml``.

    python -m agents.train_ppo --config configs/ppo.yml --env-id fig13_fingers \
        [--seed 0] [--n-timesteps N] [--out DIR] [--log-dir DIR] [--device cpu]

The model directory (``--out``, default ``agents/models/<entry>``) receives ``model.zip``,
``vecnormalize.pkl`` (when the entry normalizes), ``config.yml`` (the entry as used) and
``train_stats.json`` (timesteps, wall time, env steps/s); ``agents.evaluate`` loads it.
TensorBoard logs, ``Monitor`` CSVs (episode return, length, ``is_success`` and the sum of
every reward term), evaluation results and checkpoints go to ``--log-dir`` (default
``runs/ppo/<entry>``). See ``docs/training.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np
import yaml

from grasp_env.envs import ENTRY_POINT

#: Reward terms of FrictionlessGrasp-v0 (``info["reward_<term>"]``), summed per episode.
REWARD_TERMS = ("form_closure", "grip", "lift", "drop", "ctrl")
#: Keys the Monitor CSV records at each episode's end.
MONITOR_KEYWORDS = ("is_success", *(f"ep_reward_{t}" for t in REWARD_TERMS))
#: Keys of a config entry that are not PPO constructor arguments.
ENTRY_KEYS = (
    "env_id",
    "env_kwargs",
    "env_wrapper",
    "n_envs",
    "n_timesteps",
    "policy",
    "normalize",
)
#: Offsets of the evaluation env's seed from the training seed (training envs use
#: ``seed .. seed + n_envs - 1``); ``agents.evaluate`` draws its held-out shapes elsewhere.
EVAL_SEED_OFFSET = 1000
#: Measured on the 2-core machine (docs/training.md): with the current simulator DummyVecEnv
#: is as fast or faster for 2 envs (SubprocVecEnv won only while a step was 3x slower).
DEFAULT_VEC_ENV = "dummy"
MODEL_DIR = Path(__file__).resolve().parent / "models"


# ---------------------------------------------------------------------- config
def load_config(path: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """Read a zoo-style YAML file: ``{config name: entry}``; fails naming the bad value."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ValueError(f"--config {str(path)!r}: cannot read it ({exc.strerror})") from None
    config = yaml.safe_load(text)
    if not isinstance(config, dict) or not config:
        raise ValueError(f"--config {str(path)!r}: expected a mapping of config names to entries")
    for name, entry in config.items():
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: entry {name!r} must be a mapping, got {entry!r}")
        if "env_id" not in entry:
            raise ValueError(f"{path}: entry {name!r} has no env_id")
        if not isinstance(entry.get("env_kwargs", {}), dict):
            raise ValueError(f"{path}: entry {name!r}: env_kwargs must be a mapping")
    return config


def get_entry(config: dict[str, dict[str, Any]], name: str) -> dict[str, Any]:
    """The entry called ``name``; fails listing the names there are."""
    if name not in config:
        raise ValueError(f"--env-id {name!r} is not in the config; choose from {sorted(config)}")
    return config[name]


def check_entry(name: str, entry: dict[str, Any]) -> None:
    """Build and close one env of an entry; fails naming the entry and the bad kwarg."""
    try:
        make_env(entry["env_id"], entry.get("env_kwargs", {}), None, wrapper_specs(entry)).close()
    except (gym.error.Error, TypeError, ValueError) as exc:
        raise ValueError(f"entry {name!r}: cannot build its env: {exc}") from None


def ppo_kwargs(entry: dict[str, Any]) -> dict[str, Any]:
    """PPO constructor arguments of an entry, zoo-style strings turned into objects."""
    import torch.nn as nn
    from stable_baselines3.common.utils import LinearSchedule

    kwargs = {k: v for k, v in entry.items() if k not in ENTRY_KEYS}
    if isinstance(kwargs.get("policy_kwargs"), str):
        kwargs["policy_kwargs"] = eval(kwargs["policy_kwargs"], {"dict": dict, "nn": nn})
    for key in ("learning_rate", "clip_range"):
        value = kwargs.get(key)
        if isinstance(value, str):
            kind, _, start = value.partition("_")
            if kind != "lin":
                raise ValueError(f"{key} {value!r}: expected a number or 'lin_<value>'")
            kwargs[key] = LinearSchedule(float(start), 0.0, 1.0)
    return kwargs


def normalize_kwargs(entry: dict[str, Any]) -> dict[str, Any] | None:
    """``VecNormalize`` arguments of an entry (None: no normalization), as the zoo reads them."""
    value = entry.get("normalize", False)
    if isinstance(value, str):
        value = eval(value, {"dict": dict})
    if value is True:
        value = {}
    if value is False:
        return None
    return {**value, "gamma": entry.get("gamma", 0.99)}


# ---------------------------------------------------------------------- envs
class EpisodeTerms(gym.Wrapper):
    """Adds ``ep_reward_<term>``, each reward term summed over the episode, to every info."""

    def reset(self, **kwargs):
        self._sums = dict.fromkeys(REWARD_TERMS, 0.0)
        obs, info = self.env.reset(**kwargs)
        return obs, {**info, **self._episode_sums()}

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        for term in REWARD_TERMS:
            self._sums[term] += info[f"reward_{term}"]
        return obs, reward, terminated, truncated, {**info, **self._episode_sums()}

    def _episode_sums(self) -> dict[str, float]:
        return {f"ep_reward_{t}": v for t, v in self._sums.items()}


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


#: Training-only wrappers a config entry may name in ``env_wrapper`` (zoo key).
WRAPPERS = {"agents.train_ppo.ApproachShaping": ApproachShaping}


def wrapper_specs(entry: dict[str, Any]) -> list[tuple[type[gym.Wrapper], dict]]:
    """The entry's ``env_wrapper`` (zoo forms: a name, ``{name: kwargs}`` or a list)."""
    value = entry.get("env_wrapper") or []
    items = value if isinstance(value, list) else [value]
    specs = []
    for item in items:
        name, kwargs = next(iter(item.items())) if isinstance(item, dict) else (item, {})
        if name not in WRAPPERS:
            raise ValueError(f"env_wrapper {name!r} is not one of {sorted(WRAPPERS)}")
        specs.append((WRAPPERS[name], kwargs or {}))
    return specs


def make_env(
    env_id: str,
    env_kwargs: dict[str, Any],
    monitor_file: str | None = None,
    wrappers: list[tuple[type[gym.Wrapper], dict]] = (),
) -> gym.Env:
    """One env of an entry: ``gym.make``, the entry's wrappers, ``Monitor``, which for
    FrictionlessGrasp also logs ``is_success`` and the episode sums of the reward terms."""
    from stable_baselines3.common.monitor import Monitor

    env = gym.make(env_id, **env_kwargs)
    if env.spec.entry_point != ENTRY_POINT:  # another env (the CartPole benchmark)
        return Monitor(env, monitor_file)
    for cls, kwargs in wrappers:
        env = cls(env, **kwargs)
    return Monitor(EpisodeTerms(env), monitor_file, info_keywords=MONITOR_KEYWORDS)


def _env_factory(env_id: str, env_kwargs: dict, monitor_file: str | None, wrappers: list):
    def factory() -> gym.Env:
        import torch

        torch.set_num_threads(1)  # also in subprocess workers
        return make_env(env_id, env_kwargs, monitor_file, wrappers)

    return factory


def make_vec_env(
    entry: dict[str, Any],
    n_envs: int,
    seed: int,
    vec_env: str = DEFAULT_VEC_ENV,
    monitor_dir: str | os.PathLike | None = None,
):
    """``n_envs`` envs of an entry in a Dummy/SubprocVecEnv, seeded ``seed + rank``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    if vec_env not in ("subproc", "dummy"):
        raise ValueError(f"vec_env must be 'subproc' or 'dummy', got {vec_env!r}")
    factories = [
        _env_factory(
            entry["env_id"],
            entry.get("env_kwargs", {}),
            None if monitor_dir is None else str(Path(monitor_dir) / str(rank)),
            wrapper_specs(entry),
        )
        for rank in range(n_envs)
    ]
    cls = SubprocVecEnv if vec_env == "subproc" and n_envs > 1 else DummyVecEnv
    venv = cls(factories)
    venv.seed(seed)
    return venv


# ---------------------------------------------------------------------- callbacks
def _callbacks(
    log_dir: Path,
    eval_env,
    eval_freq: int,
    save_freq: int,
    n_eval_episodes: int,
    max_seconds: float | None,
):
    from stable_baselines3.common.callbacks import (
        BaseCallback,
        CallbackList,
        CheckpointCallback,
        EvalCallback,
    )

    class RewardTermsCallback(BaseCallback):
        """Logs the episode means of the Monitor's extra keys to TensorBoard."""

        def _on_rollout_end(self) -> None:
            episodes = list(self.model.ep_info_buffer)
            for key in MONITOR_KEYWORDS[1:]:
                values = [ep[key] for ep in episodes if key in ep]
                if values:
                    self.logger.record(f"rollout/{key}_mean", float(np.mean(values)))

        def _on_step(self) -> bool:
            return True

    class WallTimeLimit(BaseCallback):
        """Stops training once ``max_seconds`` of wall time have passed."""

        def _on_training_start(self) -> None:
            self.deadline = time.perf_counter() + (max_seconds or math.inf)

        def _on_step(self) -> bool:
            return time.perf_counter() < self.deadline

    class TimedEvalCallback(EvalCallback):
        """EvalCallback that adds up its own wall time (kept out of the training steps/s)."""

        seconds = 0.0

        def _on_step(self) -> bool:
            start = time.perf_counter()
            try:
                return super()._on_step()
            finally:
                self.seconds += time.perf_counter() - start

    evaluation = TimedEvalCallback(
        eval_env,
        n_eval_episodes=n_eval_episodes,
        eval_freq=eval_freq,
        log_path=str(log_dir / "eval"),
        best_model_save_path=str(log_dir / "eval"),
        deterministic=True,
        verbose=0,
    )
    checkpoints = CheckpointCallback(
        save_freq=save_freq,
        save_path=str(log_dir / "checkpoints"),
        name_prefix="ppo",
        save_vecnormalize=True,
    )
    callbacks = [RewardTermsCallback(), evaluation, checkpoints, WallTimeLimit()]
    return CallbackList(callbacks), evaluation


# ---------------------------------------------------------------------- training
def train(
    config_path: str | os.PathLike,
    name: str,
    *,
    seed: int = 0,
    n_timesteps: int | None = None,
    out: str | os.PathLike | None = None,
    log_dir: str | os.PathLike | None = None,
    device: str = "cpu",
    vec_env: str = DEFAULT_VEC_ENV,
    eval_freq: int = 10_000,
    n_eval_episodes: int = 5,
    save_freq: int = 25_000,
    max_minutes: float | None = None,
    progress_bar: bool = True,
) -> Path:
    """Train PPO on config entry ``name``; returns the model directory.

    ``eval_freq`` and ``save_freq`` count env steps over all envs; ``max_minutes`` stops
    training early (the model is saved as it is then).
    """
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # measured faster on 2 shared cores (docs/training.md)
    entry = get_entry(load_config(config_path), name)
    out = Path(out) if out is not None else MODEL_DIR / name
    log_dir = Path(log_dir) if log_dir is not None else Path("runs") / "ppo" / name
    total = int(n_timesteps if n_timesteps is not None else entry["n_timesteps"])
    n_envs = int(entry.get("n_envs", 1))
    if total <= 0:
        raise ValueError(f"n_timesteps must be positive, got {total}")
    out.mkdir(parents=True, exist_ok=True)
    (log_dir / "monitor").mkdir(parents=True, exist_ok=True)

    venv = make_vec_env(entry, n_envs, seed, vec_env, log_dir / "monitor")
    eval_env = make_vec_env(entry, 1, seed + EVAL_SEED_OFFSET, "dummy")
    norm = normalize_kwargs(entry)
    if norm is not None:
        venv = VecNormalize(venv, **norm)
        eval_env = VecNormalize(eval_env, **{**norm, "training": False, "norm_reward": False})
    callback, evaluation = _callbacks(
        log_dir,
        eval_env,
        eval_freq=max(eval_freq // n_envs, 1),
        save_freq=max(save_freq // n_envs, 1),
        n_eval_episodes=n_eval_episodes,
        max_seconds=None if max_minutes is None else 60.0 * max_minutes,
    )
    model = PPO(
        entry.get("policy", "MlpPolicy"),
        venv,
        seed=seed,
        device=device,
        tensorboard_log=str(log_dir / "tb"),
        verbose=0,
        **ppo_kwargs(entry),
    )
    load_start = os.getloadavg()[0]
    start = time.perf_counter()
    model.learn(total, callback=callback, progress_bar=progress_bar, tb_log_name="ppo")
    wall = time.perf_counter() - start

    model.save(out / "model.zip")
    if norm is not None:
        venv.save(str(out / "vecnormalize.pkl"))
    venv.close()
    eval_env.close()
    used = {name: {**entry, "n_timesteps": int(model.num_timesteps)}}
    (out / "config.yml").write_text(yaml.safe_dump(used, sort_keys=False))
    stats = {
        "config": name,
        "seed": seed,
        "timesteps": int(model.num_timesteps),
        "timesteps_planned": total,
        "wall_time_s": round(wall, 1),
        "env_steps_per_s": round(model.num_timesteps / wall, 1),
        "eval_time_s": round(evaluation.seconds, 1),
        "env_steps_per_s_without_eval": round(model.num_timesteps / (wall - evaluation.seconds), 1),
        "n_envs": n_envs,
        "vec_env": vec_env if n_envs > 1 else "dummy",
        "torch_threads": torch.get_num_threads(),
        "load_average_1min": [round(load_start, 1), round(os.getloadavg()[0], 1)],
        "device": device,
        "cpu": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "last_eval_mean_reward": float(evaluation.last_mean_reward),
        "versions": {
            "python": platform.python_version(),
            "torch": torch.__version__,
            "stable_baselines3": sys.modules["stable_baselines3"].__version__,
        },
    }
    (out / "train_stats.json").write_text(json.dumps(stats, indent=2) + "\n")
    return out


def load_agent(model_dir: str | os.PathLike):
    """Load a model directory: ``(model, vecnormalize or None, config entry name, entry)``."""
    import pickle

    from stable_baselines3 import PPO

    model_dir = Path(model_dir)
    if not (model_dir / "model.zip").is_file():
        raise ValueError(f"model directory {str(model_dir)!r} has no model.zip")
    ((name, entry),) = load_config(model_dir / "config.yml").items()
    model = PPO.load(model_dir / "model.zip", device="cpu")
    norm = None
    if (model_dir / "vecnormalize.pkl").is_file():
        with open(model_dir / "vecnormalize.pkl", "rb") as f:
            norm = pickle.load(f)
        norm.training, norm.norm_reward = False, False
    return model, norm, name, entry


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or math.isinf(value):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m agents.train_ppo", description=__doc__)
    parser.add_argument("--config", default="configs/ppo.yml", help="zoo-style YAML file")
    parser.add_argument("--env-id", required=True, help="config name (top-level key)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-timesteps", type=_positive_int, help="override n_timesteps")
    parser.add_argument("--out", help="model directory (default agents/models/<entry>)")
    parser.add_argument("--log-dir", help="logs, evaluations, checkpoints (runs/ppo/<entry>)")
    parser.add_argument("--device", default="cpu", choices=["cpu", "cuda", "auto"])
    parser.add_argument("--vec-env", default=DEFAULT_VEC_ENV, choices=["subproc", "dummy"])
    parser.add_argument("--eval-freq", type=_positive_int, default=10_000, help="env steps")
    parser.add_argument("--eval-episodes", type=_positive_int, default=5)
    parser.add_argument("--save-freq", type=_positive_int, default=25_000, help="env steps")
    parser.add_argument(
        "--max-minutes", type=_positive_float, help="stop training after this wall time"
    )
    parser.add_argument("--no-progress-bar", action="store_true")
    args = parser.parse_args(argv)
    try:
        check_entry(args.env_id, get_entry(load_config(args.config), args.env_id))
    except ValueError as exc:
        parser.error(str(exc))
    out = train(
        args.config,
        args.env_id,
        seed=args.seed,
        n_timesteps=args.n_timesteps,
        out=args.out,
        log_dir=args.log_dir,
        device=args.device,
        vec_env=args.vec_env,
        eval_freq=args.eval_freq,
        n_eval_episodes=args.eval_episodes,
        save_freq=args.save_freq,
        max_minutes=args.max_minutes,
        progress_bar=not args.no_progress_bar,
    )
    stats = json.loads((out / "train_stats.json").read_text())
    print(
        f"saved {out}: {stats['timesteps']} steps in {stats['wall_time_s']} s "
        f"({stats['env_steps_per_s']} env steps/s)"
    )


if __name__ == "__main__":
    main()
