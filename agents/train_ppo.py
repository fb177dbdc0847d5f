"""Train a PPO agent (stable-baselines3, CPU) on one env id of ``configs/ppo.yml``.

    python -m agents.train_ppo --env FrictionlessGrasp-v0 [--seed 0] [-n N] [--max-minutes M]
        [-f runs] [--out DIR | --update-shipped]

``configs/ppo.yml`` is in rl-baselines3-zoo's format (top-level keys are env ids), and the
training itself is the zoo's (:class:`rl_zoo3.exp_manager.ExperimentManager`: hyperparameter
parsing, schedules, ``VecNormalize``, ``Monitor``, the ``env_wrapper`` and ``callback`` keys,
evaluation and checkpoint callbacks, the run folder ``<log folder>/ppo/<env id>_<n>``), so
``python -m rl_zoo3.train --algo ppo --env <id> --gym-packages grasp_env --conf-file
configs/ppo.yml`` trains the same agent. This module adds what the zoo lacks:

* the training-only wrappers and callback the config names (:class:`ApproachShaping`,
  :class:`TrainingInfo`, :class:`RewardTermsCallback`);
* a wall-time limit, a progress line every ``--print-freq`` steps, an evaluation env seeded
  apart from the training envs, and ``train_stats.json`` (steps, wall time, env steps/s);
* checks of the config entry and the arguments before any work starts;
* model directories (``model.zip``, ``vecnormalize.pkl``, ``config.yml``,
  ``train_stats.json``), written only to ``--out`` or, with ``--update-shipped``, to
  ``agents/models/<name>``, and :func:`load_agent`, which reads them and zoo run folders.

See ``docs/training.md``.
"""

from __future__ import annotations

import argparse
import ast
import functools
import importlib
import inspect
import json
import math
import os
import platform
import shutil
import sys
import tempfile
import time
from collections import deque
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np
import yaml

from grasp_env.cli import positive_int
from grasp_env.envs import ENTRY_POINT, ENV_ID, LIFT_ENV_ID, RANDOM_SHAPES_ENV_ID
from grasp_env.envs.frictionless_grasp import REWARD_TERMS

#: Keys the Monitor CSV of :func:`make_env` records at each episode's end.
MONITOR_KEYWORDS = ("is_success", *(f"ep_reward_{t}" for t in REWARD_TERMS))
#: Keys of a config entry that are not PPO constructor arguments (the zoo's, and ``env_id``,
#: which this module adds to every entry it reads).
ENTRY_KEYS = (
    "env_id",
    "env_kwargs",
    "env_wrapper",
    "vec_env_wrapper",
    "n_envs",
    "n_timesteps",
    "policy",
    "normalize",
    "callback",
    "monitor_kwargs",
    "frame_stack",
)
#: Offset of the evaluation env's seed from the training seed (training envs use ``seed ..
#: seed + n_envs - 1``; ``rl_zoo3.train`` seeds its evaluation env like training env 0).
EVAL_SEED_OFFSET = 1000
#: ``"auto"``: the batched env (:mod:`agents.batched`, every env stepped by one compiled
#: call) where the entry has several envs and no wrapper but ``TrainingInfo`` (whose work it
#: does), else DummyVecEnv (measured as fast as SubprocVecEnv for 2 envs on 2 cores).
DEFAULT_VEC_ENV = "auto"
VEC_ENVS = ("auto", "batched", "dummy", "subproc")
#: Wrappers the batched env stands in for: it passes on only what training reads.
BATCHED_WRAPPERS = frozenset({"agents.train_ppo.TrainingInfo"})
#: Env kwargs the evaluation during training leaves out: the reward weights (it reports the
#: env's own return) and the shape pool (it meets new shapes).
TRAINING_ONLY = ("reward_", "shape_pool")
DEFAULT_CONFIG = "configs/ppo.yml"
DEFAULT_LOG_FOLDER = "runs"
MODEL_DIR = Path(__file__).resolve().parent / "models"
#: The shipped model directory (``agents/models/<name>``) of each env id.
SHIPPED = {
    ENV_ID: "fig13_fingers",
    RANDOM_SHAPES_ENV_ID: "random_shapes_palm",
    LIFT_ENV_ID: "lift_palm",
}
#: The shipped model directory of each env id's residual agents (an entry whose
#: ``env_wrapper`` names ``agents.residual.PlannerResidual``, ``configs/ppo_residual.yml``).
SHIPPED_RESIDUAL = {LIFT_ENV_ID: "lift_residual"}
#: The shipped model directory of each env id's hand-over agents (``env_wrapper`` naming
#: ``agents.handover.PlannerHandover``, ``configs/ppo_handover.yml``): none so far.
SHIPPED_HANDOVER: dict[str, str] = {}
#: The shipped model directory of each env id's grip agents (``PlannerResidual`` with
#: ``after_plan``: they act once the planner's plan is played, ``configs/ppo_grip.yml``).
SHIPPED_GRIP = {LIFT_ENV_ID: "lift_grip"}
#: Config names of the former scheme (top-level keys were config names), still accepted.
LEGACY_NAMES = {name: env_id for env_id, name in SHIPPED.items()}

