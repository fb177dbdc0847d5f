"""Hyperparameter files in rl-baselines3-zoo's format, read for stable-baselines3 and RLlib.

A file maps env ids to entries (``configs/ppo.yml``). An entry may name another file of the
folder with ``extends: <file>``: it is that file's entry of the same env id, its keys
replaced by the extending entry's (one level deep). :func:`load_config` resolves it, so the
agents that play beside the planner (``configs/ppo_grip.yml`` etc.) state only what differs
from the lifting entry of ``configs/ppo.yml``; ``python -m agents.train_ppo`` gives the zoo
the resolved entry (the zoo's own command reads files without ``extends``).

:func:`load_config` reads both the zoo's files and RLlib's (``configs/rllib_ppo.yml``);
:func:`get_entry`, :func:`check_entry`, :func:`ppo_kwargs` and :func:`make_vec_env` are for
stable-baselines3, whose values they build with the zoo's and SB3's own functions
(``rl_zoo3.utils.linear_schedule``, ``get_wrapper_class``, ``get_callback_list``, SB3's
``make_vec_env``). Importing this module needs neither (RLlib's env runners have neither):
:func:`wrapper_specs` reads ``env_wrapper`` without the zoo.
"""

from __future__ import annotations

import importlib
import inspect
import math
import os
from pathlib import Path
from typing import Any

import gymnasium as gym
import yaml

from grasp_env.cli import read_text

REPO = Path(__file__).resolve().parent.parent
#: The default hyperparameter file, as the commands show it: relative to the repository
#: (:func:`config_path` finds it from any working directory).
DEFAULT_CONFIG = "configs/ppo.yml"
#: The key that names the file an entry extends.
EXTENDS = "extends"
#: Keys of an entry that are not PPO constructor arguments: the zoo's, and ``env_id``, which
#: :func:`get_entry` adds.
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
#: PPO arguments that may be a schedule, ``"lin_<value>"`` (the zoo's keys).
SCHEDULES = ("learning_rate", "clip_range", "clip_range_vf")
#: PPO arguments that are counts, positive integers: stable-baselines3 checks them only when
#: it builds the model, after the run folder is made.
COUNTS = ("n_steps", "batch_size", "n_epochs")
#: Vector envs of the training envs. ``"auto"``: the batched env (:mod:`agents.batched`,
#: every env stepped by one compiled call) where the entry has several envs and no wrapper
#: but ``TrainingInfo`` (whose work it does), else DummyVecEnv (measured as fast as
#: SubprocVecEnv for 2 envs on 2 cores).
VEC_ENVS = ("auto", "batched", "dummy", "subproc")
#: Wrappers the batched env stands in for: it passes on only what training reads.
BATCHED_WRAPPERS = frozenset({"agents.wrappers.TrainingInfo"})


# ---------------------------------------------------------------------- files
def read_yaml(path: str | os.PathLike, what: str = "config file") -> Any:
    """A YAML file's data; fails with a one-line ``ValueError`` naming the file and where it
    is not valid (not UTF-8 text, not YAML)."""
    try:
        text = read_text(path)
    except ValueError as exc:
        raise ValueError(f"{what} {exc}") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ValueError(f"{what} {str(path)!r}: not valid YAML{where}: {problem}") from None


def config_path(path: str | os.PathLike) -> Path:
    """A hyperparameter file's path: ``path`` as given where it exists (relative to the
    working directory), else a relative path of the repository's (``configs/ppo.yml``), so
    that the commands find the shipped files from any directory."""
    path = Path(path)
    if path.is_absolute() or path.exists() or not (REPO / path).exists():
        return path
    return REPO / path


