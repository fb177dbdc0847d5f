"""The two parts of an env step, timed without a profiler: the env's Python shell and the
compiled move.

* **The env's shell** (action check, the call into the compiled step, the state and info
  dict it returns): ``env.step`` with the compiled step (:func:`grasp_env.kernel.step.
  step_env`) replaced by a fixed result, so that only the shell runs. Two cases per set-up:
  the step keeps the contacts (the state keeps the last one's contacts), and it alternates
  between two states with different contacts (their contacts are made afresh every step).
* **The compiled move by the work it does**: the moves of seeded random-action steps,
  replayed through :meth:`grasp_env.Simulator.move_arrays` and classed by what they took
  (the hand stayed clear of an object resting on the support; no pose solve; 1-3, 4-9, 10 or
  more pose solves), with the class's share of the steps and of the move time, its median
  time per call from Python (dispatch and the results' conversion included) and the
  allocations the compiled code makes per move (numba's own counters, which only a process
  started with ``NUMBA_NRT_STATS=1`` keeps: a child process counts them on the same
  steps).

Usage: ``python -m benchmarks.step_parts [--quick] [--steps N] [--out FILE]``
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import grasp_env  # noqa: F401  (registers the env ids)
from benchmarks.common import REPO, headless, page_main, table, write
from benchmarks.throughput import RandomActions
from grasp_env.cli import positive_int
from grasp_env.envs.episode import state_arrays
from grasp_env.kernel import step as kernel
from grasp_env.sim.move import OUT_SIZE, OUT_UNTOUCHED

#: Set-ups measured: name -> ``gymnasium.make`` keyword arguments.
CONFIGS = {
    "default": {},
    "palm_control": {"palm_control": True},
    "preliftoff": {"start": "preliftoff"},
}
#: Move classes: name -> whether a move with ``(solves, untouched)`` belongs to it.
CLASSES = {
    "hand clear of a resting object": lambda solves, untouched: untouched,
    "no pose solve": lambda solves, untouched: not untouched and solves == 0,
    "1-3 pose solves": lambda solves, untouched: 1 <= solves <= 3,
    "4-9 pose solves": lambda solves, untouched: 4 <= solves <= 9,
    ">= 10 pose solves": lambda solves, untouched: solves >= 10,
}


SHELL_HEADER = [
    "set-up", "contacts kept", "contacts changing",
]  # fmt: skip
MOVE_HEADER = [
    "set-up", "move", "% of steps", "% of move time", "median us/move", "allocations/move"
]  # fmt: skip


def record_moves(kwargs: dict, steps: int, count_allocations: bool = False) -> list[tuple]:
    """``(seconds, pose solves, untouched, allocations)`` of the move of each of ``steps``
    seeded random-action steps (allocations 0 unless ``count_allocations``, which needs
    ``NUMBA_NRT_STATS=1`` set before numba was imported)."""
    from numba.core.runtime import rtsys

    moves, calls = [], []
    step_env = kernel.step_env

    def recorded(model, consts, settings, state, *rest):
        target = kernel.target_of(consts, settings, state[1], rest[-2])[0]
        calls.append((state[0].copy(), state[1].copy(), target, state[2].copy()))
        return step_env(model, consts, settings, state, *rest)

    env = gym.make("FrictionlessGrasp-v0", **kwargs)
    policy = RandomActions(env.action_space, seed=0)
    obs, _ = env.reset(seed=0)
    kernel.step_env = recorded
    try:
        for _ in range(steps):
            calls.append(env.unwrapped.simulator)
            obs, _, terminated, truncated, _ = env.step(policy.act(obs))
            if terminated or truncated:
                obs, _ = env.reset()
    finally:
        kernel.step_env = step_env
    sim = None
    for call in calls:
        if not isinstance(call, tuple):
            sim = call
            continue
        allocs = rtsys.get_allocation_stats().alloc if count_allocations else 0
        t0 = time.perf_counter()
        out = sim.move_arrays(*call)
        seconds = time.perf_counter() - t0
        if count_allocations:
            allocs = rtsys.get_allocation_stats().alloc - allocs
        moves.append((seconds, sim.solves, bool(out[0][OUT_UNTOUCHED]), allocs))
    return moves


def classify(moves: list[tuple]) -> dict[str, dict]:
    """Per class of :data:`CLASSES`: share of the moves and of their time, median time per
    move (us) and mean allocations per move."""
    total = sum(m[0] for m in moves) or 1.0
    out = {}
    for name, member in CLASSES.items():
        mine = [m for m in moves if member(m[1], m[2])]
        out[name] = {
            "share": len(mine) / len(moves),
            "time_share": sum(m[0] for m in mine) / total,
            "median_us": statistics.median(m[0] for m in mine) * 1e6 if mine else float("nan"),
            "allocations": statistics.fmean(m[3] for m in mine) if mine else float("nan"),
        }
    return out


def _child_allocations(name: str, steps: int) -> dict[str, float]:
    """Mean compiled-code allocations per move of each class, counted by a child process
    started with ``NUMBA_NRT_STATS=1`` on the same seeded steps."""
    env = {**os.environ, "NUMBA_NRT_STATS": "1"}
    code = (
        "import json, sys; from benchmarks import step_parts as p; "
        f"m = p.record_moves(p.CONFIGS[{name!r}], {steps}, True); "
        "json.dump({k: v['allocations'] for k, v in p.classify(m).items()}, sys.stdout)"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True,
        check=True,
    )  # fmt: skip
    return json.loads(res.stdout.strip().splitlines()[-1])


def _two_states(kwargs: dict, steps: int):
    """An env after seeded random steps, with two of the states it passed through that have
    different contacts, at least one hand contact each where the set-up makes any."""
    env = gym.make("FrictionlessGrasp-v0", **kwargs)
    policy = RandomActions(env.action_space, seed=1)
    obs, _ = env.reset(seed=0)
    found = {}
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(policy.act(obs))
        state = env.unwrapped.state
        keys = tuple(c.key for c in state.contacts)
        if any(c.body != "support" for c in state.contacts) and keys not in found:
            found[keys] = state
            if len(found) == 2:
                break
        if terminated or truncated:
            obs, _ = env.reset()
    states = list(found.values()) or [env.unwrapped.state]
    return env, states[0], states[-1]


def shell_times(kwargs: dict, steps: int, repeat: int = 5) -> dict[str, float]:
    """us per ``env.step`` with the compiled step fixed, contacts kept or changing (median
    of ``repeat`` runs)."""
    env, first, second = _two_states(kwargs, 5000)
    episode = env.unwrapped._episode
    action = np.zeros(env.action_space.shape, dtype=env.action_space.dtype)
    step_env = kernel.step_env
    results = {}
    for name, state in (("first", first), ("second", second)):
        q, h, keys, rows = state_arrays(state)
        out = np.zeros(OUT_SIZE)
        out[:3], out[3:8] = q, h
        results[name] = (kernel.OK, episode.obs.copy(), [], out, q, h, keys, rows,
                         episode.an.copy())  # fmt: skip
    out = {}
    try:
        for case, names in (("kept", ("first", "first")), ("changing", ("first", "second"))):
            turn = [0]

            def fixed(*args, names=names, turn=turn):
                turn[0] ^= 1
                return results[names[turn[0]]]

            kernel.step_env = fixed
            times = []
            for _ in range(repeat):
                t0 = time.perf_counter()
                for _ in range(steps):
                    env.step(action)
                times.append((time.perf_counter() - t0) / steps * 1e6)
            out[case] = statistics.median(times)
    finally:
        kernel.step_env = step_env
    out["changing contacts"] = tuple(c.key for c in first.contacts) != tuple(
        c.key for c in second.contacts
    )
    return out


def run(quick: bool, out: Path, steps: int | None = None) -> Path:
    """Measure every set-up of :data:`CONFIGS` and write the page."""
    headless()
    steps = steps or (200 if quick else 20_000)
    shell_steps = max(steps // 4, 20)
    shell_rows, move_rows = [], []
    for name, kwargs in CONFIGS.items():
        shell = shell_times(kwargs, shell_steps)
        changing = "" if shell["changing contacts"] else " (no second contact set found)"
        shell_rows.append(
            [f"`{name}`", f"{shell['kept']:.1f}", f"{shell['changing']:.1f}{changing}"]
        )
        classes = classify(record_moves(kwargs, steps))
        allocations = _child_allocations(name, steps)
        for cls, res in classes.items():
            if res["share"] == 0.0:
                continue
            move_rows.append([
                f"`{name}`", cls, f"{100 * res['share']:.1f}", f"{100 * res['time_share']:.1f}",
                f"{res['median_us']:.1f}", f"{allocations[cls]:.0f}",
            ])  # fmt: skip
        print(f"{name}: shell {shell['kept']:.1f} us/step (contacts kept)")
    body = [
        "`benchmarks/step_parts.py`: each part timed unprofiled, one process, "
        f"{steps:,} seeded random-action steps per set-up (`RandomActions`, seed 0).",
        "",
        "## The env's shell",
        "",
        "us per `env.step` with the compiled step replaced by a fixed result (median of 5 "
        f"runs of {shell_steps:,} steps): the action check, the call, the state and the "
        'info dict. "Contacts kept": every step returns the same state; "contacts changing": '
        "two states with different contacts in turn, their contacts made afresh.",
        "",
        *table(SHELL_HEADER, shell_rows),
        "",
        "## The compiled move, by the work it does",
        "",
        "Each move of the steps above, replayed and classed by what it took. Time per call "
        "from Python (`Simulator.move_arrays`: the compiled call with its dispatch and the "
        "conversion of its results); allocations: numba's allocation counter per move "
        "(`NUMBA_NRT_STATS=1`, counted by a child process on the same steps).",
        "",
        *table(MOVE_HEADER, move_rows, align="llrrrr"),
    ]
    return write(out, "The parts of an env step", body)


#: ``run``'s option on the command line: name, type, help.
OPTIONS = (("steps", positive_int, "random-action steps per set-up"),)


def main(argv: list[str] | None = None) -> int:
    return page_main(argv, run, "step_parts.md", "200 steps per set-up", OPTIONS)


if __name__ == "__main__":
    raise SystemExit(main())