DESCRIPTION = (
    "Train a PPO agent (stable-baselines3 on the CPU, through rl-baselines3-zoo's "
    "ExperimentManager) on one env id of a zoo-format hyperparameter file. Each run goes to "
    "a new folder <log folder>/ppo/<env id>_<n> (model, VecNormalize statistics, Monitor "
    "CSVs, evaluations, checkpoints, TensorBoard logs, train_stats.json); nothing is "
    "overwritten unless --update-shipped is given. See docs/training.md."
)


# ---------------------------------------------------------------------- config
class _ZooLoader(yaml.SafeLoader):
    """A safe loader that also reads the zoo's saved ``config.yml``/``args.yml`` (dumped
    ``OrderedDict``s), and nothing else beyond plain YAML."""


def _ordered_dict(loader: yaml.SafeLoader, node: yaml.Node) -> dict:
    (pairs,) = loader.construct_sequence(node, deep=True)
    return dict(pairs)


_ZooLoader.add_constructor(
    "tag:yaml.org,2002:python/object/apply:collections.OrderedDict", _ordered_dict
)


def _read_yaml(path: str | os.PathLike, what: str) -> Any:
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ValueError(f"{what} {str(path)!r}: cannot read it ({exc.strerror})") from None
    try:
        return yaml.load(text, Loader=_ZooLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ValueError(f"{what} {str(path)!r}: not valid YAML{where}: {problem}") from None


def load_config(path: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """Read a hyperparameter file: ``{key: entry}``, each entry with its ``env_id``.

    In rl-baselines3-zoo's format a key is an env id; an entry that has an ``env_id`` of its
    own (the former scheme) is keyed by a config name. Fails with a one-line message naming
    the file and the bad part.
    """
    config = _read_yaml(path, "config file")
    if not isinstance(config, dict) or not config:
        raise ValueError(f"config file {str(path)!r}: expected a mapping of env ids to entries")
    entries = {}
    for key, entry in config.items():
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: entry {key!r} must be a mapping, got {entry!r}")
        if not isinstance(entry.get("env_kwargs") or {}, dict):
            raise ValueError(f"{path}: entry {key!r}: env_kwargs must be a mapping")
        entries[str(key)] = {"env_id": str(key), **entry}
    return entries


def get_entry(config: dict[str, dict[str, Any]], name: str) -> dict[str, Any]:
    """The entry of env id ``name`` (or of a former config name); fails listing the keys."""
    if name not in config and LEGACY_NAMES.get(name) in config:
        name = LEGACY_NAMES[name]
    if name not in config:
        raise ValueError(f"env id {name!r} is not in the config; choose from {sorted(config)}")
    return config[name]


def _expression(value: Any, key: str) -> Any:
    """A zoo-style value that may be a Python expression string (``"dict(...)"``)."""
    if not isinstance(value, str):
        return value
    import torch

    try:
        return eval(value, {"dict": dict, "nn": torch.nn, "th": torch})  # as the zoo has them
    except Exception as exc:
        raise ValueError(f"{key} {value!r}: not a valid expression ({exc})") from None


def _schedule(value: Any, key: str):
    from stable_baselines3.common.utils import LinearSchedule

    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise ValueError(f"{key} {value!r}: expected a number or 'lin_<value>'")
    if isinstance(value, str):
        kind, _, start = value.partition("_")
        try:
            if kind != "lin":
                raise ValueError
            return LinearSchedule(float(start), 0.0, 1.0)
        except ValueError:
            raise ValueError(f"{key} {value!r}: expected a number or 'lin_<value>'") from None
    return value


def ppo_kwargs(entry: dict[str, Any]) -> dict[str, Any]:
    """PPO constructor arguments of an entry, zoo-style strings turned into objects (for
    ``benchmarks.ppo_throughput``, which builds PPO without the zoo)."""
    kwargs = {k: v for k, v in entry.items() if k not in ENTRY_KEYS}
    if "policy_kwargs" in kwargs:
        kwargs["policy_kwargs"] = _expression(kwargs["policy_kwargs"], "policy_kwargs")
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if key in kwargs:
            kwargs[key] = _schedule(kwargs[key], key)
    return kwargs


def normalize_kwargs(entry: dict[str, Any]) -> dict[str, Any] | None:
    """``VecNormalize`` arguments of an entry (None: no normalization), as the zoo reads them."""
    value = _expression(entry.get("normalize", False), "normalize")
    if value is True:
        value = {}
    if value is False or value is None:
        return None
    if not isinstance(value, dict):
        raise ValueError(f"normalize {entry['normalize']!r}: expected a bool or a dict")
    return {**value, "gamma": entry.get("gamma", 0.99)}


def _import(path: Any, key: str) -> type:
    """The object a dotted path names, as the zoo imports ``env_wrapper`` and ``callback``."""
    if not isinstance(path, str) or "." not in path:
        raise ValueError(f"{key} {path!r}: expected a dotted path such as 'package.module.Class'")
    module, _, name = path.rpartition(".")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"{key} {path!r}: cannot import it ({exc})") from None


def _named_items(value: Any, key: str) -> list[tuple[Any, dict]]:
    """The zoo's forms of ``env_wrapper``/``callback``: a path, ``{path: kwargs}`` or a list."""
    items = value if isinstance(value, list) else [] if value is None else [value]
    out = []
    for item in items:
        if isinstance(item, dict):
            if len(item) != 1:
                raise ValueError(f"{key} {item!r}: expected one {{path: kwargs}} per item")
            ((name, kwargs),) = item.items()
        else:
            name, kwargs = item, {}
        if not isinstance(kwargs or {}, dict):
            raise ValueError(f"{key} {name!r}: its arguments must be a mapping, got {kwargs!r}")
        out.append((name, kwargs or {}))
    return out


def wrapper_specs(entry: dict[str, Any]) -> list[tuple[type[gym.Wrapper], dict]]:
    """The entry's ``env_wrapper`` as ``(class, kwargs)`` pairs, imported like the zoo does."""
    return [
        (_import(name, "env_wrapper"), kwargs)
        for name, kwargs in _named_items(entry.get("env_wrapper"), "env_wrapper")
    ]


def check_entry(name: str, entry: dict[str, Any]) -> None:
    """Check every value of an entry and build one env of it, before any training starts.

    Fails with a ``ValueError`` naming the entry and the bad value.
    """
    from stable_baselines3 import PPO

    def fail(message: str) -> None:
        raise ValueError(f"entry {name!r}: {message}")

    env_id = entry["env_id"]
    if env_id not in gym.registry:
        fail(f"{env_id!r} is not a registered env id")
    try:
        n_timesteps = float(entry["n_timesteps"])
    except (KeyError, TypeError, ValueError):
        fail(f"n_timesteps must be a number, got {entry.get('n_timesteps')!r}")
    if not n_timesteps >= 1 or math.isinf(n_timesteps):
        fail(f"n_timesteps must be positive, got {entry['n_timesteps']!r}")
    n_envs = entry.get("n_envs", 1)
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        fail(f"n_envs must be a positive integer, got {n_envs!r}")
    if not isinstance(entry.get("policy", "MlpPolicy"), str):
        fail(f"policy must be a policy name, got {entry['policy']!r}")
    allowed = set(inspect.signature(PPO.__init__).parameters) - {"self", "env", "policy"}
    unknown = sorted(set(entry) - set(ENTRY_KEYS) - allowed)
    if unknown:
        fail(f"unknown key(s) {', '.join(map(str, unknown))}: neither the zoo's nor PPO's")
    try:
        kwargs = ppo_kwargs(entry)
        if not isinstance(kwargs.get("policy_kwargs", {}), dict):
            raise ValueError(f"policy_kwargs {entry['policy_kwargs']!r}: expected a dict")
        normalize_kwargs(entry)
        monitor = _expression(entry.get("monitor_kwargs", {}), "monitor_kwargs")
        if not isinstance(monitor, dict) or not isinstance(monitor.get("info_keywords", ()), tuple):
            raise ValueError(
                f"monitor_kwargs {entry['monitor_kwargs']!r}: expected a dict with a tuple as "
                "info_keywords, e.g. \"dict(info_keywords=('is_success',))\""
            )
        for path, _ in _named_items(entry.get("callback"), "callback"):
            _import(path, "callback")
        wrappers = wrapper_specs(entry)
    except ValueError as exc:
        fail(str(exc))
    try:
        make_env(env_id, entry.get("env_kwargs") or {}, None, wrappers).close()
    except (gym.error.Error, TypeError, ValueError) as exc:
        fail(f"cannot build its env: {exc}")


# ---------------------------------------------------------------------- wrappers, callbacks
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
    (``reward_*``, shaping terms of inner wrappers included), and where present ``sim_error``
    and ``Monitor``'s ``episode`` (the zoo puts ``env_wrapper`` outside the Monitor; SB3's
    episode statistics and its evaluation count episodes by it). SB3's vector envs copy every
    info at every step (DummyVecEnv deep-copies them, SubprocVecEnv pickles them); the env's
    whole info (poses, contacts with their points and normals, events) made that copy about a
    fifth of PPO's time. Training only: the evaluation commands and the policies' own envs
    see the whole info. Named last in ``env_wrapper`` in ``configs/ppo.yml``, so that the
    wrappers inside it still see everything."""

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        kept = {key: value for key, value in info.items() if key.startswith("reward_")}
        kept["is_success"] = info["is_success"]
        for key in _PASSED_ON:
            if key in info:
                kept[key] = info[key]
        return obs, reward, terminated, truncated, kept


#: Info keys :class:`TrainingInfo` passes on where a step has them.
_PASSED_ON = ("sim_error", "episode")


@functools.cache
def _callbacks() -> dict[str, type]:
    """The SB3 callbacks of this module, defined on first use so that importing it (for
    :class:`ApproachShaping` or :func:`load_config`, e.g. from ``agents.train_rllib``) needs
    no stable-baselines3; ``agents.train_ppo.RewardTermsCallback`` etc. resolve through the
    module's ``__getattr__``."""
    from stable_baselines3.common.callbacks import BaseCallback

    class RewardTermsCallback(BaseCallback):
        """Logs to TensorBoard the mean over the last 100 episodes of each reward term's
        episode sum (``rollout/ep_reward_<term>_mean``, from ``info["reward_<term>"]``,
        shaping terms of wrappers such as ``reward_approach`` included), beside SB3's
        ``rollout/ep_rew_mean``. Named in ``configs/ppo.yml`` (``callback``), so zoo runs
        log the terms as well."""

        def _on_training_start(self) -> None:
            self._sums = [{} for _ in range(self.training_env.num_envs)]
            self._episodes: deque[dict[str, float]] = deque(maxlen=100)

        def _on_step(self) -> bool:
            for sums, info, done in zip(
                self._sums, self.locals["infos"], self.locals["dones"], strict=True
            ):
                for key, value in info.items():
                    if key.startswith("reward_"):
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

    class ProgressLines(BaseCallback):
        """Prints one line every ``every`` env steps: steps done, rate, time left, mean
        return of the last 100 episodes."""

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

    classes = (RewardTermsCallback, ProgressLines, WallTimeLimit)
    for cls in classes:
        cls.__module__, cls.__qualname__ = __name__, cls.__name__
    return {cls.__name__: cls for cls in classes}


