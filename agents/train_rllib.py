"""Train PPO with Ray RLlib (new API stack) on an env id of ``configs/rllib_ppo.yml``.

    python -m agents.train_rllib --env FrictionlessGrasp-v0 --num-env-runners 2 \
        [--address auto|HOST:PORT|ray://HOST:PORT] [--ship-code] [--config FILE] \
        [--iterations K | --timesteps T] [--out DIR] [--seed S]

Without ``--address`` it starts a Ray instance of its own on this machine (loopback only, no
dashboard); with one it joins that cluster, whose nodes sample with the env runners. Each
iteration prints env steps, mean episode return, success rate and env steps/s. ``--out``
(default ``runs/rllib/<env id>``) receives ``checkpoint/`` (``Algorithm.save_to_path``),
``config.yml`` (the entry as used) and ``train_stats.json``; ``agents.evaluate
--rllib-checkpoint`` evaluates it. See ``docs/rllib.md``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import sys
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import yaml

from agents.config import REPO, load_config
from agents.rllib_config import EntryEnv, build_config, compile_env, env_config, get_entry
from agents.rllib_policy import CHECKPOINT_DIR
from agents.rllib_training import check_address, cluster_cpus, runner_nodes, start_ray, train
from grasp_env.cli import HelpFormatter, nonnegative_int, out_dir_problem, positive_int, seed_int

DEFAULT_CONFIG = REPO / "configs" / "rllib_ppo.yml"


# ---------------------------------------------------------------------- command


def _out_problem(out: Path) -> str | None:
    """Why ``--out`` cannot take a run (None if it can): inside the repository only
    ``runs/`` may receive checkpoints."""
    path = out.resolve()
    if path.is_relative_to(REPO) and not path.is_relative_to(REPO / "runs"):
        return f"--out {str(out)!r} is inside the repository; use runs/... or a path outside it"
    problem = out_dir_problem(out)
    return None if problem is None else f"--out {problem}"


def rllib_installed() -> bool:
    """Whether Ray RLlib can be imported (the ``rllib`` extra)."""
    try:
        return importlib.util.find_spec("ray.rllib") is not None
    except ImportError:  # no ray at all
        return False


def parse_args(argv: list[str] | None) -> tuple[argparse.Namespace, dict[str, Any]]:
    """Parse and check everything that can be checked before Ray starts; returns the
    arguments and the entry."""
    parser = argparse.ArgumentParser(
        prog="python -m agents.train_rllib", description=__doc__, formatter_class=HelpFormatter
    )
    parser.add_argument("--env", required=True, help="env id (a top-level key of --config)")
    parser.add_argument("--num-env-runners", type=nonnegative_int, required=True)
    parser.add_argument("--config", default=str(DEFAULT_CONFIG), help="RLlib PPO YAML file")
    parser.add_argument("--address", type=check_address, help="Ray cluster (default: local)")
    parser.add_argument(
        "--ship-code", action="store_true", help="send grasp_env and agents to the cluster"
    )
    parser.add_argument(
        "--num-cpus",
        type=positive_int,
        help="CPUs of the local instance (default: all cores, one per env runner at least)",
    )
    stop = parser.add_mutually_exclusive_group()
    stop.add_argument("--iterations", type=positive_int, help="training iterations")
    stop.add_argument("--timesteps", type=positive_int, help="env steps (default: entry's)")
    parser.add_argument("--out", help="run directory (default: runs/rllib/<env id>)")
    parser.add_argument("--seed", type=seed_int, default=0)
    parser.add_argument("--checkpoint-every", type=positive_int, default=10, help="iterations")
    args = parser.parse_args(argv)
    if args.address is None and args.ship_code:
        parser.error("--ship-code needs --address (a local instance uses this checkout)")
    if args.address is not None and args.num_cpus is not None:
        parser.error("--num-cpus is for a local instance; a cluster has the CPUs it has")
    try:
        config = load_config(args.config)
    except ValueError as exc:
        parser.error(f"--config {exc}")
    try:
        entry = get_entry(config, args.env)
    except ValueError as exc:
        parser.error(str(exc))
    import grasp_env  # noqa: F401  (registers its env ids)

    try:
        gym.spec(args.env)
    except gym.error.Error as exc:
        parser.error(f"--env {args.env!r}: {exc}")
    if not rllib_installed():
        parser.error(
            "Ray RLlib is not installed: install the rllib extra, pip install -e '.[rllib]' "
            "(in a venv of its own: docs/rllib.md)"
        )
    try:
        EntryEnv(env_config(entry, args.env)).close()
    except (gym.error.Error, TypeError, ValueError) as exc:
        parser.error(f"entry {args.env!r}: cannot build its env: {exc}")
    try:
        build_config(entry, args.env, args.num_env_runners, args.seed).validate()
    except ValueError as exc:
        parser.error(f"entry {args.env!r}: {exc}")
    args.out = Path(args.out) if args.out else Path("runs") / "rllib" / args.env
    if problem := _out_problem(args.out):
        parser.error(problem)
    if args.iterations is None and args.timesteps is None:
        args.timesteps = int(entry["n_timesteps"])
    return args, entry


def main(argv: list[str] | None = None) -> None:
    import torch

    args, entry = parse_args(argv)
    torch.set_num_threads(1)  # the learner, as in agents.train_ppo
    if (seconds := compile_env(entry, args.env, args.seed)) > 10:
        print(f"compiled the simulator in {seconds:.0f} s (cached for later runs)", flush=True)
    try:
        start_ray(
            args.address,
            args.num_cpus or max(os.cpu_count() or 1, args.num_env_runners),
            args.ship_code,
        )
    except ConnectionError as exc:
        sys.exit(f"train_rllib: {exc}")
    import ray

    try:
        if (cpus := cluster_cpus()) < args.num_env_runners:
            sys.exit(
                f"train_rllib: the cluster has {cpus:g} CPUs; "
                f"{args.num_env_runners} env runners need one each"
            )
        load = os.getloadavg()[0]
        used = dict(entry)  # beside the checkpoint, for agents.evaluate
        config_file = args.out / "config.yml"
        config_file.write_text(yaml.safe_dump({args.env: used}, sort_keys=False))
        algo = build_config(entry, args.env, args.num_env_runners, args.seed).build_algo()
        print(f"env runners on: {runner_nodes(algo)}", flush=True)
        stats = train(
            algo,
            iterations=args.iterations,
            timesteps=args.timesteps,
            checkpoint=(args.out / CHECKPOINT_DIR).resolve(),
            checkpoint_every=args.checkpoint_every,
        )
        algo.stop()
    finally:
        ray.shutdown()
    used["n_timesteps"] = stats["timesteps"]
    config_file.write_text(yaml.safe_dump({args.env: used}, sort_keys=False))
    stats = {
        "env_id": args.env,
        "seed": args.seed,
        **stats,
        "num_env_runners": args.num_env_runners,
        "address": args.address or "local",
        "load_average_1min": [round(load, 1), round(os.getloadavg()[0], 1)],
        "cpu": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "versions": {
            "python": platform.python_version(),
            "ray": ray.__version__,
            "torch": torch.__version__,
            "gymnasium": gym.__version__,
        },
    }
    (args.out / "train_stats.json").write_text(json.dumps(stats, indent=2) + "\n")
    print(
        f"saved {args.out / CHECKPOINT_DIR}: {stats['timesteps']} steps in "
        f"{stats['wall_time_s']} s ({stats['env_steps_per_s']} env steps/s)"
    )


if __name__ == "__main__":
    main()
