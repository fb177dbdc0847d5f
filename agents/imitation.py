"""Imitation of the scripted planner: a network-only policy cloned from its actions.

    python -m agents.imitation [--episodes N] [--lift-episodes N] [--dagger-iters K]
        [--out DIR] [--workers 2]

1. **Expert data.** :class:`agents.scripted.ScriptedPolicy` plays random shapes of the
   training distribution, the env set-up it is evaluated in (``agents.evaluate``'s
   ``SCRIPTED_KWARGS``: the scene's start, palm control; ``--episodes``) and from the
   planner's placement (the lifting task, ``--lift-episodes``), with the observation's hand
   features, on seeds ``--seed + k``, refused where they meet the held-out and validation
   seeds (1,000,000 to 2,999,999). Every step records ``(observation, expert action)``; the
   expert's actions are float32 in the env's ``Box(-1, 1)`` (checked). Once the expert's plan
   is played, ``--hold-steps`` steps of holding still are kept and the episode ends, so that
   the long holds do not outweigh the motion. Episodes the planner does not grasp are left
   out unless ``--keep-failures``.
2. **Behaviour cloning** into a stable-baselines3 PPO policy (``MlpPolicy``): the actor's
   mean is fitted to the expert's actions by mean squared error (Adam, ``--epochs``), on
   observations normalized as ``VecNormalize`` does, with the data's mean and variance
   (saved as ``vecnormalize.pkl``).
3. **DAgger** (``--dagger-iters`` rounds): the current network plays ``--dagger-episodes``
   new training episodes (both starts, in the proportion of step 1); at every
   ``--query-every``-th step the expert is asked for its action at the visited state: a
   fresh ``ScriptedPolicy`` planned from that state (:func:`expert_action`; its exploratory
   search, seconds of simulation, is left out, and a state from which it has no plan gets
   no label). The labels join the data and the network is trained again from the previous
   weights.

Writes into ``--out`` a model directory that ``agents.evaluate --models`` and
``agents.train_ppo -i`` read (``model.zip``, ``vecnormalize.pkl``, ``config.yml``: the entry
of ``FrictionlessGraspRandomShapes-v0`` with ``hand_features``, ``train_stats.json``), the
data (``expert.npz``), ``round_<k>/`` (the model after each round), ``progress.csv`` (one
row per round: samples, losses, the network's success in the DAgger episodes) and
``training.md``, the training page (``--page`` elsewhere; ``--report RUN`` writes it again
for a finished run). ``--dagger-weight`` weighs each DAgger label in the loss. At test
time the model is its network alone on the env's observation: no planner, no simulator
calls. The recipe and results: ``docs/imitation.md``.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import functools
import json
import math
import os
import platform
import shlex
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np
import yaml

import grasp_env  # noqa: F401  (registers the env ids)
from agents.scripted import ScriptedPolicy
from grasp_env.cli import HelpFormatter, nonnegative_int, out_dir_problem, positive_int
from grasp_env.envs import LIFT_ENV_ID, RANDOM_SHAPES_ENV_ID
from grasp_env.errors import ComputationError

#: The env id the model's config names: random shapes from the scene's start with palm
#: control, as the planner is evaluated; the model adds the observation's hand features.
ENV_ID = RANDOM_SHAPES_ENV_ID
#: Env kwargs of the two starts of the training distribution, each with the hand features
#: (they change the observation only): the scene's start (``agents.evaluate.SCRIPTED_KWARGS``
#: with random shapes) and the planner's placement (the lifting task).
STARTS = {
    "scene": (ENV_ID, {"hand_features": True}),
    "placement": (LIFT_ENV_ID, {}),
}
#: Seeds that training data must not use: the held-out suites' (``agents.evaluate``,
#: 1,000,000 on) and the learning curves' validation episodes (2,000,000 on).
RESERVED_SEEDS = range(1_000_000, 3_000_000)
#: Floor of the saved observation variance: entries that hardly vary in the data (padding,
#: flags) are not blown up where they do vary.
MIN_VAR = 1e-4
#: The model's training entry (zoo format; the lifting entry's reward and PPO settings, for
#: a PPO fine-tune with ``agents.train_ppo -i``).
ENTRY: dict[str, Any] = {
    "env_kwargs": {
        "hand_features": True,
        "reward_form_closure_weight": 1.0,
        "reward_hold_weight": 1.0,
        "reward_grip_weight": 0.5,
        "reward_lift_weight": 10.0,
    },
    "env_wrapper": ["agents.wrappers.TrainingInfo"],
    "n_envs": 2,
    "n_timesteps": 0,
    "policy": "MlpPolicy",
    "normalize": "dict(norm_obs=True, norm_reward=True)",
    "n_steps": 1024,
    "batch_size": 256,
    "n_epochs": 10,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "learning_rate": 1e-4,
    "ent_coef": 0.0,
    "clip_range": 0.2,
    "monitor_kwargs": "dict(info_keywords=('is_success',))",
    "callback": ["agents.callbacks.RewardTermsCallback"],
}


def make_env(start: str, **kwargs) -> gym.Env:
    """A training env of one start (``"scene"`` or ``"placement"``)."""
    env_id, extra = STARTS[start]
    return gym.make(env_id, **{**extra, **kwargs})


# ---------------------------------------------------------------------- the expert
class _StateView:
    """The env's accessors with another state in place of the env's: what
    :class:`ScriptedPolicy` reads to plan from a state (nothing in the env changes)."""

    def __init__(self, base, state) -> None:
        self._base = base
        self.state = state

    @property
    def unwrapped(self):
        return self

    def __getattr__(self, name: str):
        return getattr(self._base, name)


class _QueryExpert(ScriptedPolicy):
    """The planner asked for one action: its exploratory search (seconds of simulation) is
    left out."""

    def _explore(self, state) -> None:
        self._explored = True


def expert_action(env: gym.Env, state=None) -> np.ndarray | None:
    """The planner's action at ``state`` (default: the env's): a fresh ``ScriptedPolicy``
    planned from it, as at an episode's start, without its exploratory search; None where it
    has no plan that lifts (or fails). The env is not changed."""
    base = env.unwrapped
    policy = _QueryExpert(_StateView(base, base.state if state is None else state))
    try:
        policy.reset()
        if not (policy.plan.success or policy.on_fallback):
            return None
        return policy.act()
    except ComputationError:
        return None


def check_actions(actions: np.ndarray, space: gym.spaces.Box) -> None:
    """Raise ValueError unless every row is in the env's action space."""
    actions = np.asarray(actions)
    bad = ~np.all((actions >= space.low) & (actions <= space.high), axis=-1)
    if actions.dtype != space.dtype or bad.any():
        raise ValueError(f"expert actions outside {space}: {actions[bad][:3]}")


