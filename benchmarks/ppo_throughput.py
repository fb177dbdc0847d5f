"""PPO training throughput on FrictionlessGrasp-v0 against CartPole-v1, in the same run.

Trains the same PPO settings (a ``configs/ppo.yml`` entry's: n_envs, n_steps, batch size,
epochs, network, VecNormalize; no evaluation, checkpoints or progress bar; one torch thread)
on our env and on CartPole-v1, with each vector-env class (SubprocVecEnv, DummyVecEnv). Both
models are built and warmed up first, then trained in alternating rounds of a fixed number of
env steps (the order rotated each round), so that a change in the machine's load touches both
sides alike; the page gives env steps/s of ``PPO.learn`` per side (median over rounds) and
the median and range of the per-round ratios.

Usage: ``python -m benchmarks.ppo_throughput [--quick] [--rounds N] [--entry fig13_fingers]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

from benchmarks.common import OUT, REPO, headless, table, write
from grasp_env.cli import positive_int

VEC_ENVS = ("dummy", "subproc")
ROUNDS = 5


def warmed_model(entry: dict, vec_env: str, seed: int = 0):
    """A PPO model of a config entry on its vector env, after one untimed rollout and update
    (the envs' first resets, loading compiled code, torch's first passes), so that it is
    measured in its steady state."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.train_ppo import make_vec_env, normalize_kwargs, ppo_kwargs

    venv = make_vec_env(entry, int(entry.get("n_envs", 1)), seed, vec_env)
    norm = normalize_kwargs(entry)
    if norm is not None:
        venv = VecNormalize(venv, **norm)
    model = PPO(
        entry.get("policy", "MlpPolicy"), venv, seed=seed, device="cpu", **ppo_kwargs(entry)
    )
    model.learn(model.n_steps * model.n_envs)
    return model


def steps_per_second(model, steps: int) -> float:
    """Env steps/s of ``model.learn(steps)`` (wall time of learn only)."""
    before, start = model.num_timesteps, time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    return (model.num_timesteps - before) / (time.perf_counter() - start)


def compare(entry: dict, cartpole: dict, vec_env: str, steps: tuple[int, int], rounds: int):
    """Per-round steps/s of our env's and CartPole's PPO, trained in alternating rounds."""
    models = (warmed_model(entry, vec_env), warmed_model(cartpole, vec_env))
    rates: tuple[list, list] = ([], [])
    for r in range(rounds):
        for side in (0, 1) if r % 2 == 0 else (1, 0):
            rates[side].append(steps_per_second(models[side], steps[side]))
    for model in models:
        model.get_env().close()
    return rates


def run(
    quick: bool = False,
    out: Path = OUT / "ppo_throughput.md",
    entry_name: str = "fig13_fingers",
    rounds: int | None = None,
) -> Path:
    """Measure both envs with both vector-env classes and write the markdown page."""
    import torch

    from agents.train_ppo import get_entry, load_config

    headless()
    torch.set_num_threads(1)
    entry = get_entry(load_config(REPO / "configs" / "ppo.yml"), entry_name)
    rounds = rounds or (1 if quick else ROUNDS)
    rollout = int(entry.get("n_envs", 1)) * int(entry["n_steps"])
    steps = (rollout * (1 if quick else 4), rollout * (2 if quick else 6))
    cartpole = {**entry, "env_id": "CartPole-v1", "env_kwargs": {}, "env_wrapper": None}
    rows = []
    for vec_env in VEC_ENVS:
        ours, theirs = compare(entry, cartpole, vec_env, steps, rounds)
        ratios = [a / b for a, b in zip(ours, theirs, strict=True)]
        load = os.getloadavg()[0]
        ratio = statistics.median(ratios)
        print(
            f"{vec_env}: ratio {ratio:.3f} ({min(ratios):.3f}-{max(ratios):.3f}), load {load:.1f}"
        )
        rows.append([
            vec_env, f"{statistics.median(ours):.0f}", f"{statistics.median(theirs):.0f}",
            f"{ratio:.3f}", f"{min(ratios):.3f}-{max(ratios):.3f}", f"{load:.1f}",
        ])  # fmt: skip
    header = [
        "vec env", f"{entry_name} steps/s", "CartPole-v1 steps/s", "ratio (median)",
        "ratio range", "load (1 min)",
    ]  # fmt: skip
    body = [
        f"PPO settings of `{entry_name}` (configs/ppo.yml): {entry['n_envs']} envs, n_steps "
        f"{entry['n_steps']}, batch {entry['batch_size']}, {entry['n_epochs']} epochs, "
        f"{entry['policy_kwargs']}; one torch thread. Each model is warmed up by one untimed "
        f"rollout and update, then both train in {rounds} alternating rounds of {steps[0]} "
        f"steps on our env and {steps[1]} on CartPole-v1 (order rotated each round); steps/s "
        "are medians over rounds of the wall time of `PPO.learn`, the ratio the median (and "
        "range) of the per-round ratios. `agents.train_ppo` and the zoo train with DummyVecEnv "
        "unless told otherwise (`--vec-env subproc`).",
        "",
        *table(header, rows),
    ]
    return write(out, "PPO training throughput", body)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one rollout per measurement")
    parser.add_argument(
        "--rounds", type=positive_int, help=f"alternating rounds (default {ROUNDS}, 1 with --quick)"
    )
    parser.add_argument("--entry", default="fig13_fingers", help="configs/ppo.yml entry")
    parser.add_argument("--out", type=Path, default=OUT / "ppo_throughput.md")
    args = parser.parse_args(argv)
    run(args.quick, args.out, args.entry, args.rounds)


if __name__ == "__main__":
    main()
