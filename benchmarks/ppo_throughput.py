"""PPO training throughput on FrictionlessGrasp-v0 against CartPole-v1, in the same run.

Trains the same PPO settings (a ``configs/ppo.yml`` entry's: n_envs, n_steps, batch size,
epochs, network, VecNormalize; no evaluation, checkpoints or progress bar; one torch thread)
for a fixed number of env steps on our env and on CartPole-v1, with each vector-env class
(SubprocVecEnv, DummyVecEnv), and reports env steps/s of ``PPO.learn`` and the ratio.

Usage: ``python -m benchmarks.ppo_throughput [--quick] [--entry fig13_fingers]``
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from benchmarks.common import OUT, REPO, headless, table, write

VEC_ENVS = ("subproc", "dummy")


def steps_per_second(entry: dict, steps: int, vec_env: str, seed: int = 0) -> float:
    """Env steps/s of ``PPO.learn(steps)`` for a config entry (wall time of learn only,
    after a warm-up rollout)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.train_ppo import make_vec_env, normalize_kwargs, ppo_kwargs

    torch.set_num_threads(1)
    venv = make_vec_env(entry, int(entry.get("n_envs", 1)), seed, vec_env)
    norm = normalize_kwargs(entry)
    if norm is not None:
        venv = VecNormalize(venv, **norm)
    policy = entry.get("policy", "MlpPolicy")
    model = PPO(policy, venv, seed=seed, device="cpu", **ppo_kwargs(entry))
    # Warm-up, not timed: one rollout and update (the envs' first resets, loading compiled
    # code, torch's first passes), so that both envs are measured in their steady state.
    model.learn(model.n_steps * model.n_envs)
    before, start = model.num_timesteps, time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    rate = (model.num_timesteps - before) / (time.perf_counter() - start)
    venv.close()
    return rate


def run(
    quick: bool = False,
    out: Path = OUT / "ppo_throughput.md",
    entry_name: str = "fig13_fingers",
) -> Path:
    """Measure both envs with both vector-env classes and write the markdown page."""
    from agents.train_ppo import get_entry, load_config

    headless()
    entry = get_entry(load_config(REPO / "configs" / "ppo.yml"), entry_name)
    rollout = int(entry.get("n_envs", 1)) * int(entry["n_steps"])
    ours_steps = rollout * (1 if quick else 6)
    cartpole_steps = rollout * (4 if quick else 8)
    cartpole = {**entry, "env_id": "CartPole-v1", "env_kwargs": {}, "env_wrapper": None}
    rows = []
    for vec_env in VEC_ENVS:
        ours = steps_per_second(entry, ours_steps, vec_env)
        theirs = steps_per_second(cartpole, cartpole_steps, vec_env)
        load = os.getloadavg()[0]
        print(f"{vec_env}: {ours:.0f} vs CartPole {theirs:.0f} steps/s (load {load:.1f})")
        ratio = ours / theirs
        rows.append([vec_env, f"{ours:.0f}", f"{theirs:.0f}", f"{ratio:.3f}", f"{load:.1f}"])
    header = ["vec env", f"{entry_name} steps/s", "CartPole-v1 steps/s", "ratio", "load (1 min)"]
    body = [
        f"PPO settings of `{entry_name}` (configs/ppo.yml): {entry['n_envs']} envs, n_steps "
        f"{entry['n_steps']}, batch {entry['batch_size']}, {entry['n_epochs']} epochs, "
        f"{entry['policy_kwargs']}; {ours_steps} steps on our env, {cartpole_steps} on "
        "CartPole-v1; wall time of `PPO.learn` only, after one untimed warm-up rollout and "
        "update (first resets, loading compiled code, torch's first passes).",
        "",
        *table(header, rows),
    ]
    return write(out, "PPO training throughput", body)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one rollout per measurement")
    parser.add_argument("--entry", default="fig13_fingers", help="configs/ppo.yml entry")
    parser.add_argument("--out", type=Path, default=OUT / "ppo_throughput.md")
    args = parser.parse_args(argv)
    run(args.quick, args.out, args.entry)


if __name__ == "__main__":
    main()