def expert_episode(job: tuple[str, int, int]) -> dict[str, Any]:
    """One episode of the planner: ``(start, seed, hold_steps)`` ->
    ``{"obs", "act", "success", "steps", "seed", "start", "seconds"}``."""
    start, seed, hold_steps = job
    t0 = time.process_time()
    env = make_env(start)
    obs, info = env.reset(seed=seed)
    policy = ScriptedPolicy(env)
    observations, actions = [], []
    held, success, error = 0, False, ""
    try:
        policy.reset(obs, info)
        while True:
            action = policy.act(obs)
            observations.append(obs)
            actions.append(action)
            obs, _, terminated, truncated, info = env.step(action)
            success = bool(info["is_success"])
            held = held + 1 if policy.done else 0
            if terminated or truncated or held > hold_steps:
                break
    except ComputationError as exc:
        error = f"{type(exc).__name__}: {exc}"
    space, width = env.action_space, env.observation_space.shape[0]
    env.close()
    acts = np.array(actions, np.float32).reshape(-1, space.shape[0])
    check_actions(acts, space)
    return {
        "obs": np.array(observations, np.float32).reshape(len(actions), width),
        "act": acts,
        "success": success,
        "steps": len(actions),
        "seed": seed,
        "start": start,
        "error": error,
        "seconds": time.process_time() - t0,
    }


# ---------------------------------------------------------------------- DAgger
@functools.cache
def _network(model_dir: str):
    from agents.models import load_agent

    model, norm, _, _ = load_agent(model_dir)
    return model, norm


