"""Env throughput: steps/s of ``FrictionlessGrasp-v0`` against Gymnasium baselines, same run.

One process, ``render_mode=None``. Random actions are drawn in bulk from a seeded
``numpy.random.Generator`` (``Box.sample`` alone costs about 13 us). Each round runs every
env for ``budget`` seconds of stepping (resets included; env construction and
:data:`WARMUP_STEPS` first steps excluded), in a rotated order so that load changes on a
shared machine spread over all envs. Reported: the median steps/s over rounds, the median
over rounds of the per-round ratio to each baseline, and one line per target
(:data:`TARGETS`) with its ratio. The scripted policy (``agents.scripted.ScriptedPolicy``)
runs when it exists.

Usage: ``python -m benchmarks.throughput [--quick]``
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

import grasp_env  # noqa: F401  (registers FrictionlessGrasp-v0)
from benchmarks.common import headless, page_main, table, write
from grasp_env.cli import positive_float, positive_int

BASELINES = ("LunarLander-v3", "CartPole-v1")
#: The env configurations stepped with random actions.
CONFIGS = (
    {},
    {"palm_control": True},
    {"shape_randomizer": True, "palm_control": True},
    {"start": "preliftoff"},
)
#: Targets: (configuration, baseline, least ratio); a least ratio of None: the ratio is
#: reported without a verdict (against CartPole-v1, an env with no contacts to simulate).
TARGETS = (
    ({}, "LunarLander-v3", 1.0),
    ({}, "CartPole-v1", None),
    ({"start": "preliftoff"}, "LunarLander-v3", 0.5),
    ({"palm_control": True}, "LunarLander-v3", 1.0),
    ({"shape_randomizer": True, "palm_control": True}, "LunarLander-v3", 1.0),
)
#: Why a Box2D baseline is missing, and the install that keeps pygame working (gymnasium's
#: own message recommends its box2d extra, whose pygame-ce overwrites pygame's files).
NO_BOX2D = 'Box2D is not installed (pip install box2d, or pip install -e ".[bench]")'
ACTION_BLOCK = 4096  #: random actions drawn per call to the generator
WARMUP_STEPS = 20  #: untimed random steps of each env before its first round


class RandomActions:
    """Uniform random actions of a Box or Discrete space, drawn in blocks from a Generator."""

    def __init__(self, space: gym.Space, seed: int) -> None:
        self.space, self.rng = space, np.random.default_rng(seed)
        self.block, self.i = self._draw(), 0

    def _draw(self) -> np.ndarray:
        if isinstance(self.space, spaces.Discrete):
            return self.rng.integers(self.space.n, size=ACTION_BLOCK) + self.space.start
        shape = (ACTION_BLOCK, *self.space.shape)
        low, high = self.space.low, self.space.high
        return self.rng.uniform(low, high, shape).astype(self.space.dtype)

    def act(self, obs: Any) -> Any:
        if self.i == ACTION_BLOCK:
            self.block, self.i = self._draw(), 0
        self.i += 1
        return self.block[self.i - 1]

    def reset(self, obs: Any, info: dict) -> None:
        """Random actions ignore the episode start."""


@dataclass
class Runner:
    """An env and a policy stepped for a time budget; its counts carry over between rounds."""

    name: str
    env: gym.Env
    policy: Any
    time_policy: bool = False
    rates: list[float] = field(default_factory=list)
    steps: int = 0
    episodes: int = 0
    seconds: float = 0.0
    policy_seconds: float = 0.0

    def __post_init__(self) -> None:
        # A few untimed steps first: a process's first step loads the compiled simulator
        # from its cache (start-up, which memory.py measures), not a cost per step.
        self.env.reset(seed=0)
        for _ in range(WARMUP_STEPS):
            if any(self.env.step(self.env.action_space.sample())[2:4]):
                self.env.reset()
        self.obs, info = self.env.reset(seed=0)
        self.policy.reset(self.obs, info)

    def run(self, budget: float) -> float:
        """Step for ``budget`` seconds; return and record steps/s. With ``time_policy`` the
        policy's own time (``act`` and ``reset``) is summed too."""
        env, policy, obs, clock = self.env, self.policy, self.obs, time.perf_counter
        n, t0, in_policy = 0, clock(), 0.0
        end = t0 + budget
        while True:
            if self.time_policy:
                t = clock()
                action = policy.act(obs)
                in_policy += clock() - t
            else:
                action = policy.act(obs)
            obs, _, terminated, truncated, info = env.step(action)
            n += 1
            if terminated or truncated:
                obs, info = env.reset()
                t = clock()
                policy.reset(obs, info)
                in_policy += clock() - t
                self.episodes += 1
            if n % 8 == 0 and clock() >= end:
                break
        elapsed = clock() - t0
        self.obs, self.steps = obs, self.steps + n
        self.seconds += elapsed
        self.policy_seconds += in_policy
        self.rates.append(n / elapsed)
        return n / elapsed


