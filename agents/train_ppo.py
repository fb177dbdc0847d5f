"""Train a PPO agent (stable-baselines3, CPU) on one env id of a zoo-format hyperparameter file.

    python -m agents.train_ppo --env FrictionlessGrasp-v0 [--conf configs/ppo.yml] [--seed 0]
        [-n N] [--max-minutes M] [--params KEY:VALUE ...] [-f runs] [--out DIR | --update-shipped]

Runs from any directory: a relative ``--conf`` not found from the working directory is the
repository's (``configs/ppo.yml``); runs go below ``-f`` (relative to the working
directory). The zoo's short spellings ``-conf`` and ``-params`` work as well.

The training is rl-baselines3-zoo's (:class:`rl_zoo3.exp_manager.ExperimentManager`: the
entry's schedules, ``VecNormalize``, ``Monitor``, ``env_wrapper`` and ``callback``,
evaluation and checkpoints, the run folder ``<log folder>/ppo/<env id>_<n>``), on the entry
:mod:`agents.config` reads (``extends`` resolved, every value checked first). This module
adds what the zoo lacks: the batched env (:mod:`agents.batched`) for the training envs, an
evaluation env seeded apart from them, a wall-time limit, a progress line every
``--print-freq`` steps, ``train_stats.json`` (steps, wall time, env steps/s) and model
directories (:mod:`agents.models`), written only to ``--out`` or, with ``--update-shipped``,
to ``agents/models/<name>``. See ``docs/training.md``.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import json
import math
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import torch
import yaml
from rl_zoo3.exp_manager import ExperimentManager
from rl_zoo3.utils import StoreDict
from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecMonitor

from agents import config
from agents.callbacks import ProgressLines, WallTimeLimit, timed
from agents.models import MODEL_DIR, SHIPPED, export_model, shipped_name
from grasp_env.cli import HelpFormatter, out_dir_problem, positive_float, positive_int, seed_int
from grasp_env.envs import ENV_ID

#: What ``benchmarks`` import from here.
load_config, make_vec_env = config.load_config, config.make_vec_env
normalize_kwargs, ppo_kwargs = config.normalize_kwargs, config.ppo_kwargs
#: Offset of the evaluation env's seed from the training seed (training envs use ``seed ..
#: seed + n_envs - 1``; ``rl_zoo3.train`` seeds its evaluation env like training env 0).
EVAL_SEED_OFFSET = 1000
#: Env kwargs the evaluation during training leaves out: the reward weights (it reports the
#: env's own return) and the shape pool (it meets new shapes).
TRAINING_ONLY = ("reward_", "shape_pool")


def get_entry(conf: dict[str, dict[str, Any]], name: str) -> dict[str, Any]:
    """:func:`agents.config.get_entry`, the env id also named by a model shipped for it
    (``fig13_fingers``), as ``benchmarks.ppo_throughput`` names it."""
    by_model = {
        model: env for (file, env), model in SHIPPED.items() if file == config.DEFAULT_CONFIG
    }
    return config.get_entry(conf, by_model.get(name, name))


class Manager(ExperimentManager):
    """The zoo's ExperimentManager with the training envs in the batched env where
    ``batched`` is set, and the evaluation env seeded ``seed + EVAL_SEED_OFFSET`` (so that
    it does not replay training env 0's episodes) and made with the entry's task kwargs
    (the zoo passes it only those of its command line)."""

    batched = False

    def create_envs(self, n_envs: int, eval_env: bool = False, no_log: bool = False):
        if not eval_env and self.batched:  # with the zoo's monitor, wrapper, normalization
            from agents.batched import make_vec_env as batched_vec_env

            env = batched_vec_env(self.env_name.gym_id, n_envs, self.seed, **self.env_kwargs)
            log = None if no_log else os.path.join(self.save_path, "0")
            env = VecMonitor(env, log, **self.monitor_kwargs)
            env = env if self.vec_env_wrapper is None else self.vec_env_wrapper(env)
            return self._maybe_normalize(env, False)
        if not eval_env:
            return super().create_envs(n_envs, eval_env, no_log)
        seed, kwargs, wrapper = self.seed, self.eval_env_kwargs, self.vec_env_wrapper
        self.seed += EVAL_SEED_OFFSET
        if self.batched:  # wrapped like the training envs, for SB3's statistics sync
            self.vec_env_wrapper = functools.partial(_monitored, wrapper=wrapper)
        self.eval_env_kwargs = {
            k: v for k, v in (self.env_kwargs or {}).items() if not k.startswith(TRAINING_ONLY)
        }
        try:
            return super().create_envs(n_envs, eval_env, no_log)
        finally:
            self.seed, self.eval_env_kwargs, self.vec_env_wrapper = seed, kwargs, wrapper


def _monitored(env, wrapper):
    """``env`` in a ``VecMonitor`` (no file), under ``wrapper`` (None: none)."""
    return VecMonitor(env) if wrapper is None else wrapper(VecMonitor(env))


def prepare(env_id, conf_file=config.DEFAULT_CONFIG, hyperparams=None, n_timesteps=None) -> dict:
    """The entry of a training run, overrides applied, checked (ValueError)."""
    entry = {**config.get_entry(config.load_config(conf_file), env_id), **(hyperparams or {})}
    if n_timesteps is not None:
        entry["n_timesteps"] = n_timesteps
    config.check_entry(entry)
    return entry


def train(env: str, **options) -> Path:
    """Train PPO on the entry of ``env`` with the zoo; returns the run folder
    ``<log_folder>/ppo/<env id>_<n>`` (with ``train_stats.json``). ``options`` are the
    command's (:func:`parser`'s names and defaults): ``hyperparams`` override the entry's
    keys; ``eval_freq`` and ``save_freq`` count env steps over all envs (<= 0: off);
    ``max_minutes`` stops training early (the model is saved as it is then);
    ``trained_agent`` (a model directory) starts from that model and its VecNormalize
    statistics (the zoo's ``--trained-agent``); ``out`` also writes a model directory."""
    args = parser().parse_args(["--env", env])
    for key, value in options.items():
        if not hasattr(args, key):
            raise TypeError(f"train() got an unknown option {key!r}")
        setattr(args, key, value)
    entry = prepare(env, args.conf_file, args.hyperparams, args.n_timesteps)
    args.vec_env, total = config.vec_env_of(entry, args.vec_env), int(float(entry["n_timesteps"]))
    torch.set_num_threads(args.num_threads)  # 1: measured faster on 2 shared cores
    set_random_seed(args.seed)
    with tempfile.TemporaryDirectory(prefix="train_ppo_") as staging:
        resolved = Path(staging) / "config.yml"  # the zoo reads files without `extends`
        resolved.write_text(yaml.safe_dump({env: config.load_config(args.conf_file)[env]}))
        trained = _zoo_layout(args.trained_agent, env, staging) if args.trained_agent else ""
        zoo_args = argparse.Namespace(**vars(args), algo="ppo", env_kwargs=None)
        # fmt: off
        manager = Manager(
            zoo_args, "ppo", env, str(args.log_folder), n_timesteps=total, seed=args.seed,
            eval_freq=args.eval_freq, n_eval_episodes=args.eval_episodes,
            save_freq=args.save_freq, hyperparams=args.hyperparams or None, log_interval=-1,
            verbose=args.verbose, device=args.device, config=str(resolved),
            vec_env_type="dummy" if args.vec_env == "batched" else args.vec_env,
            show_progress=args.progress, trained_agent=trained,
        )
        # fmt: on
        manager.batched = args.vec_env == "batched"
        run = Path(manager.save_path)
        manager.tensorboard_log = str(run / "tb")
        model, saved = manager.setup_experiment()
    evaluation = next((c for c in manager.callbacks if isinstance(c, EvalCallback)), None)
    eval_seconds = timed(evaluation) if evaluation is not None else [0.0]
    for callback in manager.callbacks:
        if isinstance(callback, CheckpointCallback):
            callback.save_vecnormalize = True  # a checkpoint is useless without its statistics
    limit = None if args.max_minutes is None else 60.0 * args.max_minutes
    manager.callbacks.append(WallTimeLimit(limit))
    if args.print_freq > 0 and not args.progress:
        manager.callbacks.append(ProgressLines(args.print_freq, total))
    load_start, start = os.getloadavg()[0], time.perf_counter()
    manager.learn(model)
    wall = time.perf_counter() - start
    manager.save_trained_model(model)
    last_eval = evaluation.last_mean_reward if evaluation is not None else math.nan
    steps = int(model.num_timesteps)
    stats = {
        "env_id": env,
        "seed": args.seed,
        "timesteps": steps,
        "timesteps_planned": total,
        "wall_time_s": round(wall, 1),
        "env_steps_per_s": round(steps / wall, 1),
        "eval_time_s": round(eval_seconds[0], 1),
        "env_steps_per_s_without_eval": round(steps / (wall - eval_seconds[0]), 1),
        "n_envs": manager.n_envs,
        "vec_env": args.vec_env if manager.n_envs > 1 else "dummy",
        "torch_threads": torch.get_num_threads(),
        "load_average_1min": [round(load_start, 1), round(os.getloadavg()[0], 1)],
        "device": args.device,
        "cpu": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "last_eval_mean_reward": float(last_eval) if math.isfinite(last_eval) else None,
        "run": str(run),
        "trained_agent": str(args.trained_agent) if args.trained_agent else None,
        "versions": {
            "python": platform.python_version(),
            "torch": torch.__version__,
            "stable_baselines3": sys.modules["stable_baselines3"].__version__,
            "rl_zoo3": importlib.import_module("rl_zoo3").__version__,
        },
    }
    (run / "train_stats.json").write_text(json.dumps(stats, indent=2) + "\n")
    if args.out is not None:
        export_model(run, args.out, {env: {**saved, "n_timesteps": steps}})
    return run


def _zoo_layout(model_dir, env_id: str, folder: str) -> str:
    """A model directory copied into ``folder`` where the zoo looks for a trained agent
    (``model.zip``, its VecNormalize statistics in ``<env id>/vecnormalize.pkl`` beside it);
    the path of its ``model.zip``."""
    model_dir, staged = trained_agent_dir(model_dir), Path(folder)
    shutil.copy(model_dir / "model.zip", staged / "model.zip")
    if (model_dir / "vecnormalize.pkl").is_file():
        (staged / env_id).mkdir()
        shutil.copy(model_dir / "vecnormalize.pkl", staged / env_id / "vecnormalize.pkl")
    return str(staged / "model.zip")


def trained_agent_dir(model_dir: str | os.PathLike) -> Path:
    """``model_dir`` as a path, checked to hold a model (``ValueError`` naming it)."""
    if not (Path(model_dir) / "model.zip").is_file():
        raise ValueError(f"--trained-agent {str(model_dir)!r}: no model.zip there")
    return Path(model_dir)


class Hyperparams(StoreDict):
    """The zoo's ``--hyperparams`` (``key:value``, the value a Python expression), where a
    value that is no expression is a string (``learning_rate:lin_3e-4``)."""

    def __call__(self, parser, namespace, values, option_string=None):
        items = {}
        for item in values:
            key, sep, text = item.partition(":")
            if not sep or not key:
                parser.error(f"{option_string}: expected key:value, got {item!r}")
            try:
                super().__call__(parser, namespace, [item], option_string)
                items.update(getattr(namespace, self.dest))
            except Exception:
                items[key] = text
            if problem := config.count_problem(key, items[key]):
                parser.error(f"{option_string} {item!r}: {problem}")
        setattr(namespace, self.dest, items)


class _Parser(argparse.ArgumentParser):
    """Reports a bad argument or file in one line (no usage block)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


# fmt: off
def parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m agents.train_ppo", formatter_class=HelpFormatter, description=(
        "Train PPO (stable-baselines3 through rl-baselines3-zoo's ExperimentManager) on one env id "
        "of a zoo-format hyperparameter file. Each run goes to a new folder <log folder>/ppo/<env "
        "id>_<n>; nothing is overwritten unless --update-shipped is given. See docs/training.md."
    ))
    add = p.add_argument
    add("--env", "--env-id", dest="env", default=ENV_ID, metavar="ID", help="env id")
    add("--conf", "--conf-file", "--config", "-conf", dest="conf_file",
        default=config.DEFAULT_CONFIG, metavar="FILE",
        help="zoo-format hyperparameter file (a relative path not found from here: the "
        "repository's)")
    add("--seed", type=seed_int, default=0, metavar="N", help="training env k is seeded seed + k")
    add("-n", "--n-timesteps", type=positive_int, metavar="N",
        help="total env steps (default: the entry's n_timesteps)")
    add("--max-minutes", type=positive_float, metavar="M",
        help="stop after M minutes of wall time (the model is saved as it is then)")
    add("--params", "--hyperparams", "-params", dest="hyperparams", nargs="+", action=Hyperparams,
        metavar="KEY:VALUE",
        help="override entry keys, e.g. n_steps:256 learning_rate:lin_3e-4")
    add("-f", "--log-folder", default="runs", metavar="DIR",
        help="runs go to DIR/ppo/<env id>_<n>, a new n each run")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--out", metavar="DIR", help="also write a model directory to DIR")
    where.add_argument("--update-shipped", action="store_true",
                       help="also write it to agents/models/<name>, replacing the shipped one")
    add("-i", "--trained-agent", metavar="DIR",
        help="start from this model directory (model.zip, VecNormalize statistics)")
    add("-P", "--progress", action="store_true", help="show a progress bar")
    add("--print-freq", type=int, default=5_000, metavar="STEPS",
        help="without --progress, a progress line every STEPS env steps (0: never)")
    add("--device", default="cpu", choices=["cpu", "cuda", "auto"], help="torch device")
    add("--vec-env", default="auto", choices=config.VEC_ENVS, help="vector env of the training "
        "envs (auto: the batched env where the entry has several envs and no wrapper but "
        "TrainingInfo, else dummy)")
    add("--num-threads", type=positive_int, default=1, metavar="N", help="torch threads")
    add("--eval-freq", type=int, default=10_000, metavar="N",
        help="evaluate every N env steps over all envs (<= 0: never)")
    add("--eval-episodes", type=positive_int, default=5, metavar="N", help="per evaluation")
    add("--save-freq", type=int, default=25_000, metavar="N",
        help="checkpoint (with VecNormalize) every N env steps, all envs (<= 0: never)")
    add("--verbose", type=int, default=0, choices=[0, 1, 2], help="verbosity of SB3, the zoo")
    return p
# fmt: on


def main(argv: list[str] | None = None) -> None:
    p = parser()
    args = p.parse_args(argv)
    try:
        config.load_config(args.conf_file)
    except ValueError as exc:
        p.error(f"--conf {exc}")
    try:
        prepare(args.env, args.conf_file, args.hyperparams, args.n_timesteps)
        if args.update_shipped:
            args.out = str(MODEL_DIR / shipped_name(args.conf_file, args.env))
        elif args.out is not None and (Path(args.out) / "model.zip").exists():
            raise ValueError(f"--out {args.out!r} already holds a model; choose a new directory")
        if args.trained_agent:
            trained_agent_dir(args.trained_agent)
    except ValueError as exc:
        p.error(str(exc))
    # the arguments agree; now the folders (the log folder made here, the model's after
    # training, so that an interrupted run leaves none behind)
    for option, folder, create in (("--out", args.out, False), ("-f", args.log_folder, True)):
        if folder is not None and (problem := out_dir_problem(Path(folder), create)):
            p.error(f"{option} {problem}")
    run = train(**vars(args))
    stats = json.loads((run / "train_stats.json").read_text())
    where = f"; model directory {args.out}" if args.out is not None else ""
    print(
        f"run {run}: {stats['timesteps']} steps in {stats['wall_time_s']} s "
        f"({stats['env_steps_per_s']} env steps/s){where}"
    )


if __name__ == "__main__":
    main()