def network_action(model, norm, obs: np.ndarray) -> np.ndarray:
    """The model's deterministic action on one observation (as ``agents.evaluate`` plays)."""
    x = norm.normalize_obs(obs) if norm is not None else obs
    return model.predict(x, deterministic=True)[0]


def dagger_episode(job: tuple[str, str, int, int, int]) -> dict[str, Any]:
    """The network of ``model_dir`` plays one episode; the expert labels every
    ``every``-th visited state: ``(model_dir, start, seed, every, _)`` -> the labelled
    ``obs`` and ``act``, the network's ``success``, ``queries`` and ``unlabelled``."""
    model_dir, start, seed, every, _ = job
    t0 = time.process_time()
    model, norm = _network(model_dir)
    env = make_env(start)
    obs, info = env.reset(seed=seed)
    observations, actions = [], []
    queries = unlabelled = steps = 0
    while True:
        if steps % every == 0:
            queries += 1
            label = expert_action(env)
            if label is None:
                unlabelled += 1
            else:
                observations.append(obs)
                actions.append(label)
        obs, _, terminated, truncated, info = env.step(network_action(model, norm, obs))
        steps += 1
        if terminated or truncated:
            break
    space, width = env.action_space, env.observation_space.shape[0]
    env.close()
    acts = np.array(actions, np.float32).reshape(-1, space.shape[0])
    check_actions(acts, space)
    return {
        "obs": np.array(observations, np.float32).reshape(len(actions), width),
        "act": acts,
        "success": bool(info["is_success"]),
        "steps": steps,
        "seed": seed,
        "start": start,
        "queries": queries,
        "unlabelled": unlabelled,
        "seconds": time.process_time() - t0,
    }


# ---------------------------------------------------------------------- the network
def new_model(net_arch: list[int], log_std_init: float = -1.0, seed: int = 0):
    """A fresh PPO model on the training env (``MlpPolicy``, separate actor and critic
    networks of ``net_arch``) and its ``VecNormalize`` (statistics set by
    :func:`set_normalization`)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: make_env("scene")]), gamma=ENTRY["gamma"])
    kwargs = {k: ENTRY[k] for k in ("n_steps", "batch_size", "n_epochs", "gamma", "gae_lambda")}
    kwargs.update(learning_rate=ENTRY["learning_rate"], ent_coef=0.0, clip_range=0.2)
    policy_kwargs = {
        "net_arch": {"pi": list(net_arch), "vf": list(net_arch)},
        "log_std_init": log_std_init,
    }
    model = PPO("MlpPolicy", venv, policy_kwargs=policy_kwargs, seed=seed, device="cpu", **kwargs)
    return model, venv


def set_normalization(norm, obs: np.ndarray) -> None:
    """``norm``'s observation statistics from the data (variance floored at ``MIN_VAR``);
    frozen."""
    norm.obs_rms.mean = obs.mean(axis=0).astype(np.float64)
    norm.obs_rms.var = np.maximum(obs.var(axis=0), MIN_VAR).astype(np.float64)
    norm.obs_rms.count = float(len(obs))
    norm.training = False


def actor_mean(policy, x):
    """The actor's mean action (before clipping) for normalized observations ``x``."""
    features = policy.extract_features(x, policy.pi_features_extractor)
    return policy.action_net(policy.mlp_extractor.forward_actor(features))