def _name(kwargs: dict) -> str:
    """A configuration's row name."""
    args = ", ".join(f"{k}={v!r}" for k, v in kwargs.items())
    return f"FrictionlessGrasp-v0 ({args or 'default'})"


def scripted_runner() -> tuple[Runner | None, str]:
    """The scripted policy on ``start="preliftoff"``, or None and the reason it is absent."""
    try:
        from agents.scripted import ScriptedPolicy
    except ImportError as exc:
        return None, f"scripted policy absent ({exc})"
    errors = []
    for kwargs in ({"start": "preliftoff"}, {"start": "preliftoff", "palm_control": True}):
        env = gym.make("FrictionlessGrasp-v0", **kwargs)
        try:
            args = ", ".join(f"{k}={v!r}" for k, v in kwargs.items())
            name = f"FrictionlessGrasp-v0 scripted ({args})"
            return Runner(name, env, ScriptedPolicy(env), time_policy=True), ""
        except Exception as exc:  # a policy under construction: report, do not fail the suite
            errors.append(f"{kwargs}: {type(exc).__name__}: {exc}")
            env.close()
    return None, "scripted policy failed: " + "; ".join(errors)


def make_runners() -> tuple[list[Runner], list[str]]:
    """Our env configurations, the scripted policy, then the baselines that can be built."""
    runners, notes = [], []
    for i, kwargs in enumerate(CONFIGS):
        env = gym.make("FrictionlessGrasp-v0", **kwargs)
        runners.append(Runner(_name(kwargs), env, RandomActions(env.action_space, seed=i)))
    scripted, note = scripted_runner()
    if scripted is None:
        notes.append(note)
    else:
        runners.append(scripted)
    for i, name in enumerate(BASELINES, len(CONFIGS)):
        try:
            env = gym.make(name)
        except gym.error.DependencyNotInstalled:
            notes.append(f"{name} skipped: {NO_BOX2D}")
            print(f"{name} skipped: {NO_BOX2D}")
            continue
        runners.append(Runner(name, env, RandomActions(env.action_space, seed=i)))
    return runners, notes


def run(quick: bool, out: Path, budget: float | None = None, rounds: int | None = None) -> Path:
    """Run the throughput benchmark and write its markdown page."""
    headless()
    budget = budget if budget is not None else (1.0 if quick else 5.0)
    rounds = rounds if rounds is not None else (2 if quick else 5)
    runners, notes = make_runners()
    for r in range(rounds):
        k = r % len(runners)
        for runner in runners[k:] + runners[:k]:
            rate = runner.run(budget)
            print(f"round {r}: {runner.name}: {rate:,.0f} steps/s")
    base = {b.name: b for b in runners if b.name in BASELINES}
    header = ["env / policy", "steps/s (median)", "us/step", "steps", "episodes", "policy share"]
    header += [f"ratio to {name}" for name in base]
    rows = []
    for runner in runners:
        rate = statistics.median(runner.rates)
        share = f"{runner.policy_seconds / runner.seconds:.0%}" if runner.time_policy else "-"
        row = [runner.name, f"{rate:,.0f}", f"{1e6 / rate:,.1f}", runner.steps, runner.episodes]
        row.append(share)
        for b in base.values():
            ratios = [x / y for x, y in zip(runner.rates, b.rates, strict=True)]
            row.append(f"{statistics.median(ratios):.4f}")
        rows.append(row)
        runner.env.close()
    by_name = {runner.name: runner for runner in runners}
    targets = []
    for kwargs, baseline, least in TARGETS:
        name = _name(kwargs)
        line = f"target: {name} >= {least:g}x {baseline}" if least else f"{name} / {baseline}"
        if baseline not in base:
            notes.append(f"{line} skipped: {baseline} not measured")
            continue
        pairs = zip(by_name[name].rates, base[baseline].rates, strict=True)
        ratio = statistics.median(x / y for x, y in pairs)
        verdict = "" if least is None else f" ({'met' if ratio >= least else 'not met'})"
        targets.append(f"* {line}: **{ratio:.3f}x**{verdict}")
        print(f"{line}: {ratio:.3f}x{verdict}")
    body = [
        f"{rounds} rounds x {budget:g} s per env, rotated order; random actions from a "
        "seeded Generator in blocks; `render_mode=None`; resets inside the timing; ratios "
        "are medians of per-round ratios. Policy share: the scripted policy's own time "
        "(planning at reset, re-planning, `act`) as a fraction of the wall time.",
        "",
        *table(header, rows),
        "",
        "Targets (random actions):",
        "",
        *targets,
        "",
        *[f"* {note}" for note in notes],
    ]
    return write(out, "Env throughput (single process)", body)


#: ``run``'s options on the command line: name, type, help.
OPTIONS = (
    ("budget", positive_float, "seconds per env per round"),
    ("rounds", positive_int, "rounds"),
)


def main(argv: list[str] | None = None) -> int:
    return page_main(argv, run, "throughput.md", "2 rounds of 1 s per env", OPTIONS)


if __name__ == "__main__":
    raise SystemExit(main())
