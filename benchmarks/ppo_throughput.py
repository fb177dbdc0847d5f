"""PPO training throughput on FrictionlessGrasp-v0 against CartPole-v1, in the same run.

Trains the same PPO settings (a config entry's: n_envs, n_steps, batch size, epochs,
network, VecNormalize; no evaluation, checkpoints or progress bar; one torch thread) on our
env and on CartPole-v1: a ``configs/ppo.yml`` entry with each of SB3's vector-env classes
(SubprocVecEnv, DummyVecEnv) on both sides, and the lifting task's large-batch entry
(``configs/ppo_batched.yml``) on the batched env (``agents.batched``) against CartPole-v1 in
a DummyVecEnv of as many envs. The models are built and warmed up first, then trained in
alternating rounds of a fixed number of env steps (the order rotated each round), so that a
change in the machine's load touches both sides alike; the page gives env steps/s of
``PPO.learn`` per side (median over rounds) and the median and range of the per-round
ratios.

Beside them, the same PPO on a null env (:func:`null_vec_env`: our env's spaces, no work)
measures what PPO itself costs on those spaces: the most any env with them could reach.

Usage: ``python -m benchmarks.ppo_throughput [--quick] [--rounds N] [--entry fig13_fingers]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

from benchmarks.common import REPO, headless, page_main, table, write
from grasp_env.cli import positive_int

VEC_ENVS = ("dummy", "subproc")
#: Shape pool of the batched lifting entry here, made before timing.
POOL = 256
ROUNDS = 5
#: Least ratio to the same PPO on CartPole-v1: the fig13 entry with DummyVecEnv (the
#: training default on 2 cores), and the batched lifting entry against CartPole-v1 in a
#: DummyVecEnv of as many envs.
TARGETS = {"single": 0.8, "batched": 1.0}


#: Episode length of the null env: about a lifting episode's with random actions.
NULL_EPISODE = 129


def null_vec_env(n_envs: int, observation_space, action_space, length: int = NULL_EPISODE):
    """An SB3 ``VecEnv`` with the given spaces that does no work (:class:`NullVecEnv`)."""
    from stable_baselines3.common.vec_env import VecEnv

    class NullVecEnv(VecEnv):
        """Zero observations and rewards, every episode ``length`` steps long (staggered
        across the envs), with SB3's ``terminal_observation`` and ``TimeLimit.truncated`` at
        its end: PPO on it pays for itself alone."""

        def __init__(self) -> None:
            super().__init__(n_envs, observation_space, action_space)
            self.render_mode = None
            self._t = np.arange(n_envs) % length
            self._obs = np.zeros((n_envs, *observation_space.shape), observation_space.dtype)

        def reset(self) -> np.ndarray:
            self._t[:] = np.arange(n_envs) % length
            return self._obs.copy()

        def step_async(self, actions: np.ndarray) -> None:
            pass

        def step_wait(self):
            self._t += 1
            dones = self._t >= length
            self._t[dones] = 0
            infos = [{} for _ in range(n_envs)]
            for i in np.flatnonzero(dones):
                infos[i]["terminal_observation"] = self._obs[i].copy()
                infos[i]["TimeLimit.truncated"] = True
            return self._obs.copy(), np.zeros(n_envs, np.float32), dones, infos

        def close(self) -> None:
            pass

        def get_attr(self, attr_name, indices=None) -> list:
            return [None] * len(self._get_indices(indices))

        def set_attr(self, attr_name, value, indices=None) -> None:
            pass

        def env_method(self, method_name, *args, indices=None, **kwargs) -> list:
            return [None] * len(self._get_indices(indices))

        def env_is_wrapped(self, wrapper_class, indices=None) -> list:
            return [False] * len(self._get_indices(indices))

    return NullVecEnv()


def warmed_model(entry: dict, vec_env: str, seed: int = 0):
    """A PPO model of a config entry on its vector env (``"null"``: :func:`null_vec_env`
    with the entry's env's spaces, behind a ``VecMonitor`` as the real envs are), after one
    untimed rollout and update (the envs' first resets, loading compiled code, torch's first
    passes), so that it is measured in its steady state."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from agents.train_ppo import make_vec_env, normalize_kwargs, ppo_kwargs
    from benchmarks.batched import prepare_pool

    n_envs = int(entry.get("n_envs", 1))
    if vec_env == "null":
        spaces = make_vec_env(entry, 1, seed, "dummy")
        venv = VecMonitor(null_vec_env(n_envs, spaces.observation_space, spaces.action_space))
        spaces.close()
    else:
        venv = make_vec_env(entry, n_envs, seed, vec_env)
    if vec_env == "batched":
        prepare_pool(venv.venv.venv)  # VecMonitor, then the SB3 adapter
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


def compare(
    entry: dict, cartpole: dict, vec_envs: tuple[str, str], steps: tuple[int, int], rounds: int
):
    """Per-round steps/s of PPO on our env, on CartPole and on a null env with our env's
    spaces (as many steps as ours), trained in alternating rounds (the order rotated)."""
    models = (
        warmed_model(entry, vec_envs[0]), warmed_model(cartpole, vec_envs[1]),
        warmed_model(entry, "null"),
    )  # fmt: skip
    budget = (steps[0], steps[1], steps[0])
    rates: tuple[list, list, list] = ([], [], [])
    for r in range(rounds):
        for k in range(3):
            side = (r + k) % 3
            rates[side].append(steps_per_second(models[side], budget[side]))
    for model in models:
        model.get_env().close()
    return rates