def load_config(path: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """Read a hyperparameter file (found by :func:`config_path`): ``{env id: entry}``, each
    ``extends`` resolved. Fails with a one-line ``ValueError`` naming the file and the bad
    part."""
    return _load(config_path(path), ())


def _load(path: Path, extending: tuple[Path, ...]) -> dict[str, dict[str, Any]]:
    """:func:`load_config` of ``path``, read for the files ``extending`` (which it may not
    extend in turn)."""
    config = read_yaml(path)
    if not isinstance(config, dict) or not config:
        raise ValueError(f"config file {str(path)!r}: expected a mapping of env ids to entries")
    entries = {}
    for key, entry in config.items():
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: entry {key!r} must be a mapping, got {entry!r}")
        if EXTENDS in entry:
            base_path = path.parent / str(entry[EXTENDS])
            if base_path.resolve() in {p.resolve() for p in (*extending, path)}:
                raise ValueError(f"{path}: entry {key!r} extends {str(base_path)!r}, a cycle")
            base = _load(base_path, (*extending, path))
            if key not in base:
                raise ValueError(f"{path}: entry {key!r} extends {str(base_path)!r}, without it")
            entry = {**base[key], **{k: v for k, v in entry.items() if k != EXTENDS}}
        if not isinstance(entry.get("env_kwargs") or {}, dict):
            raise ValueError(f"{path}: entry {key!r}: env_kwargs must be a mapping")
        entries[str(key)] = entry
    return entries


def get_entry(config: dict[str, dict[str, Any]], env_id: str) -> dict[str, Any]:
    """The entry of ``env_id`` with its ``env_id`` key; fails listing the env ids."""
    if env_id not in config:
        raise ValueError(f"env id {env_id!r} is not in the config; choose from {sorted(config)}")
    return {"env_id": env_id, **config[env_id]}


# ---------------------------------------------------------------------- values
def _expression(value: Any, key: str) -> Any:
    """A zoo value that may be a Python expression string (``"dict(...)"``), evaluated with
    the names the zoo gives it."""
    if not isinstance(value, str):
        return value
    import torch

    try:
        return eval(value, {"dict": dict, "nn": torch.nn, "th": torch})
    except Exception as exc:
        raise ValueError(f"{key} {value!r}: not a valid expression ({exc})") from None


def ppo_kwargs(entry: dict[str, Any]) -> dict[str, Any]:
    """PPO constructor arguments of an entry as the zoo builds them (``lin_<value>``:
    ``rl_zoo3.utils.linear_schedule``; ``policy_kwargs`` evaluated)."""
    from rl_zoo3.utils import linear_schedule

    kwargs = {k: v for k, v in entry.items() if k not in ENTRY_KEYS}
    if "policy_kwargs" in kwargs:
        kwargs["policy_kwargs"] = _expression(kwargs["policy_kwargs"], "policy_kwargs")
    for key in SCHEDULES:
        value = kwargs.get(key)
        if isinstance(value, bool) or not isinstance(value, int | float | str | None):
            raise ValueError(f"{key} {value!r}: expected a number or 'lin_<value>'")
        if isinstance(value, str):
            kind, _, start = value.partition("_")
            try:
                if kind != "lin":
                    raise ValueError
                kwargs[key] = linear_schedule(float(start))
            except ValueError:
                raise ValueError(f"{key} {value!r}: expected a number or 'lin_<value>'") from None
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


def monitor_kwargs(entry: dict[str, Any]) -> dict[str, Any]:
    """``Monitor`` arguments of an entry."""
    value = _expression(entry.get("monitor_kwargs", {}), "monitor_kwargs")
    if not isinstance(value, dict) or not isinstance(value.get("info_keywords", ()), tuple):
        raise ValueError(
            f"monitor_kwargs {entry['monitor_kwargs']!r}: expected a dict with a tuple as "
            "info_keywords, e.g. \"dict(info_keywords=('is_success',))\""
        )
    return value


def wrapper_specs(entry: dict[str, Any]) -> list[tuple[type[gym.Wrapper], dict]]:
    """The entry's ``env_wrapper`` as ``(class, kwargs)`` pairs, in the zoo's forms (a dotted
    path, ``{path: kwargs}``, or a list of them); fails naming a path it cannot import."""
    value = entry.get("env_wrapper")
    items = value if isinstance(value, list) else [] if value is None else [value]
    specs = []
    for item in items:
        if isinstance(item, dict) and len(item) != 1:
            raise ValueError(f"env_wrapper {item!r}: expected one {{path: kwargs}} per item")
        name, kwargs = next(iter(item.items())) if isinstance(item, dict) else (item, {})
        if not isinstance(kwargs or {}, dict):
            raise ValueError(f"env_wrapper {name!r}: its arguments must be a mapping")
        if not isinstance(name, str) or "." not in name:
            raise ValueError(f"env_wrapper {name!r}: expected a dotted path 'package.module.Class'")
        module, _, attr = name.rpartition(".")
        try:
            specs.append((getattr(importlib.import_module(module), attr), kwargs or {}))
        except (ImportError, AttributeError) as exc:
            raise ValueError(f"env_wrapper {name!r}: cannot import it ({exc})") from None
    return specs


def count_problem(key: str, value: Any) -> str | None:
    """Why ``value`` cannot be PPO's ``key`` where that is a count (:data:`COUNTS`), or
    None."""
    if key in COUNTS and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
        return f"{key} must be a positive integer, got {value!r}"
    return None


def check_entry(entry: dict[str, Any]) -> None:
    """Check every value of an entry (from :func:`get_entry`) and build one env of it, as the
    zoo will, before any training starts. Fails with a ``ValueError`` naming the entry and
    the bad value."""
    from rl_zoo3.utils import get_callback_list, get_wrapper_class
    from stable_baselines3 import PPO

    env_id = entry["env_id"]

    def fail(message: str) -> None:
        raise ValueError(f"entry {env_id!r}: {message}")

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
    for key in COUNTS:
        if key in entry and (problem := count_problem(key, entry[key])):
            fail(problem)
    if entry.get("normalize_advantage", True):  # stable-baselines3's assertions, and defaults
        if entry.get("batch_size", 64) < 2:
            fail("batch_size must be > 1 where advantages are normalized (normalize_advantage)")
        if entry.get("n_steps", 2048) * n_envs < 2:
            fail("n_steps x n_envs must be > 1 where advantages are normalized")
    try:
        if not isinstance(ppo_kwargs(entry).get("policy_kwargs", {}), dict):
            raise ValueError(f"policy_kwargs {entry['policy_kwargs']!r}: expected a dict")
        normalize_kwargs(entry)
        monitor_kwargs(entry)
        wrapper_specs(entry)
        get_callback_list(entry)
    except (ValueError, ImportError, AttributeError, TypeError) as exc:
        fail(str(exc))
    try:
        env = gym.make(env_id, **(entry.get("env_kwargs") or {}))
        wrap = get_wrapper_class(entry)
        (env if wrap is None else wrap(env)).close()
    except (gym.error.Error, TypeError, ValueError) as exc:
        fail(f"cannot build its env: {exc}")


# ---------------------------------------------------------------------- vector envs
def vec_env_of(entry: dict[str, Any], vec_env: str) -> str:
    """The vector env a run uses: ``vec_env``, with ``"auto"`` resolved (batched where the
    entry has several envs and no wrapper the batched env cannot stand in for); ValueError
    where ``"batched"`` is asked for an entry it cannot run."""
    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {list(VEC_ENVS)}, got {vec_env!r}")
    wrappers = {f"{cls.__module__}.{cls.__qualname__}" for cls, _ in wrapper_specs(entry)}
    possible = wrappers <= BATCHED_WRAPPERS
    if vec_env == "batched" and not possible:
        raise ValueError(
            f"vec_env='batched' steps the env itself, without the wrappers "
            f"{sorted(wrappers - BATCHED_WRAPPERS)}: use 'dummy' or 'subproc'"
        )
    if vec_env == "auto":
        return "batched" if possible and int(entry.get("n_envs", 1)) > 1 else "dummy"
    return vec_env


def make_vec_env(
    entry: dict[str, Any],
    n_envs: int,
    seed: int,
    vec_env: str = "auto",
    monitor_dir: str | os.PathLike | None = None,
):
    """``n_envs`` envs of an entry, seeded ``seed + rank``, each in a ``Monitor`` under the
    entry's wrappers as the zoo builds them (SB3's ``make_vec_env``), or the batched env
    under one ``VecMonitor`` (:func:`vec_env_of`); for timing PPO without the zoo."""
    from rl_zoo3.utils import get_wrapper_class
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    vec_env = vec_env_of({**entry, "n_envs": n_envs}, vec_env)
    env_kwargs = entry.get("env_kwargs") or {}
    if vec_env == "batched":
        from agents.batched import make_vec_env as batched_vec_env

        venv = batched_vec_env(entry["env_id"], n_envs, seed, **env_kwargs)
        return VecMonitor(venv, None if monitor_dir is None else str(Path(monitor_dir) / "0"))
    return sb3_make_vec_env(
        entry["env_id"],
        n_envs,
        seed,
        env_kwargs=env_kwargs,
        monitor_dir=None if monitor_dir is None else str(monitor_dir),
        wrapper_class=get_wrapper_class(entry),
        vec_env_cls=SubprocVecEnv if vec_env == "subproc" and n_envs > 1 else DummyVecEnv,
        monitor_kwargs=monitor_kwargs(entry),
    )
