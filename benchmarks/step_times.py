"""Step-time distribution of ``FrictionlessGrasp-v0`` on adversarial shapes: the tail.

A learner waits for the slowest steps, and a rare step that takes seconds stalls a whole vector
of envs. The shapes are the ``extreme`` suite of :mod:`benchmarks.episodes` (slivers,
near-circles, nearly collinear vertices, a 1e-12..1e-9 bulge on the resting edge) and the
soak's whole stress population (``soak``), all three starts, random palm-control actions, up
to ``--steps`` steps an episode. Each ``env.step`` (the ``gymnasium.make`` env with its
wrappers) is timed alone with ``time.perf_counter``; resets are not timed. Episodes are
shared out to ``--workers`` processes (one per core), so the times include the machine's
load: the page starts with the load average.

Reported per suite and overall: steps, median, p99, p99.9 and max, against the targets
p99.9 <= 20 ms and max <= 0.5 s, and the slowest steps with the suite, seed and step that
reproduce them (``--replay SUITE SEED STEP`` re-runs the episode and times that step again).

Usage: ``python -m benchmarks.step_times [--episodes N] [--quick] [--steps S] [--workers W]
[--out DIR]`` from the repository root (200 episodes a suite: about a minute on 2 cores).
"""

from __future__ import annotations

import heapq
import json
import multiprocessing as mp
import os
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.common import OUT, headless, parser, table, write
from grasp_env.cli import fields, one_of, out_dir_problem, positive_int, seed_int, workers

SUITES = ("extreme", "soak")
#: Targets, seconds.
P999_TARGET, MAX_TARGET = 0.020, 0.5
#: Slowest steps kept per episode and listed on the page.
SLOWEST = 10


def warm_up() -> None:
    """Run a few untimed steps, so that no timed step pays for a first-use import."""
    from benchmarks.episodes import action_rng, make_env, random_action

    headless()
    env, _ = make_env("default", 1)
    env.reset(seed=1)
    rng = action_rng(1)
    for _ in range(20):
        env.step(random_action(rng))
    env.close()


def time_episode(job: tuple[str, int, int]) -> dict[str, Any]:
    """Play episode ``(suite, seed)`` for up to ``steps`` steps timing every ``env.step``;
    the times and the episode's slowest steps (with their events)."""
    from benchmarks.episodes import action_rng, make_env, random_action, start_of

    suite, seed, steps = job
    headless()
    env, kind = make_env(suite, seed)
    rng = action_rng(seed)
    env.reset(seed=seed)
    times: list[float] = []
    slow: list[tuple[float, int, list[str]]] = []
    clock = time.perf_counter
    for k in range(1, steps + 1):
        action = random_action(rng)
        t0 = clock()
        try:
            _, _, terminated, truncated, info = env.step(action)
        except Exception as exc:  # timed like any step; it ends the episode
            terminated, truncated, info = True, False, {"events": [f"raised {exc!r}"[:80]]}
        dt = clock() - t0
        times.append(dt)
        # a failed step leaves the state, and its events, as they were
        entry = (dt, k, ["sim_error"] if "sim_error" in info else list(info["events"]))
        if len(slow) < SLOWEST:
            heapq.heappush(slow, entry)
        elif dt > slow[0][0]:
            heapq.heapreplace(slow, entry)
        if terminated or truncated:
            break
    env.close()
    return {
        "suite": suite,
        "seed": seed,
        "start": start_of(seed),
        "kind": kind,
        "times": times,
        "slow": [{"time": t, "step": k, "events": ev} for t, k, ev in slow],
    }


def stats(times: Sequence[float]) -> dict[str, float]:
    """Count, median, p99, p99.9 and max (seconds) of step times."""
    t = np.asarray(times, dtype=float)
    if not len(t):
        return {"steps": 0, "median": np.nan, "p99": np.nan, "p99.9": np.nan, "max": np.nan}
    q = np.quantile(t, [0.5, 0.99, 0.999])
    return {
        "steps": len(t),
        "median": float(q[0]),
        "p99": float(q[1]),
        "p99.9": float(q[2]),
        "max": float(t.max()),
    }


def run(
    out: Path = OUT,
    *,
    episodes: int = 200,
    steps: int = 100,
    workers: int = 2,
    suites: Sequence[str] = SUITES,
) -> dict[str, Any]:
    """Time the episodes of every suite in ``workers`` processes; write
    ``out/step_times.md`` and ``.json`` and return the report."""
    jobs = [(suite, seed, steps) for suite in suites for seed in range(episodes)]
    t0 = time.perf_counter()
    if workers <= 1:
        warm_up()
        results = [time_episode(job) for job in jobs]
    else:
        ctx = mp.get_context("spawn" if os.name == "nt" else "fork")
        with ProcessPoolExecutor(workers, mp_context=ctx, initializer=warm_up) as ex:
            results = list(ex.map(time_episode, jobs, chunksize=4))
    wall = time.perf_counter() - t0
    by_suite = {s: [t for r in results if r["suite"] == s for t in r["times"]] for s in suites}
    slowest = heapq.nlargest(
        SLOWEST,
        (
            {**step, **{k: r[k] for k in ("suite", "seed", "start", "kind")}}
            for r in results
            for step in r["slow"]
        ),
        key=lambda s: s["time"],
    )
    report = {
        "episodes": episodes,
        "steps": steps,
        "workers": workers,
        "wall": wall,
        "suites": {s: stats(t) for s, t in by_suite.items()},
        "all": stats([t for ts in by_suite.values() for t in ts]),
        "slowest": slowest,
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "step_times.json").write_text(json.dumps(report, indent=1) + "\n")
    write(out / "step_times.md", "Step times on adversarial shapes", page(report))
    return report