def run(quick: bool, out: Path, entry: str = "fig13_fingers", rounds: int | None = None) -> Path:
    """Measure both envs with both vector-env classes and write the markdown page."""
    import torch

    from agents.train_ppo import get_entry, load_config

    headless()
    torch.set_num_threads(1)
    rounds = rounds or (1 if quick else ROUNDS)
    cases = []  # (label, our entry, our vec env, CartPole's vec env, least ratio or None)
    named = get_entry(load_config(REPO / "configs" / "ppo.yml"), entry)
    for vec_env in VEC_ENVS:
        least = TARGETS["single"] if vec_env == "dummy" else None  # the training default
        cases.append((f"`{entry}`, {vec_env}", named, vec_env, vec_env, least))
    lift = get_entry(load_config(REPO / "configs" / "ppo_batched.yml"), "FrictionlessGraspLift-v0")
    # a smaller pool, made before timing: steady-state training, whatever the pool's size
    lift = {**lift, "env_kwargs": {**lift["env_kwargs"], "shape_pool": POOL}}
    cases.append(
        ("lifting, batched (`configs/ppo_batched.yml`)", lift, "batched", "dummy",
         TARGETS["batched"])
    )  # fmt: skip
    rows, targets = [], []
    for label, mine, ours_vec, theirs_vec, least in cases:
        rollout = int(mine.get("n_envs", 1)) * int(mine["n_steps"])
        steps = (rollout * (1 if quick else 4), rollout * (2 if quick else 6))
        # CartPole with our PPO settings: none of our env's kwargs, wrappers or info keys
        cartpole = {
            **mine, "env_id": "CartPole-v1", "env_kwargs": {}, "env_wrapper": None,
            "monitor_kwargs": {},
        }  # fmt: skip
        ours, theirs, alone = compare(mine, cartpole, (ours_vec, theirs_vec), steps, rounds)
        ratios = [a / b for a, b in zip(ours, theirs, strict=True)]
        ceilings = [a / b for a, b in zip(alone, theirs, strict=True)]
        # per env step, what our env (with its wrappers) adds to PPO's own time
        env_us = [1e6 * (1.0 / a - 1.0 / b) for a, b in zip(ours, alone, strict=True)]
        load = os.getloadavg()[0]
        ratio = statistics.median(ratios)
        print(f"{label}: ratio {ratio:.3f} ({min(ratios):.3f}-{max(ratios):.3f}), load {load:.1f}")
        if least is not None:
            verdict = "met" if ratio >= least else "not met"
            targets.append(
                f"* target: {label} >= {least:g}x the same PPO on CartPole-v1 ({theirs_vec}): "
                f"**{ratio:.3f}x** ({verdict})"
            )
        rows.append([
            label, f"{mine['n_envs']} x {mine['n_steps']}, batch {mine['batch_size']}, "
            f"{mine['n_epochs']} epochs", f"{statistics.median(ours):.0f}",
            f"{statistics.median(theirs):.0f} ({theirs_vec})", f"{ratio:.3f}",
            f"{min(ratios):.3f}-{max(ratios):.3f}", f"{statistics.median(alone):.0f}",
            f"{statistics.median(ceilings):.3f} ({min(ceilings):.3f}-{max(ceilings):.3f})",
            f"{statistics.median(env_us):.1f}", f"{load:.1f}",
        ])  # fmt: skip
    header = [
        "set-up", "PPO settings", "our env steps/s", "CartPole-v1 steps/s", "ratio (median)",
        "ratio range", "null env steps/s", "null env / CartPole (range)", "our env us/step",
        "load (1 min)",
    ]  # fmt: skip
    body = [
        "PPO settings of a config entry on both sides (envs x n_steps, batch, epochs, the "
        "entry's network and VecNormalize); one torch thread. Each model is warmed up by one "
        f"untimed rollout and update, then the three (with the null env below) train in "
        f"{rounds} alternating rounds of 4 rollouts on our env and on the null env and 6 on "
        "CartPole-v1 (1 and 2 with `--quick`; order rotated each round); steps/s are "
        "medians over rounds of the wall time of `PPO.learn`, the ratio the median (and "
        "range) of the per-round ratios. `agents.train_ppo` trains "
        "on the batched env where an entry has several envs and no wrapper but "
        "`TrainingInfo`, else with DummyVecEnv (`--vec-env`).",
        "",
        "**Null env**: the same PPO, trained in the same rounds, on an env with our env's "
        "observation and action spaces that does no work (zero observations and rewards, "
        f"episodes of {NULL_EPISODE} steps, behind a `VecMonitor`): what PPO itself costs "
        "with those spaces, so `null env / CartPole` is the most any env with them could "
        "reach against CartPole-v1. `our env us/step`: per env step, the time our env (with "
        "its wrappers and the SB3 adapter) adds to PPO's own, the median over rounds of "
        "1/(our steps/s) - 1/(null env steps/s); for a ratio of 1 it would have to be at most "
        "1/(CartPole steps/s) - 1/(null env steps/s).",
        "",
        *table(header, rows),
        "",
        *targets,
    ]
    return write(out, "PPO training throughput", body)


def entry_name(text: str) -> str:
    """An ``argparse`` type: an env id of ``configs/ppo.yml`` or a model shipped for one
    (``agents.train_ppo.get_entry``), checked before any model is built."""
    from agents.train_ppo import get_entry, load_config

    try:
        get_entry(load_config(REPO / "configs" / "ppo.yml"), text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{exc}, or a model shipped for one") from None
    return text


#: ``run``'s options on the command line: name, type, help, default.
OPTIONS = (
    ("rounds", positive_int, f"alternating rounds (default {ROUNDS}, 1 with --quick)"),
    ("entry", entry_name, "configs/ppo.yml entry, or a model shipped for one", "fig13_fingers"),
)


def main(argv: list[str] | None = None) -> int:
    return page_main(argv, run, "ppo_throughput.md", "one rollout per measurement", OPTIONS)


if __name__ == "__main__":
    raise SystemExit(main())
