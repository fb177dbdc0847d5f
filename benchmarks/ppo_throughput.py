"""PPO training throughput on FrictionlessGrasp-v0 against CartPole-v1, in the same run.

    python benchmarks/ppo_throughput.py [--entry fig13_fingers] [--steps 2048] \
        [--vec-env subproc dummy]

Trains the same PPO settings (the config entry's, ``configs/ppo.yml``; no evaluation, no
checkpoints, no progress bar) for ``--steps`` env steps on our env and on CartPole-v1 with
each vector env class, one torch thread, and prints env steps/s and their ratio.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

from agents.train_ppo import get_entry, load_config, make_vec_env, normalize_kwargs, ppo_kwargs


def steps_per_second(entry: dict, steps: int, vec_env: str, seed: int = 0) -> float:
    """Env steps/s of ``PPO.learn(steps)`` for a config entry (wall time of learn only)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    venv = make_vec_env(entry, int(entry.get("n_envs", 1)), seed, vec_env)
    norm = normalize_kwargs(entry)
    if norm is not None:
        venv = VecNormalize(venv, **norm)
    policy = entry.get("policy", "MlpPolicy")
    model = PPO(policy, venv, seed=seed, device="cpu", **ppo_kwargs(entry))
    start = time.perf_counter()
    model.learn(steps)
    rate = model.num_timesteps / (time.perf_counter() - start)
    venv.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--config", default="configs/ppo.yml")
    parser.add_argument("--entry", default="fig13_fingers")
    parser.add_argument("--steps", type=int, default=2048)
    parser.add_argument("--vec-env", nargs="+", default=["subproc", "dummy"])
    args = parser.parse_args()
    entry = get_entry(load_config(args.config), args.entry)
    cartpole = {**entry, "env_id": "CartPole-v1", "env_kwargs": {}}
    print(f"| vec env | {args.entry} steps/s | CartPole-v1 steps/s | ratio | load average |")
    print("| --- | --- | --- | --- | --- |")
    for vec_env in args.vec_env:
        ours = steps_per_second(entry, args.steps, vec_env)
        theirs = steps_per_second(cartpole, max(args.steps, 8192), vec_env)
        load = os.getloadavg()[0]
        print(f"| {vec_env} | {ours:.0f} | {theirs:.0f} | {ours / theirs:.3f} | {load:.1f} |")


if __name__ == "__main__":
    main()
