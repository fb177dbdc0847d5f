"""Ray and the training loop of an RLlib run: the cluster joined or a local instance started,
where the env runners run, and ``Algorithm.train()`` called to a budget with a line per
iteration (env steps, mean return, success rate, env steps/s) and checkpoints."""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # the driver never phones home

if TYPE_CHECKING:
    from ray.rllib.algorithms.algorithm import Algorithm


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
