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
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # the driver never phones home

import gymnasium as gym
import yaml

from agents.config import REPO, load_config, wrapper_specs
from agents.rllib_policy import CHECKPOINT_DIR
from grasp_env.cli import HelpFormatter, nonnegative_int, out_dir_problem, positive_int

if TYPE_CHECKING:
    from ray.rllib.algorithms.algorithm import Algorithm
    from ray.rllib.algorithms.ppo import PPOConfig

DEFAULT_CONFIG = REPO / "configs" / "rllib_ppo.yml"
#: PPOConfig methods whose keyword arguments an entry may set, section by section.
SECTIONS = ("env_runners", "training", "rl_module")
#: Keys of an entry besides the sections.
ENTRY_KEYS = ("env_kwargs", "env_wrapper", "n_timesteps", "normalize_obs")
#: Settings the command line owns.
COMMAND_LINE_KEYS = ("num_env_runners",)
#: Episodes over which the success rate is averaged (RLlib's window for episode returns).
SUCCESS_WINDOW = 100


# ---------------------------------------------------------------------- config
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


# ---------------------------------------------------------------------- ray
def check_address(text: str) -> str:
    """``auto``, ``HOST:PORT`` or ``ray://HOST:PORT``."""
    host, sep, port = text.removeprefix("ray://").rpartition(":")
    if text == "auto" or (sep and host and port.isdigit() and 0 < int(port) < 65536):
        return text
    raise argparse.ArgumentTypeError(f"expected auto, HOST:PORT or ray://HOST:PORT, got {text!r}")