def behaviour_clone(
    model,
    norm,
    obs: np.ndarray,
    act: np.ndarray,
    epochs: int,
    batch_size: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
    val_fraction: float = 0.1,
    log=None,
    weights: np.ndarray | None = None,
) -> list[dict[str, float]]:
    """Fit the actor's mean to ``act`` by mean squared error (Adam, a cosine-decayed
    learning rate); returns per epoch ``{"epoch", "train_loss", "val_loss"}`` (the loss
    over a held-out ``val_fraction`` of the samples, nan without one); ``weights``: each
    sample's weight in the training loss (default: all 1)."""
    import torch

    policy = model.policy
    x_all = torch.as_tensor(norm.normalize_obs(obs), dtype=torch.float32)
    y_all = torch.as_tensor(act, dtype=torch.float32)
    w_all = torch.as_tensor(np.ones(len(act)) if weights is None else weights, dtype=torch.float32)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(obs))
    n_val = int(len(obs) * val_fraction) if len(obs) >= 20 else 0
    val, train = order[:n_val], order[n_val:]
    params = [
        *policy.features_extractor.parameters(),
        *policy.mlp_extractor.policy_net.parameters(),
        *policy.action_net.parameters(),
    ]
    params = list(dict.fromkeys(params))
    optimizer = torch.optim.Adam(params, lr=lr)
    steps = epochs * max(1, math.ceil(len(train) / batch_size))
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, steps)
    torch.manual_seed(seed)
    history = []
    policy.train()
    for epoch in range(1, epochs + 1):
        perm = rng.permutation(train)
        total = 0.0
        for i in range(0, len(perm), batch_size):
            idx = torch.as_tensor(perm[i : i + batch_size])
            err = ((actor_mean(policy, x_all[idx]) - y_all[idx]) ** 2).mean(dim=1)
            loss = (w_all[idx] * err).sum() / w_all[idx].sum()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
            total += loss.item() * len(idx)
        with torch.no_grad():
            val_loss = (
                float(((actor_mean(policy, x_all[val]) - y_all[val]) ** 2).mean())
                if n_val
                else math.nan
            )
        row = {"epoch": epoch, "train_loss": total / max(1, len(train)), "val_loss": val_loss}
        history.append(row)
        if log is not None:
            log(f"  epoch {epoch}/{epochs}: train loss {row['train_loss']:.4f}, val {val_loss:.4f}")
    policy.eval()
    return history


def mse(model, norm, obs: np.ndarray, act: np.ndarray) -> float:
    """Mean squared error of the actor's mean on ``(obs, act)``."""
    import torch

    with torch.no_grad():
        x = torch.as_tensor(norm.normalize_obs(obs), dtype=torch.float32)
        return float(((actor_mean(model.policy, x) - torch.as_tensor(act)) ** 2).mean())


def save_model(model, norm, out: Path, stats: dict[str, Any], net_arch: list[int]) -> None:
    """Write the model directory: ``model.zip``, ``vecnormalize.pkl``, ``config.yml`` (the
    entry of :data:`ENV_ID`) and ``train_stats.json``."""
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    norm.save(str(out / "vecnormalize.pkl"))
    entry = dict(ENTRY)
    entry["policy_kwargs"] = (
        f"dict(net_arch=dict(pi={list(net_arch)}, vf={list(net_arch)}), "
        f"log_std_init={model.policy.log_std.mean().item():.3g})"
    )
    (out / "config.yml").write_text(yaml.safe_dump({ENV_ID: entry}, sort_keys=False))
    (out / "train_stats.json").write_text(json.dumps(stats, indent=1) + "\n")


# ---------------------------------------------------------------------- running jobs
def run_jobs(fn, jobs: list, workers: int, deadline: float | None, label: str) -> list[dict]:
    """Run ``fn`` on every job (``workers`` processes), printing a progress line per
    episode; stops taking new jobs at ``deadline`` (``time.monotonic``)."""
    results: list[dict] = []
    t0 = time.monotonic()

    def report(r: dict) -> None:
        results.append(r)
        done = len(results)
        ok = sum(x["success"] for x in results)
        samples = sum(len(x["act"]) for x in results)
        rate = (time.monotonic() - t0) / done
        print(
            f"[{label} {done}/{len(jobs)}] {r['start']} seed {r['seed']}: "
            f"{'grasp' if r['success'] else 'no grasp'}, {len(r['act'])} samples "
            f"({samples} in all, success {ok}/{done}, {rate:.1f} s/episode)",
            file=sys.stderr,
            flush=True,
        )

    if workers <= 1:
        for job in jobs:
            if deadline is not None and time.monotonic() > deadline:
                break
            report(fn(job))
        return results
    with ProcessPoolExecutor(workers, initializer=_one_thread) as pool:
        pending = [pool.submit(fn, job) for job in jobs]
        for future in pending:
            if deadline is not None and time.monotonic() > deadline:
                for f in pending:
                    f.cancel()  # the running ones finish
            if future.cancelled():
                continue
            report(future.result())
    if len(results) < len(jobs):
        print(f"[{label}] time is up: {len(results)} of {len(jobs)} episodes", file=sys.stderr)
    return results


