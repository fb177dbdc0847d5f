"""PPO training throughput of Ray RLlib against stable-baselines3, same settings, same run.

Trains ``FrictionlessGrasp-v0`` (the paper's fig13 set-up) on this machine: stable-baselines3
PPO with ``configs/ppo.yml``'s entry (2 envs x n_steps 512, DummyVecEnv and SubprocVecEnv, as
``ppo_throughput.py`` measures it) and RLlib PPO with ``configs/rllib_ppo.yml``'s (the same
1024-step batches, epochs, minibatches, network and observation filter) on a local Ray
instance with 0 (the driver samples), 1 and 2 env runners of 1 or 2 envs each. Every
trainer runs one torch thread in its learner and the same number of env steps; the rate is
env steps over the wall time of ``PPO.learn`` / the ``Algorithm.train()`` calls
(construction and Ray's start-up excluded, the first update included). Needs ``ray[rllib]``
and stable-baselines3 (``pip install -e ".[rllib,train]"``).

Usage: ``python -m benchmarks.rllib_throughput [--quick] [--iterations K] [--env ID] [--out FILE]``
"""

from __future__ import annotations

import importlib.util
import os
import time
from pathlib import Path

from benchmarks.common import REPO, headless, parser, table, write
from grasp_env.cli import positive_int

#: RLlib set-ups: (env runners, envs per runner). Two envs in one process is what SB3's
#: DummyVecEnv does; RLlib then batches their forward passes and connector calls.
RLLIB_SETUPS = ((0, 1), (0, 2), (1, 1), (1, 2), (2, 1))
VEC_ENVS = ("dummy", "subproc")


def rllib_rate(
    entry: dict, env_id: str, runners: int, envs: int, iterations: int, seed: int = 0
) -> tuple[float, float]:
    """Env steps/s of ``iterations`` calls of ``Algorithm.train()`` on ``env_id`` with
    ``runners`` env runners of ``envs`` envs each (Ray already started), and the first
    iteration's learner update in seconds."""
    from ray.rllib.utils.metrics import LEARNER_UPDATE_TIMER, TIMERS

    from agents.rllib_config import build_config
    from agents.rllib_training import env_steps

    config = build_config(entry, env_id, runners, seed)
    algo = config.env_runners(num_envs_per_env_runner=envs).build_algo()
    wall, learner = 0.0, 0.0
    for i in range(iterations):
        start = time.perf_counter()
        result = algo.train()
        wall += time.perf_counter() - start
        if i == 0:  # RLlib's timers are moving averages; the first one is exact
            learner = float(result[TIMERS][LEARNER_UPDATE_TIMER])
    steps = env_steps(result)
    algo.stop()
    return steps / wall, learner


def run(
    quick: bool, out: Path, env_id: str = "FrictionlessGrasp-v0", iterations: int | None = None
) -> Path:
    """Measure both libraries and write the markdown page."""
    import ray
    import torch

    from agents.config import load_config
    from agents.rllib_config import get_entry
    from agents.rllib_training import start_ray
    from agents.train_ppo import get_entry as sb3_entry
    from agents.train_ppo import load_config as sb3_config
    from benchmarks.ppo_throughput import steps_per_second, warmed_model

    headless()
    torch.set_num_threads(1)
    iterations = iterations or (2 if quick else 8)
    sb3 = sb3_entry(sb3_config(REPO / "configs" / "ppo.yml"), env_id)
    rllib = get_entry(load_config(REPO / "configs" / "rllib_ppo.yml"), env_id)
    batch = int(sb3["n_envs"]) * int(sb3["n_steps"])
    steps = iterations * batch
    rows, baseline = [], None
    for vec_env in VEC_ENVS:
        model = warmed_model(sb3, vec_env)
        rate = steps_per_second(model, steps)
        model.get_env().close()
        baseline = baseline or rate
        load = os.getloadavg()[0]
        print(f"stable-baselines3 {vec_env}: {rate:.0f} env steps/s (load {load:.1f})")
        label = f"stable-baselines3, {sb3['n_envs']} envs, {vec_env.capitalize()}VecEnv"
        processes = 1 if vec_env == "dummy" else 1 + int(sb3["n_envs"])
        rows.append([label, processes, steps, f"{rate:.0f}", f"{rate / baseline:.2f}", "-"])
        rows[-1].append(f"{load:.1f}")
    start_ray(None, max(os.cpu_count() or 1, *(r for r, _ in RLLIB_SETUPS)), ship_code=False)
    try:
        for runners, envs in RLLIB_SETUPS:
            rate, learner = rllib_rate(rllib, env_id, runners, envs, iterations)
            load = os.getloadavg()[0]
            label = f"RLlib, {runners} env runners x {envs} envs"
            label += " (the driver samples)" if not runners else ""
            print(f"{label}: {rate:.0f} env steps/s (load {load:.1f})")
            rows.append([label, 1 + runners, steps, f"{rate:.0f}", f"{rate / baseline:.2f}"])
            rows[-1] += [f"{learner:.2f}", f"{load:.1f}"]
    finally:
        ray.shutdown()
    header = [
        "trainer",
        "processes",
        "env steps",
        "env steps/s",
        "vs SB3 dummy",
        "learner update s (1st)",
        "load (1 min, after)",
    ]
    body = [
        f"`{env_id}` (configs/ppo.yml and configs/rllib_ppo.yml): {batch} env steps "
        f"per update ({sb3['n_envs']} x {sb3['n_steps']} in SB3; in RLlib the train batch "
        f"split over the env runners), {sb3['n_epochs']} epochs, minibatch "
        f"{sb3['batch_size']}, [64, 64] tanh networks, observation normalization; "
        f"{iterations} updates each, one torch thread per learner; a local Ray instance "
        f"(ray {ray.__version__}) on {os.cpu_count()} cores. Processes: that step envs or "
        "learn (the driver included). Learner update: the first iteration's "
        "`learner_update_timer` (RLlib only).",
        "",
        *table(header, rows),
    ]
    return write(out, "RLlib PPO training throughput", body)


def main(argv: list[str] | None = None) -> int:
    ap = parser(
        "benchmarks.rllib_throughput", __doc__, "rllib_throughput.md", "2 updates per measurement"
    )
    ap.add_argument("--iterations", type=positive_int, help="updates per measurement (default: 8)")
    ap.add_argument("--env", default="FrictionlessGrasp-v0", help="env id of both files")
    args = ap.parse_args(argv)
    missing = [m for m in ("ray", "stable_baselines3") if importlib.util.find_spec(m) is None]
    if missing:
        ap.error(f'needs {" and ".join(missing)}: pip install -e ".[rllib,train]"')
    run(args.quick, args.out, args.env, args.iterations)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