def start_ray(address: str | None, num_cpus: int, ship_code: bool) -> None:
    """Join the cluster at ``address``, or start a local instance of ``num_cpus`` CPUs that
    uses loopback only. ``ship_code`` sends this checkout's ``grasp_env`` and ``agents`` to
    every worker (runtime_env ``py_modules``) instead of their installs."""
    import ray
    from ray._private import ray_constants

    import agents
    import grasp_env

    if address is None:
        # Ray resolves 127.0.0.1, even given as the node address, to the machine's outward
        # address, and listens there. With clusters off it takes the loopback address
        # instead; the variable reaches the processes it starts, the constant this one.
        os.environ[ray_constants.ENABLE_RAY_CLUSTERS_ENV_VAR] = "0"
        ray_constants.ENABLE_RAY_CLUSTER = False
        ray.init(
            address="local",  # never attach to a cluster found on this machine
            num_cpus=num_cpus,
            include_dashboard=False,
            log_to_driver=False,
        )
        return
    runtime_env = None
    if ship_code:
        modules = [Path(m.__file__).parent for m in (grasp_env, agents)]
        runtime_env = {"py_modules": [str(m) for m in modules]}
    try:
        ray.init(address=address, runtime_env=runtime_env, log_to_driver=False)
    except (ConnectionError, ray.exceptions.AuthenticationError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if os.environ.get("RAY_AUTH_MODE") != "token":
            reason += " (a cluster with token authentication needs RAY_AUTH_MODE=token here)"
        raise ConnectionError(f"cannot connect to the Ray cluster at {address}: {reason}") from None


def cluster_cpus() -> float:
    import ray

    return float(ray.cluster_resources().get("CPU", 0.0))


def runner_nodes(algo: Algorithm) -> str:
    """Where the remote env runners run: ``"<node ip> x<count>, ..."``."""
    import collections

    import ray

    ips = algo.env_runner_group.foreach_env_runner(
        lambda runner: ray.util.get_node_ip_address(), local_env_runner=False
    )
    counts = collections.Counter(ips)
    return ", ".join(f"{ip} x{n}" for ip, n in sorted(counts.items())) or "the driver"


# ---------------------------------------------------------------------- training
def _metric(result: dict[str, Any], key: str) -> float:
    from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS

    value = result.get(ENV_RUNNER_RESULTS, {}).get(key, math.nan)
    return float(value) if value is not None else math.nan


def env_steps(result: dict[str, Any]) -> int:
    """Env steps sampled so far (all env runners): 0 before any env runner has returned
    samples (RLlib ends an iteration early, without that count, when none does within
    ``env_runners.sample_timeout_s``, 60 s by default)."""
    from ray.rllib.utils.metrics import NUM_ENV_STEPS_SAMPLED_LIFETIME

    steps = _metric(result, NUM_ENV_STEPS_SAMPLED_LIFETIME)
    return 0 if math.isnan(steps) else int(steps)


def progress_line(iteration: int, result: dict[str, Any], rate: float, seconds: float) -> str:
    """One line per iteration: env steps, mean return, success rate, env steps/s."""
    from ray.rllib.utils.metrics import EPISODE_RETURN_MEAN

    def num(x: float, fmt: str) -> str:
        return "-" if math.isnan(x) else format(x, fmt)

    return (
        f"iter {iteration:4d}  env steps {env_steps(result):8d}  "
        f"return {num(_metric(result, EPISODE_RETURN_MEAN), '8.2f')}  "
        f"success {num(_metric(result, 'success_rate'), '4.2f')}  "
        f"{rate:6.1f} steps/s  ({seconds:.1f} s)"
    )


def train(
    algo: Algorithm,
    *,
    iterations: int | None = None,
    timesteps: int | None = None,
    checkpoint: Path | None = None,
    checkpoint_every: int = 10,
    log: Callable[[str], object] | None = None,
) -> dict[str, Any]:
    """Call ``algo.train()`` until ``iterations`` or ``timesteps`` (env steps) is reached,
    passing each iteration's line to ``log`` (default: print it at once) and saving to
    ``checkpoint`` every ``checkpoint_every`` iterations and at the end. Returns steps, wall
    time of the ``train()`` calls and env steps/s over them (start-up and checkpoints
    excluded)."""
    from ray.rllib.utils.metrics import EPISODE_RETURN_MEAN

    if (iterations is None) == (timesteps is None):
        raise ValueError("give exactly one of iterations and timesteps")
    log = log or (lambda line: print(line, flush=True))
    steps, wall, iteration, result = 0, 0.0, 0, {}
    while (iterations is None or iteration < iterations) and (
        timesteps is None or steps < timesteps
    ):
        start = time.perf_counter()
        result = algo.train()
        seconds = time.perf_counter() - start
        iteration += 1
        new_steps = env_steps(result)
        line = progress_line(iteration, result, (new_steps - steps) / seconds, seconds)
        if new_steps == steps:
            line += "  no env runner returned samples in time"
        log(line)
        steps, wall = new_steps, wall + seconds
        if checkpoint is not None and iteration % checkpoint_every == 0:
            algo.save_to_path(checkpoint)
    if checkpoint is not None:
        algo.save_to_path(checkpoint)
    return {
        "iterations": iteration,
        "timesteps": steps,
        "wall_time_s": round(wall, 1),
        "env_steps_per_s": round(steps / wall, 1) if wall > 0 else math.nan,
        "last_episode_return_mean": _metric(result, EPISODE_RETURN_MEAN),
        "last_success_rate": _metric(result, "success_rate"),
    }


# ---------------------------------------------------------------------- command


def _out_problem(out: Path) -> str | None:
    """Why ``--out`` cannot take a run (None if it can): inside the repository only
    ``runs/`` may receive checkpoints."""
    path = out.resolve()
    if path.is_relative_to(REPO) and not path.is_relative_to(REPO / "runs"):
        return f"--out {str(out)!r} is inside the repository; use runs/... or a path outside it"
    problem = out_dir_problem(out)
    return None if problem is None else f"--out {problem}"


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
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--checkpoint-every", type=positive_int, default=10, help="iterations")
    args = parser.parse_args(argv)
    if args.address is None and args.ship_code:
        parser.error("--ship-code needs --address (a local instance uses this checkout)")
    if args.address is not None and args.num_cpus is not None:
        parser.error("--num-cpus is for a local instance; a cluster has the CPUs it has")
    try:
        entry = get_entry(load_config(args.config), args.env)
    except ValueError as exc:
        parser.error(str(exc))
    import grasp_env  # noqa: F401  (registers its env ids)

    try:
        gym.spec(args.env)
    except gym.error.Error as exc:
        parser.error(f"--env {args.env!r}: {exc}")
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