def __getattr__(name: str) -> Any:
    if name in ("RewardTermsCallback", "ProgressLines", "WallTimeLimit"):
        return _callbacks()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _minutes(seconds: float) -> str:
    minutes = int(seconds // 60)
    return (
        f"{minutes // 60}h{minutes % 60:02d}m"
        if minutes >= 60
        else f"{minutes}m{int(seconds % 60):02d}s"
    )


def _timed(callback) -> list[float]:
    """Adds up the wall time of ``callback``'s steps (the periodic evaluation) in the list
    it returns, so that it can be kept out of the training steps/s."""
    seconds = [0.0]
    on_step = callback._on_step

    def timed() -> bool:
        start = time.perf_counter()
        try:
            return on_step()
        finally:
            seconds[0] += time.perf_counter() - start

    callback._on_step = timed
    return seconds


# ---------------------------------------------------------------------- envs without the zoo
class EpisodeTerms(gym.Wrapper):
    """Adds ``ep_reward_<term>``, each reward term summed over the episode, to the info of
    the episode's last step, where ``Monitor`` reads it (only there: vector envs copy every
    info at every step)."""

    def reset(self, **kwargs):
        self._sums = dict.fromkeys(REWARD_TERMS, 0.0)
        return self.env.reset(**kwargs)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        for term in REWARD_TERMS:
            self._sums[term] += info[f"reward_{term}"]
        if terminated or truncated:
            info = {**info, **{f"ep_reward_{t}": v for t, v in self._sums.items()}}
        return obs, reward, terminated, truncated, info


def make_env(
    env_id: str,
    env_kwargs: dict[str, Any],
    monitor_file: str | None = None,
    wrappers: list[tuple[type[gym.Wrapper], dict]] = (),
) -> gym.Env:
    """One env of an entry without the zoo (benchmarks, checks): ``gym.make``, the entry's
    wrappers, ``Monitor``, which for FrictionlessGrasp also logs ``is_success`` and the episode
    sums of the reward terms."""
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
    """``n_envs`` envs of an entry in the batched env or a Dummy/SubprocVecEnv
    (:func:`vec_env_of`), seeded ``seed + rank`` (for ``benchmarks.ppo_throughput``, which
    times PPO without the zoo)."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    vec_env = vec_env_of({**entry, "n_envs": n_envs}, vec_env)
    if vec_env == "batched":
        from agents.batched import make_vec_env as batched_vec_env

        venv = batched_vec_env(entry["env_id"], n_envs, seed, **(entry.get("env_kwargs") or {}))
        return VecMonitor(venv, None if monitor_dir is None else str(Path(monitor_dir) / "0"))
    factories = [
        _env_factory(
            entry["env_id"],
            entry.get("env_kwargs") or {},
            None if monitor_dir is None else str(Path(monitor_dir) / str(rank)),
            wrapper_specs(entry),
        )
        for rank in range(n_envs)
    ]
    cls = SubprocVecEnv if vec_env == "subproc" and n_envs > 1 else DummyVecEnv
    venv = cls(factories)
    venv.seed(seed)
    return venv


# ---------------------------------------------------------------------- training
def _manager_class():
    from rl_zoo3.exp_manager import ExperimentManager

    class Manager(ExperimentManager):
        """The zoo's ExperimentManager with the evaluation env seeded ``seed + 1000``, so
        that it does not replay training env 0's episodes (random shapes), and made with the
        entry's task kwargs (``env_kwargs`` other than reward weights: the zoo passes the
        evaluation env only those given on its command line), so that it reports the env's
        own return on the task trained."""

        #: Whether the training envs are the batched env (set after construction).
        batched = False

        def create_envs(self, n_envs: int, eval_env: bool = False, no_log: bool = False):
            if not eval_env and self.batched:
                return self._batched_envs(n_envs, no_log)
            if not eval_env:
                return super().create_envs(n_envs, eval_env, no_log)
            seed, self.seed = self.seed, self.seed + EVAL_SEED_OFFSET
            kwargs, wrapper = self.eval_env_kwargs, self.vec_env_wrapper
            if self.batched:  # wrapped like the training envs, for SB3's statistics sync
                self.vec_env_wrapper = _monitored(wrapper)
            self.eval_env_kwargs = {
                k: v for k, v in (self.env_kwargs or {}).items() if not k.startswith(TRAINING_ONLY)
            }
            try:
                return super().create_envs(n_envs, eval_env, no_log)
            finally:
                self.seed, self.eval_env_kwargs, self.vec_env_wrapper = seed, kwargs, wrapper

        def _batched_envs(self, n_envs: int, no_log: bool):
            """The training envs as the batched env, with the zoo's monitor (one file for
            all envs), vec-env wrapper and normalization."""
            from stable_baselines3.common.vec_env import VecMonitor

            from agents.batched import make_vec_env as batched_vec_env

            env = batched_vec_env(self.env_name.gym_id, n_envs, self.seed, **self.env_kwargs)
            log = None if no_log else os.path.join(self.save_path, "0")
            env = VecMonitor(env, log, **self.monitor_kwargs)
            if self.vec_env_wrapper is not None:
                env = self.vec_env_wrapper(env)
            return self._maybe_normalize(env, False)

    return Manager


def _monitored(wrapper):
    """A vec-env wrapper that puts a ``VecMonitor`` (no file) under ``wrapper``."""
    from stable_baselines3.common.vec_env import VecMonitor

    def wrap(env):
        env = VecMonitor(env)
        return env if wrapper is None else wrapper(env)

    return wrap


def vec_env_of(entry: dict[str, Any], vec_env: str) -> str:
    """The vector env a run uses: ``vec_env``, with ``"auto"`` resolved (batched where the
    entry has several envs and no wrapper the batched env cannot stand in for); ValueError
    where ``"batched"`` is asked for an entry it cannot run."""
    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {list(VEC_ENVS)}, got {vec_env!r}")
    wrappers = {name for name, _ in _named_items(entry.get("env_wrapper"), "env_wrapper")}
    possible = wrappers <= BATCHED_WRAPPERS
    if vec_env == "batched" and not possible:
        raise ValueError(
            f"vec_env='batched' steps the env itself, without the wrappers "
            f"{sorted(wrappers - BATCHED_WRAPPERS)}: use 'dummy' or 'subproc'"
        )
    if vec_env == "auto":
        return "batched" if possible and int(entry.get("n_envs", 1)) > 1 else "dummy"
    return vec_env


def prepare(
    env_id: str,
    conf_file: str | os.PathLike = DEFAULT_CONFIG,
    hyperparams: dict[str, Any] | None = None,
    n_timesteps: int | None = None,
) -> tuple[str, dict[str, Any]]:
    """``(env id, entry)`` of a training run, overrides applied, checked (ValueError)."""
    config = load_config(conf_file)
    entry = get_entry(config, env_id)
    key = next(k for k, v in config.items() if v is entry)
    if entry["env_id"] != key:
        raise ValueError(
            f"config file {str(conf_file)!r}: entry {key!r} is in the former format (a config "
            "name with an env_id); rl-baselines3-zoo keys entries by env id (docs/training.md)"
        )
    env_id = key
    entry = {**entry, **(hyperparams or {})}
    if n_timesteps is not None:
        entry["n_timesteps"] = n_timesteps
    check_entry(env_id, entry)
    return env_id, entry


def shipped_name(env_id: str, entry: dict[str, Any]) -> str:
    """The shipped model directory's name (``agents/models/<name>``) of a training entry:
    by env id, agents that play beside the planner apart (ValueError where none is
    shipped)."""
    from agents.handover import PlannerHandover
    from agents.residual import planner_wrapper

    wrapper = planner_wrapper(entry)
    names, kind = SHIPPED, "model"
    if wrapper is not None and wrapper[0] is PlannerHandover:
        names, kind = SHIPPED_HANDOVER, "hand-over model"
    elif wrapper is not None and wrapper[1].get("after_plan"):
        names, kind = SHIPPED_GRIP, "grip model"
    elif wrapper is not None:
        names, kind = SHIPPED_RESIDUAL, "residual model"
    if env_id not in names:
        raise ValueError(f"--update-shipped: no shipped {kind} for {env_id!r}")
    return names[env_id]


def train(
    env_id: str,
    *,
    conf_file: str | os.PathLike = DEFAULT_CONFIG,
    hyperparams: dict[str, Any] | None = None,
    seed: int = 0,
    n_timesteps: int | None = None,
    log_folder: str | os.PathLike = DEFAULT_LOG_FOLDER,
    out: str | os.PathLike | None = None,
    device: str = "cpu",
    vec_env: str = DEFAULT_VEC_ENV,
    eval_freq: int = 10_000,
    n_eval_episodes: int = 5,
    save_freq: int = 25_000,
    max_minutes: float | None = None,
    progress: bool = False,
    print_freq: int = 5_000,
    num_threads: int = 1,
    verbose: int = 0,
    trained_agent: str | os.PathLike | None = None,
) -> Path:
    """Train PPO on the config entry of ``env_id`` with the zoo; returns the run folder.

    The run folder is ``<log_folder>/ppo/<env id>_<n>`` (a new ``n`` each run, as the zoo
    numbers them), with ``train_stats.json`` added. ``out`` also writes a model directory
    there. ``hyperparams`` override the entry's keys (the zoo's ``--hyperparams``);
    ``eval_freq`` and ``save_freq`` count env steps over all envs (<= 0: off); ``max_minutes``
    stops training early (the model is saved as it is then). ``trained_agent`` (a model
    directory, :func:`load_agent`'s kind) starts from that model and its VecNormalize
    statistics instead of a new policy (the zoo's ``--trained-agent``).
    """
    import torch
    from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
    from stable_baselines3.common.utils import set_random_seed

    env_id, entry = prepare(env_id, conf_file, hyperparams, n_timesteps)
    vec_env = vec_env_of(entry, vec_env)
    overrides = {**(hyperparams or {})}
    total = int(float(entry["n_timesteps"]))
    torch.set_num_threads(num_threads)  # 1: measured faster on 2 shared cores
    set_random_seed(seed)
    args = argparse.Namespace(
        algo="ppo",
        env=env_id,
        conf_file=str(conf_file),
        hyperparams=overrides or None,
        env_kwargs=None,
        seed=seed,
        n_timesteps=total,
        log_folder=str(log_folder),
        out=None if out is None else str(out),
        device=device,
        vec_env=vec_env,
        eval_freq=eval_freq,
        eval_episodes=n_eval_episodes,
        save_freq=save_freq,
        max_minutes=max_minutes,
        num_threads=num_threads,
    )
    # the zoo reads a trained agent (weights and VecNormalize statistics) while it sets up
    with tempfile.TemporaryDirectory(prefix="trained_agent_") as staging:
        manager = _manager_class()(
            args,
            "ppo",
            env_id,
            str(log_folder),
            n_timesteps=total,
            eval_freq=eval_freq,
            n_eval_episodes=n_eval_episodes,
            save_freq=save_freq,
            hyperparams=overrides or None,
            seed=seed,
            log_interval=-1,  # SB3's default
            verbose=verbose,
            vec_env_type="dummy" if vec_env == "batched" else vec_env,
            device=device,
            config=str(conf_file),
            show_progress=progress,
            trained_agent=_zoo_layout(trained_agent, env_id, staging) if trained_agent else "",
        )
        manager.batched = vec_env == "batched"
        run = Path(manager.save_path)
        manager.tensorboard_log = str(run / "tb")
        model, saved = manager.setup_experiment()
    eval_seconds = [0.0]
    for callback in manager.callbacks:
        if isinstance(callback, EvalCallback):
            eval_seconds = _timed(callback)
        if isinstance(callback, CheckpointCallback):
            callback.save_vecnormalize = True  # a checkpoint is useless without its statistics
    manager.callbacks.append(
        _callbacks()["WallTimeLimit"](None if max_minutes is None else 60.0 * max_minutes)
    )
    if print_freq > 0 and not progress:
        manager.callbacks.append(_callbacks()["ProgressLines"](print_freq, total))

    load_start = os.getloadavg()[0]
    start = time.perf_counter()
    manager.learn(model)
    wall = time.perf_counter() - start
    manager.save_trained_model(model)

    stats = {
        "env_id": env_id,
        "seed": seed,
        "timesteps": int(model.num_timesteps),
        "timesteps_planned": total,
        "wall_time_s": round(wall, 1),
        "env_steps_per_s": round(model.num_timesteps / wall, 1),
        "eval_time_s": round(eval_seconds[0], 1),
        "env_steps_per_s_without_eval": round(model.num_timesteps / (wall - eval_seconds[0]), 1),
        "n_envs": manager.n_envs,
        "vec_env": vec_env if manager.n_envs > 1 else "dummy",
        "torch_threads": torch.get_num_threads(),
        "load_average_1min": [round(load_start, 1), round(os.getloadavg()[0], 1)],
        "device": device,
        "cpu": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "last_eval_mean_reward": next(
            (
                float(c.last_mean_reward)
                for c in manager.callbacks
                if isinstance(c, EvalCallback) and math.isfinite(c.last_mean_reward)
            ),
            None,
        ),
        "run": str(run),
        "versions": {
            "python": platform.python_version(),
            "torch": torch.__version__,
            "stable_baselines3": sys.modules["stable_baselines3"].__version__,
            "rl_zoo3": importlib.import_module("rl_zoo3").__version__,
        },
    }
    (run / "train_stats.json").write_text(json.dumps(stats, indent=2) + "\n")
    if out is not None:
        used = {key: value for key, value in saved.items() if key != "env_id"}
        export_model(run, out, {env_id: {**used, "n_timesteps": int(model.num_timesteps)}})
    return run


def _zoo_layout(model_dir: str | os.PathLike, env_id: str, folder: str) -> str:
    """A model directory copied into ``folder`` where the zoo looks for a trained agent
    (``model.zip``, and its VecNormalize statistics in ``<env id>/vecnormalize.pkl`` beside
    it); the path of its ``model.zip``."""
    model_dir = trained_agent_dir(model_dir)
    staged = Path(folder)
    shutil.copy(model_dir / "model.zip", staged / "model.zip")
    norm = model_dir / "vecnormalize.pkl"
    if norm.is_file():
        (staged / env_id).mkdir()
        shutil.copy(norm, staged / env_id / "vecnormalize.pkl")
    return str(staged / "model.zip")


def trained_agent_dir(model_dir: str | os.PathLike) -> Path:
    """``model_dir`` as a path, checked to hold a model (``ValueError`` naming it)."""
    model_dir = Path(model_dir)
    if not (model_dir / "model.zip").is_file():
        raise ValueError(f"--trained-agent {str(model_dir)!r}: no model.zip there")
    return model_dir


def export_model(run: str | os.PathLike, out: str | os.PathLike, config: dict) -> Path:
    """Write the model directory ``out`` from a zoo run folder: ``model.zip``,
    ``vecnormalize.pkl`` (if the run normalizes), ``config.yml`` (``config``, zoo format) and
    ``train_stats.json``."""
    run, out = Path(run), Path(out)
    ((env_id, _),) = config.items()
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(run / f"{env_id}.zip", out / "model.zip")
    norm = run / env_id / "vecnormalize.pkl"
    if norm.is_file():
        shutil.copyfile(norm, out / "vecnormalize.pkl")
    else:
        (out / "vecnormalize.pkl").unlink(missing_ok=True)
    (out / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
    shutil.copyfile(run / "train_stats.json", out / "train_stats.json")
    return out


# ---------------------------------------------------------------------- loading
def load_agent(model_dir: str | os.PathLike):
    """Load a model: ``(model, vecnormalize or None, name, entry)``.

    ``model_dir`` is a model directory (``model.zip``, ``config.yml``, maybe
    ``vecnormalize.pkl``; ``name`` is the directory's name, or the config name of a
    former-format ``config.yml``) or a zoo run folder (``<env id>.zip`` and ``<env
    id>/config.yml``, as ``rl_zoo3.train`` and this module write them; ``name`` is the
    folder's name). The entry's ``env_kwargs`` are complete: the env id's registered ones
    updated with the config's (and the zoo's ``--env-kwargs``).
    """
    from stable_baselines3 import PPO

    name, entry, model_file, norm_file = read_model_dir(model_dir)
    if not model_file.is_file():
        raise ValueError(
            f"model directory {str(model_dir)!r} has no model {model_file.name} (a run that "
            "has not finished?)"
        )
    return PPO.load(model_file, device="cpu"), _load_norm(norm_file), name, entry


def read_model_dir(model_dir: str | os.PathLike) -> tuple[str, dict, Path, Path]:
    """What :func:`load_agent` reads, without loading the model: ``(name, entry, model
    file, vecnormalize file)``; a zoo run folder needs only its ``<env id>/config.yml`` (its
    checkpoints can be read before the run ends, :func:`load_checkpoint`)."""
    model_dir = Path(model_dir)
    if (model_dir / "model.zip").is_file():
        ((key, entry),) = load_config(model_dir / "config.yml").items()
        name = key if key != entry["env_id"] else model_dir.resolve().name
        model_file, norm_file = model_dir / "model.zip", model_dir / "vecnormalize.pkl"
    else:
        runs = sorted(p.parent for p in model_dir.glob("*/config.yml"))
        if len(runs) != 1:
            raise ValueError(
                f"model directory {str(model_dir)!r} has neither model.zip nor one zoo model "
                "(<env id>.zip beside <env id>/config.yml)"
            )
        params = runs[0]
        hyperparams = _read_yaml(params / "config.yml", "config file") or {}
        args = (
            _read_yaml(params / "args.yml", "args file") if (params / "args.yml").is_file() else {}
        )
        env_id = (args or {}).get("env") or params.name
        kwargs = {**(hyperparams.get("env_kwargs") or {}), **((args or {}).get("env_kwargs") or {})}
        entry = {**hyperparams, "env_id": env_id, "env_kwargs": kwargs}
        name = model_dir.resolve().name
        model_file, norm_file = model_dir / f"{params.name}.zip", params / "vecnormalize.pkl"
    registered = gym.spec(entry["env_id"]).kwargs if entry["env_id"] in gym.registry else {}
    entry = {**entry, "env_kwargs": {**registered, **(entry.get("env_kwargs") or {})}}
    return name, entry, model_file, norm_file


def load_checkpoint(model_file: Path):
    """A model file of a zoo run folder: ``(model, vecnormalize or None)``; a checkpoint
    ``rl_model_<n>_steps.zip`` with the statistics saved beside it
    (``rl_model_vecnormalize_<n>_steps.pkl``), the final ``<env id>.zip`` with
    ``<env id>/vecnormalize.pkl``."""
    from stable_baselines3 import PPO

    name = model_file.name
    if name.startswith("rl_model_"):
        norm_file = model_file.with_name(name.replace("rl_model_", "rl_model_vecnormalize_"))
        norm_file = norm_file.with_suffix(".pkl")
    else:
        norm_file = model_file.with_suffix("") / "vecnormalize.pkl"
    return PPO.load(model_file, device="cpu"), _load_norm(norm_file)


def _load_norm(path: Path):
    """Saved ``VecNormalize`` statistics for inference (frozen, rewards left alone), or None
    where the run did not normalize."""
    import pickle

    if not path.is_file():
        return None
    with open(path, "rb") as f:
        norm = pickle.load(f)
    norm.training, norm.norm_reward = False, False
    return norm


# ---------------------------------------------------------------------- command line


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or math.isinf(value):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _override(text: str) -> tuple[str, Any]:
    """``key:value`` of ``--hyperparams``: the value is a Python literal, else a string (which
    the zoo evaluates where it expects an expression, e.g. ``policy_kwargs:dict(...)``)."""
    key, sep, value = text.partition(":")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected key:value, got {text!r}")
    try:
        return key, ast.literal_eval(value)
    except (ValueError, SyntaxError):
        return key, value


class _Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows a default only where there is one (not None, not an off switch)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        if action.default is None or action.default is False or action.help == argparse.SUPPRESS:
            return action.help or ""
        return super()._get_help_string(action)


class _Parser(argparse.ArgumentParser):
    """Reports a bad argument or file in one line (no usage block)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="python -m agents.train_ppo",
        description=DESCRIPTION,
        formatter_class=_Formatter,
    )
    p.add_argument(
        "--env",
        "--env-id",
        dest="env",
        default=ENV_ID,
        metavar="ID",
        help=f"env id, a top-level key of --conf-file ({', '.join(SHIPPED)})",
    )
    p.add_argument(
        "-conf",
        "--conf-file",
        "--config",
        dest="conf_file",
        default=DEFAULT_CONFIG,
        metavar="FILE",
        help="hyperparameter file in rl-baselines3-zoo's format",
    )
    p.add_argument(
        "--seed", type=_int, default=0, metavar="N", help="training env k is seeded seed + k"
    )
    p.add_argument(
        "-n",
        "--n-timesteps",
        type=positive_int,
        metavar="N",
        help="total env steps (default: the entry's n_timesteps)",
    )
    p.add_argument(
        "--max-minutes",
        type=_positive_float,
        metavar="M",
        help="stop after M minutes of wall time (the model is saved as it is then)",
    )
    p.add_argument(
        "-params",
        "--hyperparams",
        nargs="+",
        type=_override,
        metavar="KEY:VALUE",
        help="override entry keys, e.g. n_steps:256 learning_rate:lin_3e-4",
    )
    p.add_argument(
        "-f",
        "--log-folder",
        default=DEFAULT_LOG_FOLDER,
        metavar="DIR",
        help="runs go to DIR/ppo/<env id>_<n>, a new n each run",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument("--out", metavar="DIR", help="also write a model directory to DIR")
    where.add_argument(
        "--update-shipped",
        action="store_true",
        help="also write the model directory to agents/models/<name>, replacing the shipped one",
    )
    p.add_argument(
        "-i",
        "--trained-agent",
        metavar="DIR",
        help="start from this model directory (its model.zip and VecNormalize statistics)",
    )
    p.add_argument("-P", "--progress", action="store_true", help="show a progress bar")
    p.add_argument(
        "--print-freq",
        type=_int,
        default=5_000,
        metavar="STEPS",
        help="without --progress, print a progress line every STEPS env steps (0: never)",
    )
    p.add_argument("--device", default="cpu", choices=["cpu", "cuda", "auto"], help="torch device")
    p.add_argument(
        "--vec-env",
        default=DEFAULT_VEC_ENV,
        choices=VEC_ENVS,
        help="vector env of the training envs (auto: the batched env where the entry has "
        "several envs and no wrapper but TrainingInfo, else dummy)",
    )
    p.add_argument("--num-threads", type=positive_int, default=1, metavar="N", help="torch threads")
    p.add_argument(
        "--eval-freq",
        type=_int,
        default=10_000,
        metavar="N",
        help="evaluate every N env steps over all envs (<= 0: never)",
    )
    p.add_argument(
        "--eval-episodes",
        type=positive_int,
        default=5,
        metavar="N",
        help="episodes per evaluation",
    )
    p.add_argument(
        "--save-freq",
        type=_int,
        default=25_000,
        metavar="N",
        help="checkpoint (with VecNormalize) every N env steps over all envs (<= 0: never)",
    )
    p.add_argument(
        "--verbose", type=_int, default=0, choices=[0, 1, 2], help="verbosity of SB3 and the zoo"
    )
    p.add_argument("--no-progress-bar", action="store_true", help=argparse.SUPPRESS)
    return p


def main(argv: list[str] | None = None) -> None:
    p = parser()
    args = p.parse_args(argv)
    hyperparams = dict(args.hyperparams or [])
    try:
        env_id, entry = prepare(args.env, args.conf_file, hyperparams, args.n_timesteps)
        out = args.out
        if args.update_shipped:
            out = MODEL_DIR / shipped_name(env_id, entry)
        elif out is not None and (Path(out) / "model.zip").exists():
            raise ValueError(f"--out {out!r} already holds a model; choose a new directory")
        if args.trained_agent:
            trained_agent_dir(args.trained_agent)
    except ValueError as exc:
        p.error(str(exc))
    run = train(
        env_id,
        conf_file=args.conf_file,
        hyperparams=hyperparams,
        seed=args.seed,
        n_timesteps=args.n_timesteps,
        log_folder=args.log_folder,
        out=out,
        device=args.device,
        vec_env=args.vec_env,
        eval_freq=args.eval_freq,
        n_eval_episodes=args.eval_episodes,
        save_freq=args.save_freq,
        max_minutes=args.max_minutes,
        progress=args.progress,
        print_freq=args.print_freq,
        num_threads=args.num_threads,
        verbose=args.verbose,
        trained_agent=args.trained_agent,
    )
    stats = json.loads((run / "train_stats.json").read_text())
    print(
        f"run {run}: {stats['timesteps']} steps in {stats['wall_time_s']} s "
        f"({stats['env_steps_per_s']} env steps/s)"
        + (f"; model directory {out}" if out is not None else "")
    )


if __name__ == "__main__":
    main()