#: The folders whose uncommitted changes a page notes.
CODE_DIRS = ("grasp_env", "agents", "configs")


def git_commit() -> str:
    """The checked-out commit (short hash), noting uncommitted changes to ``grasp_env/``,
    ``agents/`` and ``configs/``; ``unknown`` outside git."""
    repo = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=repo, capture_output=True, text=True
        )
        changed = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", *CODE_DIRS],
            cwd=repo,
            capture_output=True,
            text=True,
        )
    except OSError:
        return "unknown"
    if head.returncode != 0:
        return "unknown"
    dirty = changed.returncode == 0 and changed.stdout.strip()
    return head.stdout.strip() + (" with uncommitted changes" if dirty else "")


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


def interleave(first: list, second: list) -> list:
    """Both lists merged, each one's items spread evenly (so that a run stopped early has
    both in proportion)."""
    n = len(first) + len(second)
    keys = [(k + 0.5) / len(first) for k in range(len(first))]
    keys += [(k + 0.5) / len(second) for k in range(len(second))]
    order = sorted(range(n), key=lambda i: (keys[i], i))
    items = first + second
    return [items[i] for i in order]


def _weights(data: dict[str, np.ndarray], dagger_weight: float) -> np.ndarray:
    """Each sample's loss weight: 1 for the expert's episodes (round 0), ``dagger_weight``
    for the DAgger labels."""
    return np.where(data["round"] > 0, dagger_weight, 1.0)


def _stack(episodes: list[dict], key: str, width: int) -> np.ndarray:
    parts = [e[key] for e in episodes if len(e[key])]
    return np.concatenate(parts) if parts else np.zeros((0, width), np.float32)


def seed_problem(seed: int, count: int) -> str | None:
    """Why seeds ``seed .. seed + count - 1`` cannot be training seeds, or None."""
    first, last = seed, seed + count - 1
    if seed < 0:
        return f"--seed must be >= 0, got {seed}"
    if first <= RESERVED_SEEDS[-1] and last >= RESERVED_SEEDS[0]:
        return (
            f"--seed {seed}: the training seeds {first}..{last} meet the held-out and "
            f"validation seeds {RESERVED_SEEDS[0]}..{RESERVED_SEEDS[-1]}"
        )
    return None


