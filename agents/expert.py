"""The scripted planner as the expert that ``agents.imitation`` clones: the training
distribution's two starts, the planner's episodes (observations and its actions), its
action at any visited state (:func:`expert_action`), the network's episodes that it labels
(DAgger) and the running of many episodes in processes."""

from __future__ import annotations

import functools
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import gymnasium as gym
import numpy as np

import grasp_env  # noqa: F401  (registers the env ids)
from agents.models import load_agent, network_action
from agents.scripted import ScriptedPolicy
from grasp_env.envs import LIFT_ENV_ID, RANDOM_SHAPES_ENV_ID
from grasp_env.errors import ComputationError

#: The env id the model's config names: random shapes from the scene's start with palm
#: control, as the planner is evaluated; the model adds the observation's hand features.
ENV_ID = RANDOM_SHAPES_ENV_ID
#: Env kwargs of the two starts of the training distribution, each with the hand features
#: (they change the observation only): the scene's start (``agents.episodes.SCRIPTED_KWARGS``
#: with random shapes) and the planner's placement (the lifting task).
STARTS = {
    "scene": (ENV_ID, {"hand_features": True}),
    "placement": (LIFT_ENV_ID, {}),
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
    return {
        **_samples(env, observations, actions),
        "success": success,
        "steps": len(actions),
        "seed": seed,
        "start": start,
        "error": error,
        "seconds": time.process_time() - t0,
    }


def _samples(env, observations: list, actions: list) -> dict[str, np.ndarray]:
    """An episode's (observation, action) pairs as float32 arrays, the actions checked in the
    env's action space; closes the env."""
    space, width = env.action_space, env.observation_space.shape[0]
    env.close()
    acts = np.array(actions, np.float32).reshape(-1, space.shape[0])
    check_actions(acts, space)
    return {"obs": np.array(observations, np.float32).reshape(len(actions), width), "act": acts}


# ---------------------------------------------------------------------- DAgger
@functools.cache
def _network(model_dir: str):
    model, norm, _, _ = load_agent(model_dir)
    return model, norm


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
    return {
        **_samples(env, observations, actions),
        "success": bool(info["is_success"]),
        "steps": steps,
        "seed": seed,
        "start": start,
        "queries": queries,
        "unlabelled": unlabelled,
        "seconds": time.process_time() - t0,
    }


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


def stack_samples(episodes: list[dict], key: str, width: int) -> np.ndarray:
    """The episodes' ``key`` arrays (``"obs"`` or ``"act"``) in one, ``(0, width)`` for none."""
    parts = [e[key] for e in episodes if len(e[key])]
    return np.concatenate(parts) if parts else np.zeros((0, width), np.float32)