def _ms(x: float) -> str:
    return f"{1e3 * x:.2f}"


def page(report: dict[str, Any]) -> list[str]:
    """The markdown body of the report."""
    n, steps, w = report["episodes"], report["steps"], report["workers"]
    lines = [
        f"Command: `python -m benchmarks.step_times --episodes {n} --steps {steps} "
        f"--workers {w}` ({n} episodes a suite, seeds 0..{n - 1}, up to {steps} random "
        f"palm-control steps each, {w} processes; wall time {report['wall']:.0f} s).",
        "",
        "Wall time of each `env.step` in ms. *extreme*: slivers, near-circles, nearly "
        "collinear vertices, resting-edge bulges; *soak*: the soak's whole stress population "
        f"(`benchmarks/soak.py`). Targets: p99.9 <= {_ms(P999_TARGET)} ms, max <= "
        f"{_ms(MAX_TARGET)} ms.",
        "",
    ]
    rows = []
    for name, s in [*report["suites"].items(), ("all", report["all"])]:
        rows.append(
            [name, s["steps"], _ms(s["median"]), _ms(s["p99"]), _ms(s["p99.9"]), _ms(s["max"])]
        )
    lines += table(["suite", "steps", "median", "p99", "p99.9", "max"], rows)
    a = report["all"]
    met = [
        f"p99.9 {_ms(a['p99.9'])} ms: {'met' if a['p99.9'] <= P999_TARGET else 'not met'}",
        f"max {_ms(a['max'])} ms: {'met' if a['max'] <= MAX_TARGET else 'not met'}",
    ]
    lines += ["", "Targets over all steps: " + "; ".join(met) + ".", "", "## Slowest steps", ""]
    lines += [
        "Re-time one with `python -m benchmarks.step_times --replay SUITE SEED STEP`.",
        "",
    ]
    rows = [
        [
            _ms(s["time"]),
            s["suite"],
            s["seed"],
            s["step"],
            s["start"],
            s["kind"],
            ", ".join(s["events"]) or "-",
        ]
        for s in report["slowest"]
    ]
    lines += table(["ms", "suite", "seed", "step", "start", "shape", "events"], rows, "rlrrlll")
    return lines


def replay(suite: str, seed: int, step: int, repeat: int = 5) -> list[float]:
    """Re-run episode ``(suite, seed)`` up to ``step``, time that ``env.step`` and then the
    same move ``repeat`` times more from the same state (``simulate_action``); print them."""
    from benchmarks.episodes import action_rng, make_env, random_action

    warm_up()
    env, kind = make_env(suite, seed)
    rng = action_rng(seed)
    env.reset(seed=seed)
    for _ in range(step - 1):
        _, _, terminated, truncated, _ = env.step(random_action(rng))
        if terminated or truncated:
            raise SystemExit(f"{suite} seed {seed} ends before step {step}")
    action = random_action(rng)
    state = env.unwrapped.state
    t0 = time.perf_counter()
    _, _, _, _, info = env.step(action)
    times = [time.perf_counter() - t0]
    for _ in range(repeat):
        t0 = time.perf_counter()
        env.unwrapped.simulate_action(state, action)
        times.append(time.perf_counter() - t0)
    print(
        f"{suite} seed {seed} ({kind}) step {step}: env.step {_ms(times[0])} ms, events "
        f"{info['events']}; the move again: {', '.join(_ms(t) for t in times[1:])} ms"
    )
    return times


def main(argv: list[str] | None = None) -> int:
    ap = parser("benchmarks.step_times", __doc__, quick="3 episodes a suite")
    ap.add_argument("--episodes", type=positive_int, default=200, help="episodes a suite")
    ap.add_argument("--steps", type=positive_int, default=100, help="steps an episode at most")
    ap.add_argument("--workers", type=workers, default=2, help="processes, one per core")
    ap.add_argument("--suites", nargs="+", choices=SUITES, default=list(SUITES), help="suites")
    ap.add_argument("--out", type=Path, default=OUT, help="results folder")
    ap.add_argument(
        "--replay",
        nargs=3,
        action=fields(one_of(*SUITES), seed_int, positive_int),
        metavar=("SUITE", "SEED", "STEP"),
        help="re-time one step (1, 2, ...) of a page's episode in this process and stop",
    )
    args = ap.parse_args(argv)
    if args.replay:
        replay(*args.replay)
        return 0
    if problem := out_dir_problem(args.out):
        ap.error(f"--out {problem}")
    episodes = 3 if args.quick else args.episodes
    run(args.out, episodes=episodes, steps=args.steps, workers=args.workers, suites=args.suites)
    print((args.out / "step_times.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