def _net_arch(text: str) -> list[int]:
    try:
        sizes = [int(s) for s in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected sizes like 256,256, got {text!r}") from None
    if not sizes or min(sizes) < 1:
        raise argparse.ArgumentTypeError(f"expected positive sizes, got {text!r}")
    return sizes


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


# ---------------------------------------------------------------------- the training page
def training_page(run: Path, command: str, date: str, commit: str) -> str:
    """The training page of a run folder (its ``train_stats.json`` and ``progress.csv``):
    the expert data, and per round the samples, the losses and the network's success in the
    DAgger episodes (training seeds, the network alone playing)."""
    stats = json.loads((run / "train_stats.json").read_text())
    with open(run / "progress.csv", newline="") as f:
        rounds = list(csv.DictReader(f))
    run_args = stats.get("args", {})
    played, grasped = stats["expert_episodes"], stats["expert_success"]
    seeds, source = "-", "collected by this run"
    if (run / "expert.npz").is_file():  # the data's own record, also where it came by --data
        with np.load(run / "expert.npz") as d:
            if "seeds" in d.files and len(d["seeds"]):
                played, grasped = len(d["seeds"]), int(d["seed_success"].sum())
                seeds = f"{d['seeds'].min()}..{d['seeds'].max()}"
    if run_args.get("data"):
        source = f"from `{run_args['data']}`"
        unused = ("episodes", "lift_episodes", "hold_steps", "keep_failures", "collect_minutes")
        run_args = {k: v for k, v in run_args.items() if k not in unused}
    lines = [
        f"# Imitation of the scripted planner: training of `{run.as_posix()}`",
        "",
        "<!-- Generated by python -m agents.imitation --report: run the command below again "
        "rather than editing this page. -->",
        "",
        f"Generated on {date} at commit `{commit}` by:",
        "",
        "```bash",
        command,
        "```",
        "",
        f"The run: `{stats.get('command', 'python -m agents.imitation')}` with "
        + ", ".join(f"`{k}={v}`" for k, v in run_args.items() if v is not None)
        + (f"; run at commit `{stats['commit']}`, {stats['date']}" if "commit" in stats else "")
        + f"; {stats.get('wall_minutes', math.nan):.0f} minutes of wall time.",
        "",
        f"Expert episodes: {grasped} of {played} grasped by the planner (training seeds "
        f"{seeds}, both starts; {source}); samples after the last round: {stats['samples']}.",
        "",
        "Round 0 is behaviour cloning on the expert's episodes; round k >= 1 adds the expert's "
        "labels of the states the round k-1 network visited. Network success in row k: the "
        "round k-1 network alone, deterministic, in round k's DAgger episodes (training "
        "seeds, both starts); the last round's network is measured by agents.evaluate.",
        "",
        "| round | samples | train loss | validation loss | DAgger episodes "
        "| network success | expert queries | unlabelled | minutes |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]

    def num(text: str, fmt: str) -> str:
        return format(float(text), fmt) if text not in ("", None) else "-"

    for r in rounds:
        lines.append(
            f"| {r['round']} | {r['samples']} | {num(r['train_loss'], '.4f')} "
            f"| {num(r['val_loss'], '.4f')} | {r['episodes'] or '-'} "
            f"| {num(r['network_success'], '.2f')} | {r['queries'] or '-'} "
            f"| {r['unlabelled'] or '-'} | {num(r['minutes'], '.0f')} |"
        )
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------- main
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m agents.imitation",
        description="Clone the scripted planner into a network-only PPO policy: expert data "
        "on training shapes, behaviour cloning, DAgger rounds. Writes a model directory "
        "(model.zip, vecnormalize.pkl, config.yml, train_stats.json), expert.npz and "
        "progress.csv into --out; see docs/imitation.md.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--out", type=Path, default=Path("runs/imitation"), help="output directory")
    p.add_argument(
        "--episodes",
        type=nonnegative_int,
        default=300,
        help="expert episodes from the scene's start",
    )
    p.add_argument(
        "--lift-episodes",
        type=nonnegative_int,
        default=150,
        help="expert episodes from the planner's placement",
    )
    p.add_argument("--seed", type=int, default=0, help="first training seed (default: 0)")
    p.add_argument(
        "--hold-steps",
        type=nonnegative_int,
        default=10,
        help="steps kept after the expert's plan is played",
    )
    p.add_argument(
        "--keep-failures", action="store_true", help="also keep the episodes the planner fails"
    )
    p.add_argument(
        "--data", type=Path, help="expert data (expert.npz of an earlier run) instead of step 1"
    )
    p.add_argument("--dagger-iters", type=nonnegative_int, default=2, help="DAgger rounds")
    p.add_argument(
        "--dagger-episodes", type=positive_int, default=60, help="network episodes per round"
    )
    p.add_argument(
        "--query-every",
        type=positive_int,
        default=4,
        help="the expert labels every this many visited states",
    )
    p.add_argument("--epochs", type=positive_int, default=30, help="BC epochs (first fit)")
    p.add_argument(
        "--dagger-weight",
        type=_positive_float,
        default=1.0,
        help="weight of a DAgger label in the loss, against 1 for an expert episode's sample",
    )
    p.add_argument(
        "--dagger-epochs", type=positive_int, default=15, help="BC epochs after each round"
    )
    p.add_argument("--batch-size", type=positive_int, default=256, help="BC batch size")
    p.add_argument("--lr", type=_positive_float, default=1e-3, help="BC learning rate (Adam)")
    p.add_argument(
        "--net-arch", type=_net_arch, default="256,256", help="hidden sizes, e.g. 256,256"
    )
    p.add_argument("--workers", type=positive_int, default=2, help="processes for episodes")
    p.add_argument(
        "--collect-minutes",
        type=_positive_float,
        help="stop starting expert episodes after this wall time (default: none)",
    )
    p.add_argument(
        "--max-minutes",
        type=_positive_float,
        help="start no DAgger episode or round after this wall time (default: none)",
    )
    p.add_argument("--threads", type=positive_int, default=1, help="torch threads for BC")
    p.add_argument(
        "--report",
        type=Path,
        metavar="RUN",
        help="only write the training page of a finished run folder (to --page) and exit",
    )
    p.add_argument(
        "--page",
        type=Path,
        help="the training page's path (default: RUN/training.md; runs write OUT/training.md)",
    )
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    command = shlex.join(["python", "-m", "agents.imitation", *argv])
    if args.report is not None:
        for name in ("train_stats.json", "progress.csv"):
            if not (args.report / name).is_file():
                parser.error(f"--report {str(args.report)!r} has no {name} (not a finished run)")
        page = args.page or args.report / "training.md"
        if page.is_dir() or not page.parent.is_dir():
            parser.error(f"--page {str(page)!r}: not a file in an existing folder")
        page.write_text(training_page(args.report, command, _now(), git_commit()))
        print(f"wrote {page}")
        return 0
    n_collect = 0 if args.data else args.episodes + args.lift_episodes
    n_dagger = args.dagger_iters * args.dagger_episodes
    if problem := seed_problem(args.seed, n_collect + n_dagger):
        parser.error(problem)
    if args.data is not None and not args.data.is_file():
        parser.error(f"--data {str(args.data)!r} is not a file")
    if (args.out / "model.zip").exists():
        parser.error(f"--out {args.out} already holds a model.zip")
    if problem := out_dir_problem(args.out):
        parser.error(f"--out {problem}")
    if args.data is None and n_collect == 0:
        parser.error("--episodes 0 and --lift-episodes 0: no expert data (or give --data)")

    import torch

    torch.set_num_threads(args.threads)
    t_start = time.monotonic()
    deadline = t_start + 60 * args.max_minutes if args.max_minutes else None
    collect_deadline = t_start + 60 * args.collect_minutes if args.collect_minutes else None
    if deadline is not None:
        collect_deadline = min(deadline, collect_deadline or deadline)

    def log(msg: str) -> None:
        print(f"[{time.monotonic() - t_start:7.0f} s] {msg}", file=sys.stderr, flush=True)

    # 1. expert data
    width_obs = make_env("scene").observation_space.shape[0]
    if args.data is not None:
        with np.load(args.data) as d:
            data = {k: d[k] for k in d.files}
        log(f"expert data from {args.data}: {len(data['act'])} samples")
        collected: list[dict] = []
    else:
        jobs = interleave(
            [("scene", args.seed + k, args.hold_steps) for k in range(args.episodes)],
            [
                ("placement", args.seed + args.episodes + k, args.hold_steps)
                for k in range(args.lift_episodes)
            ],
        )
        log(f"collecting {len(jobs)} expert episodes ({args.workers} workers)")
        collected = run_jobs(expert_episode, jobs, args.workers, collect_deadline, "expert")
        kept = [e for e in collected if e["success"] or args.keep_failures]
        data = {
            "obs": _stack(kept, "obs", width_obs),
            "act": _stack(kept, "act", 5),
            "round": np.zeros(sum(len(e["act"]) for e in kept), np.int16),
            "seeds": np.array([e["seed"] for e in collected]),
            "seed_success": np.array([e["success"] for e in collected]),
        }
        np.savez_compressed(args.out / "expert.npz", **data)
        log(
            f"expert: {sum(e['success'] for e in collected)}/{len(collected)} grasped, "
            f"{len(kept)} episodes kept, {len(data['act'])} samples -> {args.out}/expert.npz"
        )
    space = make_env("scene").action_space
    check_actions(data["act"], space)

    # 2. behaviour cloning
    model, venv = new_model(args.net_arch, seed=args.seed)
    norm = venv
    set_normalization(norm, data["obs"])
    log(f"behaviour cloning on {len(data['act'])} samples, {args.epochs} epochs")
    history = behaviour_clone(
        model, norm, data["obs"], data["act"], args.epochs, args.batch_size, args.lr,
        args.seed, log=log, weights=_weights(data, args.dagger_weight),
    )  # fmt: skip
    progress = [
        {
            "round": 0,
            "samples": len(data["act"]),
            "train_loss": history[-1]["train_loss"],
            "val_loss": history[-1]["val_loss"],
            "episodes": "",
            "network_success": "",
            "queries": "",
            "unlabelled": "",
            "minutes": (time.monotonic() - t_start) / 60,
        }
    ]
    stats = {
        "command": command,
        "date": _now(),
        "commit": git_commit(),
        "method": "behaviour cloning of agents.scripted.ScriptedPolicy, then DAgger",
        "env_id": ENV_ID,
        "starts": list(STARTS),
        "expert_episodes": len(collected),
        "expert_success": sum(e["success"] for e in collected),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "python": platform.python_version(),
        "torch": torch.__version__,
    }
    ckpt = args.out / "round_0"
    save_model(model, norm, ckpt, {**stats, "rounds": progress}, args.net_arch)

    # 3. DAgger
    seed = args.seed + n_collect
    n_scene = args.episodes if args.data is None else 1
    share = n_scene / max(1, n_scene + (args.lift_episodes if args.data is None else 1))
    for it in range(1, args.dagger_iters + 1):
        if deadline is not None and time.monotonic() > deadline:
            log("time is up: no more DAgger rounds")
            break
        k_scene = round(args.dagger_episodes * share)
        jobs = interleave(
            [(str(ckpt), "scene", seed + k, args.query_every, it) for k in range(k_scene)],
            [
                (str(ckpt), "placement", seed + k, args.query_every, it)
                for k in range(k_scene, args.dagger_episodes)
            ],
        )
        seed += args.dagger_episodes
        log(f"DAgger round {it}: {len(jobs)} network episodes, expert every {args.query_every}")
        episodes = run_jobs(dagger_episode, jobs, args.workers, deadline, f"dagger {it}")
        new_obs = _stack(episodes, "obs", width_obs)
        new_act = _stack(episodes, "act", 5)
        before = mse(model, norm, new_obs, new_act) if len(new_act) else math.nan
        data["obs"] = np.concatenate([data["obs"], new_obs])
        data["act"] = np.concatenate([data["act"], new_act])
        data["round"] = np.concatenate([data["round"], np.full(len(new_act), it, np.int16)])
        np.savez_compressed(args.out / "expert.npz", **data)
        ok = sum(e["success"] for e in episodes)
        log(
            f"round {it}: network grasped {ok}/{len(episodes)}; {len(new_act)} labels "
            f"(loss on them {before:.4f}); retraining on {len(data['act'])} samples"
        )
        history = behaviour_clone(
            model, norm, data["obs"], data["act"], args.dagger_epochs, args.batch_size,
            args.lr, args.seed + it, log=log, weights=_weights(data, args.dagger_weight),
        )  # fmt: skip
        progress.append(
            {
                "round": it,
                "samples": len(data["act"]),
                "train_loss": history[-1]["train_loss"],
                "val_loss": history[-1]["val_loss"],
                "episodes": len(episodes),
                "network_success": ok / max(1, len(episodes)),
                "queries": sum(e["queries"] for e in episodes),
                "unlabelled": sum(e["unlabelled"] for e in episodes),
                "minutes": (time.monotonic() - t_start) / 60,
            }
        )
        ckpt = args.out / f"round_{it}"
        save_model(model, norm, ckpt, {**stats, "rounds": progress}, args.net_arch)

    stats["rounds"] = progress
    stats["samples"] = len(data["act"])
    stats["wall_minutes"] = (time.monotonic() - t_start) / 60
    save_model(model, norm, args.out, stats, args.net_arch)
    with open(args.out / "progress.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(progress[0]))
        writer.writeheader()
        writer.writerows(progress)
    page = args.page or args.out / "training.md"
    page.write_text(training_page(args.out, command, _now(), git_commit()))
    log(
        f"wrote {args.out}/: model.zip vecnormalize.pkl config.yml train_stats.json "
        f"progress.csv, and {page}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
